//! `[[lights]]`: delta lights (directional, point, spot) and the environment, appended after
//! the area lights of the shapes, and the power distribution that picks a light for
//! next-event estimation and light paths.

use super::values::{finite3, non_negative};
use glam::{Mat3, Vec2, Vec3};

use crate::geometry::{Bvh, Ray};

use crate::geometry::offset_origin;
use crate::image_io::{read_exr_input_hashed, rgbe};
use crate::math::{Distribution1D, Frame};
use crate::scene::envmap::{self, EnvMap};
use crate::scene::file::{path, EnvSamplingDesc, KeyPath, LightDesc, SceneFile};
use crate::scene::{Environment, Light, PrimMedia, Scene, SceneError, SceneSource};

/// Every light of the scene: the area lights first, then `[[lights]]` in order.
pub(super) struct Lights {
    /// The lights.
    pub(super) lights: Vec<Light>,
    /// The index of the environment light, if any.
    pub(super) environment: Option<u32>,
    /// Light selection proportional to power (of a scene of radius `radius` for lights at
    /// infinity).
    pub(super) light_distr: Distribution1D,
}

/// The medium around each light of `scene` (`Scene::light_media`): at the centre of an area
/// light's first primitive, lifted off its surface along the normal (the side it emits into),
/// at a point or spot light's position; `None` for the infinite lights.
pub(super) fn media_around(scene: &Scene) -> Vec<Option<u32>> {
    scene
        .lights
        .iter()
        .map(|l| match l {
            Light::Area { prims, .. } => {
                let (p, n) = scene.prims[prims[0] as usize].sample_area(glam::Vec2::splat(0.5));
                scene.medium_at(offset_origin(p, n, n))
            }
            Light::Point { position, .. } | Light::Spot { position, .. } => {
                scene.medium_at(*position)
            }
            _ => None,
        })
        .collect()
}

/// The medium of each primitive of the area lights whose primitives lie in different media
/// (`Scene::light_prim_media`), and a refusal for a primitive that itself lies in two: light
/// paths start in one medium per primitive, so a quad half inside a fog would start the paths
/// of its other half in the fog too (light tracing and BDPT would differ from path tracing).
/// Each primitive is probed at its centre and at eight points near its rim, lifted to its
/// emitting side (a boundary that cuts a primitive between these points is not seen).
pub(super) fn media_per_primitive(
    src: &SceneSource,
    scene: &Scene,
) -> Result<Vec<PrimMedia>, SceneError> {
    let mut out = vec![None; scene.lights.len()];
    let interface = |i: usize| scene.shapes[scene.prim_shape[i] as usize].interface;
    if !(0..scene.prims.len()).any(interface) {
        return Ok(out);
    }
    let boundaries = Bvh::build_over(&scene.prims, interface);
    let reach = boundaries.bounds();
    // `Scene::medium_at` through a tree of the medium boundaries alone
    let medium_at = |p: Vec3| {
        let d = Vec3::new(0.389_312, 0.727_003, 0.565_516).normalize();
        let hit = boundaries.intersect(
            &scene.prims,
            &scene.prim_opaque,
            &Ray::new(p, d),
            f32::INFINITY,
        )?;
        let shape = &scene.shapes[scene.prim_shape[hit.prim as usize] as usize];
        if d.dot(hit.ng) > 0.0 {
            shape.interior
        } else {
            shape.exterior
        }
    };
    let at = |prim: &crate::geometry::Primitive, u: Vec2| {
        let (p, n) = prim.sample_area(u);
        medium_at(offset_origin(p, n, n))
    };
    let name = |m: Option<u32>| {
        m.map_or("no medium".to_string(), |m| {
            format!("medium `{}`", scene.medium_names[m as usize])
        })
    };
    for (l, light) in scene.lights.iter().enumerate() {
        let Light::Area { prims, shape, .. } = light else {
            continue;
        };
        let mut media = Vec::with_capacity(prims.len());
        for &i in prims {
            let prim = &scene.prims[i as usize];
            let b = prim.bounds();
            let near = b.min.cmple(reach.max).all() && reach.min.cmple(b.max).all();
            let m = if near {
                at(prim, Vec2::splat(0.5))
            } else {
                medium_at(b.centroid())
            };
            for k in (0..9).filter(|k| near && *k != 4) {
                let u = Vec2::new([0.02, 0.5, 0.98][k % 3], [0.02, 0.5, 0.98][k / 3]);
                let other = at(prim, u);
                if other != m {
                    let why = format!(
                        "this area light lies in more than one medium ({} at one point of a primitive, {} at another): light paths start in one medium per primitive, so split the shape at the medium's boundary",
                        name(m),
                        name(other)
                    );
                    return Err(src.error(&path("shapes").index(*shape as usize), &why));
                }
            }
            media.push(m);
        }
        if media.iter().any(|m| *m != scene.light_media[l]) {
            out[l] = Some(media.into_boxed_slice());
        }
    }
    Ok(out)
}

/// Appends every `[[lights]]` entry to the area lights `lights` and builds the power
/// distribution; a light whose power overflows is an error at its key.
pub(super) fn build(
    src: &SceneSource,
    desc: &SceneFile,
    mut lights: Vec<Light>,
    radius: f32,
) -> Result<Lights, SceneError> {
    let mut environment = None;
    for (i, l) in desc.lights.iter().enumerate() {
        let key = path("lights").index(i);
        let light = match l {
            LightDesc::Environment { .. } => {
                if environment.is_some() {
                    return Err(src.error(&key, "only one environment light is allowed"));
                }
                let env = environment_light(src, &key, l)?;
                environment = Some(lights.len() as u32);
                Light::Environment(env)
            }
            _ => delta_light(src, &key, l)?,
        };
        lights.push(light);
    }
    let powers: Vec<f32> = lights.iter().map(|l| l.power(radius)).collect();
    if let Some(i) = powers.iter().position(|p| !p.is_finite()) {
        let key = match lights[i] {
            Light::Area { shape, .. } => path("shapes").index(shape as usize).key("emission"),
            // area lights come first, then `[[lights]]` in order
            _ => path("lights").index(
                i - lights
                    .iter()
                    .filter(|l| matches!(l, Light::Area { .. }))
                    .count(),
            ),
        };
        return Err(src.error(&key, "the light's power overflows a 32-bit float"));
    }
    let light_distr = Distribution1D::new(&powers);
    Ok(Lights {
        lights,
        environment,
        light_distr,
    })
}

/// A directional, point or spot light.
fn delta_light(src: &SceneSource, key: &KeyPath, l: &LightDesc) -> Result<Light, SceneError> {
    Ok(match l {
        LightDesc::Directional {
            direction,
            irradiance,
        } => Light::Directional {
            direction: finite3(src, &key.clone().key("direction"), *direction)?
                .try_normalize()
                .ok_or_else(|| {
                    src.error(&key.clone().key("direction"), "direction has zero length")
                })?,
            irradiance: non_negative(
                src,
                &key.clone().key("irradiance"),
                *irradiance,
                "irradiance",
            )?,
        },
        LightDesc::Point {
            position,
            intensity,
        } => Light::Point {
            position: finite3(src, &key.clone().key("position"), *position)?,
            intensity: non_negative(src, &key.clone().key("intensity"), *intensity, "intensity")?,
        },
        LightDesc::Spot {
            position,
            direction,
            intensity,
            cone_deg,
            falloff_deg,
        } => {
            if !(*cone_deg > 0.0 && *cone_deg <= 90.0) {
                return Err(src.error(
                    &key.clone().key("cone_deg"),
                    format!("cone_deg = {cone_deg} must be in (0, 90]"),
                ));
            }
            if !(*falloff_deg >= 0.0 && falloff_deg <= cone_deg) {
                return Err(src.error(
                    &key.clone().key("falloff_deg"),
                    format!("falloff_deg = {falloff_deg} must be in [0, cone_deg]"),
                ));
            }
            let dir = finite3(src, &key.clone().key("direction"), *direction)?
                .try_normalize()
                .ok_or_else(|| {
                    src.error(&key.clone().key("direction"), "direction has zero length")
                })?;
            Light::Spot {
                position: finite3(src, &key.clone().key("position"), *position)?,
                frame: Frame::from_normal(dir),
                intensity: non_negative(
                    src,
                    &key.clone().key("intensity"),
                    *intensity,
                    "intensity",
                )?,
                cos_total: cone_deg.to_radians().cos(),
                cos_falloff: (cone_deg - falloff_deg).to_radians().cos(),
            }
        }
        LightDesc::Environment { .. } => unreachable!("the environment is built apart"),
    })
}

/// The environment: constant `radiance`, the `zenith`/`horizon`/`nadir` gradient, or a `map`
/// (with `scale`, `to_world` and `sampling`, which only a map takes).
fn environment_light(
    src: &SceneSource,
    key: &KeyPath,
    l: &LightDesc,
) -> Result<Environment, SceneError> {
    let LightDesc::Environment {
        radiance,
        zenith,
        horizon,
        nadir,
        map,
        scale,
        to_world,
        sampling,
    } = l
    else {
        unreachable!("an environment")
    };
    if map.is_none() {
        let only_map = [
            ("scale", scale.is_some()),
            ("to_world", to_world.is_some()),
            ("sampling", sampling.is_some()),
        ];
        if let Some((k, _)) = only_map.iter().find(|(_, given)| *given) {
            return Err(src.error(
                &key.clone().key(k),
                format!("`{k}` applies to an environment `map` only"),
            ));
        }
    }
    Ok(match (radiance, zenith, horizon, nadir, map) {
        (Some(r), None, None, None, None) => Environment::Constant(non_negative(
            src,
            &key.clone().key("radiance"),
            *r,
            "radiance",
        )?),
        (None, Some(z), Some(h), Some(n), None) => Environment::Gradient {
            zenith: non_negative(src, &key.clone().key("zenith"), *z, "zenith")?,
            horizon: non_negative(src, &key.clone().key("horizon"), *h, "horizon")?,
            nadir: non_negative(src, &key.clone().key("nadir"), *n, "nadir")?,
        },
        (None, None, None, None, Some(file)) => {
            let uniform = sampling.unwrap_or_default() == EnvSamplingDesc::Uniform;
            Environment::Map(Box::new(environment_map(
                src,
                key,
                file,
                scale.unwrap_or(1.0),
                to_world,
                uniform,
            )?))
        }
        _ => {
            return Err(src.error(
                key,
                "an environment takes either `radiance`, or all of `zenith`, `horizon`, \
                 `nadir`, or a `map`",
            ))
        }
    })
}

/// The largest environment map file read, in bytes.
pub const MAX_MAP_BYTES: u64 = 1 << 30;

/// The map `file` (relative to the scene file) times `scale`, turned by `to_world`: errors name
/// the file and the key; texels must be finite and non-negative.
fn environment_map(
    src: &SceneSource,
    key: &KeyPath,
    file: &str,
    scale: f32,
    to_world: &Option<[[f32; 3]; 3]>,
    uniform: bool,
) -> Result<EnvMap, SceneError> {
    let map_key = key.clone().key("map");
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(src.error(
            &key.clone().key("scale"),
            format!("scale must be finite and >= 0, got {scale}"),
        ));
    }
    let rotation = match to_world {
        Some(rows) => orthogonal(src, &key.clone().key("to_world"), rows)?,
        None => Mat3::IDENTITY,
    };
    let path = src.base_dir.join(file);
    let (image, hash) = if rgbe::is_rgbe(&path) {
        rgbe::read_rgbe_input_hashed(&path, MAX_MAP_BYTES, envmap::MAX_TEXELS)
    } else {
        read_exr_input_hashed(&path, MAX_MAP_BYTES, envmap::MAX_TEXELS)
    }
    .map_err(|e| src.error(&map_key, e.to_string()))?;
    src.record_input(file, hash);
    let (w, h) = (image.width as usize, image.height as usize);
    if w < envmap::MIN_SIDE || h < envmap::MIN_SIDE || w.max(h) > envmap::MAX_SIDE {
        return Err(src.error(
            &map_key,
            format!(
                "{file}: a {w} x {h} map; each side must be in [{}, {}]",
                envmap::MIN_SIDE,
                envmap::MAX_SIDE
            ),
        ));
    }
    if let Some(k) = image
        .pixels
        .iter()
        .position(|c| !c.to_array().iter().all(|x| x.is_finite() && *x >= 0.0))
    {
        return Err(src.error(
            &map_key,
            format!(
                "{file}: texel ({}, {}) is {}: texels must be finite and >= 0",
                k % w,
                k / w,
                image.pixels[k]
            ),
        ));
    }
    let texels: Vec<_> = image.pixels.iter().map(|&c| c * scale).collect();
    if let Some(c) = texels.iter().find(|c| !c.is_finite()) {
        return Err(src.error(
            &key.clone().key("scale"),
            format!("scale {scale} makes a texel overflow ({c})"),
        ));
    }
    Ok(EnvMap::new(w, h, texels, rotation, uniform))
}

/// `to_world` given by rows: an orthogonal matrix (a rotation, or a rotation with a mirror),
/// so that it keeps solid angles and the map's density.
fn orthogonal(src: &SceneSource, key: &KeyPath, rows: &[[f32; 3]; 3]) -> Result<Mat3, SceneError> {
    let m = Mat3::from_cols_array_2d(rows).transpose();
    let error = (m.transpose() * m - Mat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f32, |a, x| a.max(x.abs()));
    if error.is_nan() || error > 1e-4 {
        return Err(src.error(
            key,
            format!("{rows:?} is not an orthogonal matrix (a rotation, possibly mirrored)"),
        ));
    }
    Ok(m)
}
