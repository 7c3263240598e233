//! From a parsed scene file to a [`Scene`]: semantic validation (physics and references) and
//! construction of primitives, lights and the BVH.

use glam::Vec3;
use std::collections::{BTreeMap, HashMap};

use super::file::{
    self, path, KeyPath, LightDesc, MaterialDesc, MediumDesc, PhaseDesc, RgbValue, SensorDesc,
    ShapeDesc,
};
use super::file::{AxisDesc, DensityDesc, PropagationDesc};
use super::{
    Camera, Environment, IrradianceMeter, Light, Scene, SceneError, SceneSource, ShapeInfo,
};
use crate::bsdf::Bsdf;
use crate::geometry::shape::{Quad, Sphere, Triangle};
use crate::geometry::{Aabb, Bvh, Primitive};
use crate::math::{Distribution1D, Frame};
use crate::medium::grid::read_grid_file;
use crate::medium::{Axis, Density, Fbm, Field, Grid, Heterogeneous, Homogeneous, LineIntegral};
use crate::medium::{Medium, Phase};

fn finite3(src: &SceneSource, key: &KeyPath, v: [f32; 3]) -> Result<Vec3, SceneError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(Vec3::from_array(v))
    } else {
        Err(src.error(key, format!("{v:?} is not a finite vector")))
    }
}

fn non_negative(
    src: &SceneSource,
    key: &KeyPath,
    v: RgbValue,
    what: &str,
) -> Result<Vec3, SceneError> {
    let c = v.to_rgb();
    if c.to_array().iter().all(|x| x.is_finite() && *x >= 0.0) {
        Ok(c)
    } else {
        Err(src.error(key, format!("{what} must be finite and >= 0, got {v}")))
    }
}

fn albedo(src: &SceneSource, key: &KeyPath, v: RgbValue) -> Result<Vec3, SceneError> {
    let c = non_negative(src, key, v, "an albedo")?;
    if c.max_element() > 1.0 {
        return Err(src.error(
            key,
            format!("albedo {v} is above 1: the surface would reflect more light than it receives"),
        ));
    }
    Ok(c)
}

fn phase(src: &SceneSource, key: &KeyPath, p: &PhaseDesc) -> Result<Phase, SceneError> {
    match p {
        PhaseDesc::Isotropic {} => Ok(Phase::Isotropic),
        PhaseDesc::Hg { g } => Phase::henyey_greenstein(*g).map_err(|e| {
            src.error(
                &key.clone().key("g"),
                format!("{e}: |g| >= 1 is not a phase function"),
            )
        }),
        PhaseDesc::Schlick { k } => {
            Phase::schlick(*k).map_err(|e| src.error(&key.clone().key("k"), e.to_string()))
        }
        PhaseDesc::Mix { weights, lobes } => {
            if weights.len() != lobes.len() {
                return Err(src.error(
                    &key.clone().key("weights"),
                    format!("{} weights for {} lobes", weights.len(), lobes.len()),
                ));
            }
            let mut out = Vec::new();
            for (i, (w, l)) in weights.iter().zip(lobes).enumerate() {
                out.push((*w, phase(src, &key.clone().key("lobes").index(i), l)?));
            }
            Phase::mix(out).map_err(|e| src.error(&key.clone().key("weights"), e.to_string()))
        }
    }
}

/// A closed, consistently oriented triangle mesh: every edge is shared by exactly two
/// triangles that traverse it in opposite directions. Vertices are welded by position first, so
/// an OBJ that splits vertices along seams (for normals or texture coordinates) still counts.
fn mesh_is_closed(positions: &[Vec3], indices: &[u32]) -> bool {
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = positions
        .iter()
        .map(|p| {
            let n = weld.len() as u32;
            *weld.entry(p.to_array().map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in indices.chunks_exact(3) {
        let t = [ids[t[0] as usize], ids[t[1] as usize], ids[t[2] as usize]];
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edges.entry((a, b)).or_insert(0) += 1;
        }
    }
    !edges.is_empty()
        && edges
            .iter()
            .all(|(&(a, b), &c)| c == 1 && edges.get(&(b, a)) == Some(&1))
}

/// Signed volume enclosed by a closed triangle mesh: positive when its normals point outwards.
fn signed_volume(tris: &[Triangle]) -> f32 {
    tris.iter().map(|t| t.p0.dot(t.e1.cross(t.e2)) / 6.0).sum()
}

/// Checks every face index of an OBJ file before tobj sees it, so the error names the OBJ line.
fn check_obj_indices(text: &str) -> Result<(), String> {
    let mut vertices = 0i64;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => vertices += 1,
            Some("f") | Some("l") => {
                for w in words {
                    let Some(Ok(k)) = w.split('/').next().map(str::parse::<i64>) else {
                        return Err(format!("line {}: `{w}` is not a vertex index", n + 1));
                    };
                    // OBJ indices are 1-based; negative ones count back from the last vertex
                    let ok = if k > 0 {
                        k <= vertices
                    } else {
                        k < 0 && -k <= vertices
                    };
                    if !ok {
                        return Err(format!(
                            "line {}: face index {k} is out of range (the file has {vertices} vertices so far)",
                            n + 1
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

fn box_quads(min: Vec3, max: Vec3) -> Vec<Quad> {
    let d = max - min;
    let (dx, dy, dz) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    // each face's u x v points out of the box
    [
        (min, dz, dy),
        (Vec3::new(max.x, min.y, min.z), dy, dz),
        (min, dx, dz),
        (Vec3::new(min.x, max.y, min.z), dz, dx),
        (min, dy, dx),
        (Vec3::new(min.x, min.y, max.z), dx, dy),
    ]
    .into_iter()
    .filter_map(|(o, u, v)| Quad::new(o, u, v))
    .collect()
}

/// Default marching step, as a fraction of the medium box's largest side.
pub const DEFAULT_RELATIVE_STEP: f32 = 1.0 / 64.0;
/// Default fBm parameters of the procedural cloud and plume.
pub const DEFAULT_OCTAVES: u32 = 5;
pub const DEFAULT_FREQUENCY: f32 = 4.0;
/// Accepted fBm octaves (more are below f32 resolution of the lattice hash).
pub const MAX_OCTAVES: u32 = 12;
/// Largest accepted bake resolution (vertices per axis): 256^3 floats are 64 MiB.
pub const MAX_BAKE_RESOLUTION: u32 = 256;

fn key_of(key: &KeyPath, k: &str) -> KeyPath {
    key.clone().key(k)
}

/// A `grid` or `procedural` medium.
fn heterogeneous(src: &SceneSource, key: &KeyPath, m: &MediumDesc) -> Result<Medium, SceneError> {
    let (sigma_a, sigma_s, ph, propagation, step) = match m {
        MediumDesc::Grid {
            sigma_a,
            sigma_s,
            phase,
            propagation,
            step,
            ..
        }
        | MediumDesc::Procedural {
            sigma_a,
            sigma_s,
            phase,
            propagation,
            step,
            ..
        } => (sigma_a, sigma_s, phase, propagation, step),
        MediumDesc::Homogeneous { .. } => unreachable!("only called for grid and procedural"),
    };
    let sa = non_negative(src, &key_of(key, "sigma_a"), *sigma_a, "sigma_a")?;
    let ss = non_negative(src, &key_of(key, "sigma_s"), *sigma_s, "sigma_s")?;
    let ph = phase(src, &key_of(key, "phase"), ph)?;
    let line_integral = match propagation {
        PropagationDesc::Equidistant => LineIntegral::Equidistant,
        PropagationDesc::Stratified => LineIntegral::Stratified,
        PropagationDesc::RandomOffset => LineIntegral::RandomOffset,
        PropagationDesc::DeltaTracking => LineIntegral::DeltaTracking,
    };
    let step = step.unwrap_or(DEFAULT_RELATIVE_STEP);
    if !(step.is_finite() && step > 0.0 && step <= 1.0) {
        return Err(src.error(
            &key_of(key, "step"),
            format!(
                "step = {step} must be in (0, 1] (a fraction of the medium box's largest side)"
            ),
        ));
    }
    let bounds = |lo: Vec3, hi: Vec3, at: &str| -> Result<Aabb, SceneError> {
        if lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all() {
            Ok(Aabb { min: lo, max: hi })
        } else {
            Err(src.error(
                &key_of(key, at),
                format!("the medium box {lo} .. {hi} must be finite with min < max on every axis"),
            ))
        }
    };
    let (density, aabb) = match m {
        MediumDesc::Grid { file, min, max, .. } => {
            let fkey = key_of(key, "file");
            let gf = read_grid_file(&src.base_dir.join(file))
                .map_err(|e| src.error(&fkey, e.to_string()))?;
            let (lo, hi) = match (min, max, gf.bounds) {
                (Some(lo), Some(hi), _) => (
                    finite3(src, &key_of(key, "min"), *lo)?,
                    finite3(src, &key_of(key, "max"), *hi)?,
                ),
                (None, None, Some(b)) => b,
                (Some(_), None, _) | (None, Some(_), _) => {
                    let k = if min.is_none() { "min" } else { "max" };
                    return Err(src.error(&key_of(key, k), "give both `min` and `max`, or neither"));
                }
                (None, None, None) => {
                    return Err(src.error(
                        &key_of(key, "min"),
                        format!(
                            "a text grid has no bounding box: give `min` and `max` for `{file}`"
                        ),
                    ))
                }
            };
            (Density::Grid(gf.grid), bounds(lo, hi, "min")?)
        }
        MediumDesc::Procedural {
            density,
            min,
            max,
            axis,
            from,
            to,
            octaves,
            frequency,
            seed,
            resolution,
            ..
        } => {
            let aabb = bounds(
                finite3(src, &key_of(key, "min"), *min)?,
                finite3(src, &key_of(key, "max"), *max)?,
                "min",
            )?;
            let linear_keys = [
                ("axis", axis.is_some()),
                ("from", from.is_some()),
                ("to", to.is_some()),
            ];
            let noise_keys = [
                ("octaves", octaves.is_some()),
                ("frequency", frequency.is_some()),
                ("seed", seed.is_some()),
            ];
            let reject = |keys: &[(&str, bool)], what: &str| -> Result<(), SceneError> {
                match keys.iter().find(|(_, set)| *set) {
                    Some((k, _)) => Err(src.error(
                        &key_of(key, k),
                        format!("`{k}` applies only to density = {what}"),
                    )),
                    None => Ok(()),
                }
            };
            let fbm = || -> Result<Fbm, SceneError> {
                let octaves = octaves.unwrap_or(DEFAULT_OCTAVES);
                if !(1..=MAX_OCTAVES).contains(&octaves) {
                    return Err(src.error(
                        &key_of(key, "octaves"),
                        format!("octaves = {octaves} must be in 1..={MAX_OCTAVES}"),
                    ));
                }
                let frequency = frequency.unwrap_or(DEFAULT_FREQUENCY);
                if !(frequency.is_finite() && frequency > 0.0) {
                    return Err(src.error(
                        &key_of(key, "frequency"),
                        format!("frequency = {frequency} must be positive"),
                    ));
                }
                Ok(Fbm {
                    octaves,
                    frequency,
                    seed: seed.unwrap_or(0),
                })
            };
            let field = match density {
                DensityDesc::Constant => {
                    reject(&linear_keys, "linear")?;
                    reject(&noise_keys, "cloud or plume")?;
                    Field::Constant
                }
                DensityDesc::Linear => {
                    reject(&noise_keys, "cloud or plume")?;
                    let need = |k: &str, v: Option<f32>| -> Result<f32, SceneError> {
                        match v {
                            None => Err(src.error(
                                key,
                                format!("density = linear needs `{k}` (the density at the {} end of the axis)", if k == "from" { "min" } else { "max" }),
                            )),
                            Some(x) if !(x.is_finite() && x >= 0.0) => Err(src.error(
                                &key_of(key, k),
                                format!("{k} = {x} must be a finite density >= 0"),
                            )),
                            Some(x) => Ok(x),
                        }
                    };
                    let axis = match axis {
                        Some(AxisDesc::X) => Axis::X,
                        Some(AxisDesc::Y) => Axis::Y,
                        Some(AxisDesc::Z) => Axis::Z,
                        None => {
                            return Err(src.error(
                                key,
                                "density = linear needs `axis` (\"x\", \"y\" or \"z\")",
                            ))
                        }
                    };
                    Field::Linear {
                        axis,
                        from: need("from", *from)?,
                        to: need("to", *to)?,
                    }
                }
                DensityDesc::Cloud => {
                    reject(&linear_keys, "linear")?;
                    Field::Cloud(fbm()?)
                }
                DensityDesc::Plume => {
                    reject(&linear_keys, "linear")?;
                    Field::Plume(fbm()?)
                }
            };
            let density = match resolution {
                None => Density::Field(field),
                Some(n) if (2..=MAX_BAKE_RESOLUTION).contains(n) => {
                    Density::Grid(Grid::bake(*n as usize, |u| field.eval(u)))
                }
                Some(n) => {
                    return Err(src.error(
                        &key_of(key, "resolution"),
                        format!("resolution = {n} must be in 2..={MAX_BAKE_RESOLUTION}"),
                    ))
                }
            };
            (density, aabb)
        }
        MediumDesc::Homogeneous { .. } => unreachable!("only called for grid and procedural"),
    };
    let h = Heterogeneous::new(density, aabb, sa, ss, ph, line_integral, step)
        .map_err(|e| src.error(key, e.to_string()))?;
    Ok(Medium::Heterogeneous(Box::new(h)))
}

/// Builds the scene described by `src`.
pub fn build(src: &SceneSource) -> Result<Scene, SceneError> {
    let desc = file::parse(&src.text, &src.name)?;

    // materials
    let mut materials: BTreeMap<String, Bsdf> = BTreeMap::new();
    materials.insert("null".into(), Bsdf::Null);
    for (name, m) in &desc.materials {
        let key = path("materials").key(name);
        if name == "null" {
            return Err(src.error(
                &key,
                "`null` is the built-in index-matched boundary; choose another name",
            ));
        }
        let bsdf = match m {
            MaterialDesc::Lambert { albedo: a } => Bsdf::Lambert {
                albedo: albedo(src, &key.clone().key("albedo"), *a)?,
            },
            MaterialDesc::Mirror { reflectance } => Bsdf::Mirror {
                reflectance: albedo(src, &key.clone().key("reflectance"), *reflectance)?,
            },
            MaterialDesc::Dielectric { ior } => {
                if !(ior.is_finite() && *ior > 0.0) {
                    return Err(src.error(
                        &key.clone().key("ior"),
                        format!("ior = {ior} must be positive"),
                    ));
                }
                Bsdf::Dielectric { ior: *ior }
            }
            MaterialDesc::Null {} => Bsdf::Null,
        };
        materials.insert(name.clone(), bsdf);
    }

    // media
    let mut media = Vec::new();
    let mut medium_names = Vec::new();
    let mut medium_index: HashMap<String, u32> = HashMap::new();
    for (name, m) in &desc.media {
        let key = path("media").key(name);
        let medium = match m {
            MediumDesc::Homogeneous {
                sigma_a,
                sigma_s,
                phase: ph,
            } => {
                let sa = non_negative(src, &key.clone().key("sigma_a"), *sigma_a, "sigma_a")?;
                let ss = non_negative(src, &key.clone().key("sigma_s"), *sigma_s, "sigma_s")?;
                let ph = phase(src, &key.clone().key("phase"), ph)?;
                Medium::Homogeneous(
                    Homogeneous::new(sa, ss, ph).map_err(|e| src.error(&key, e.to_string()))?,
                )
            }
            MediumDesc::Grid { .. } | MediumDesc::Procedural { .. } => heterogeneous(src, &key, m)?,
        };
        medium_index.insert(name.clone(), media.len() as u32);
        media.push(medium);
        medium_names.push(name.clone());
    }
    let find_medium = |key: &KeyPath, name: &Option<String>| -> Result<Option<u32>, SceneError> {
        match name {
            None => Ok(None),
            Some(n) if n == "vacuum" => Ok(None),
            Some(n) => medium_index.get(n).copied().map(Some).ok_or_else(|| {
                let known: Vec<&str> = desc.media.keys().map(String::as_str).collect();
                src.error(
                    key,
                    format!("unknown medium `{n}` (defined: {known:?}, or `vacuum`)"),
                )
            }),
        }
    };

    // shapes
    let mut prims = Vec::new();
    let mut prim_shape = Vec::new();
    let mut shapes = Vec::new();
    let mut lights = Vec::new();
    for (i, s) in desc.shapes.iter().enumerate() {
        let key = path("shapes").index(i);
        let common = s.common();
        let emission = match common.emission {
            Some(e) => Some(non_negative(
                src,
                &key.clone().key("emission"),
                e,
                "emission",
            )?),
            None => None,
        }
        .filter(|e| e.max_element() > 0.0);
        let bsdf = match &common.material {
            Some(m) => Some(materials.get(m).cloned().ok_or_else(|| {
                let known: Vec<&str> = materials.keys().map(String::as_str).collect();
                src.error(
                    &key.clone().key("material"),
                    format!("unknown material `{m}` (defined: {known:?})"),
                )
            })?),
            None if emission.is_some() => None,
            None => {
                return Err(src.error(
                    &key,
                    "a shape needs a `material` (or `emission`, for a black emitter)",
                ))
            }
        };
        if emission.is_some() && matches!(bsdf, Some(Bsdf::Null)) {
            return Err(src.error(&key.clone().key("emission"), "a null boundary cannot emit"));
        }
        let interior = find_medium(&key.clone().key("interior"), &common.interior)?;
        let exterior = find_medium(&key.clone().key("exterior"), &common.exterior)?;
        let interface = common.interior.is_some() || common.exterior.is_some();
        let mut new: Vec<Primitive> = Vec::new();
        let mut closed = true;
        match s {
            ShapeDesc::Quad { origin, u, v, .. } => {
                let o = finite3(src, &key.clone().key("origin"), *origin)?;
                let u = finite3(src, &key.clone().key("u"), *u)?;
                let v = finite3(src, &key.clone().key("v"), *v)?;
                let q = Quad::new(o, u, v).ok_or_else(|| {
                    src.error(
                        &key.clone().key("u"),
                        "u and v are parallel: the quad has no area",
                    )
                })?;
                new.push(Primitive::Quad(q));
                closed = false;
            }
            ShapeDesc::Box { min, max, .. } => {
                let lo = finite3(src, &key.clone().key("min"), *min)?;
                let hi = finite3(src, &key.clone().key("max"), *max)?;
                if !(hi.cmpgt(lo).all()) {
                    return Err(src.error(
                        &key.clone().key("max"),
                        format!("max {max:?} must exceed min {min:?} on every axis"),
                    ));
                }
                new.extend(box_quads(lo, hi).into_iter().map(Primitive::Quad));
            }
            ShapeDesc::Sphere { center, radius, .. } => {
                let c = finite3(src, &key.clone().key("center"), *center)?;
                if !(radius.is_finite() && *radius > 0.0) {
                    return Err(src.error(
                        &key.clone().key("radius"),
                        format!("radius = {radius} must be positive"),
                    ));
                }
                new.push(Primitive::Sphere(Sphere {
                    center: c,
                    radius: *radius,
                }));
            }
            ShapeDesc::Mesh { obj, .. } => {
                let file = src.base_dir.join(obj);
                let obj_key = key.clone().key("obj");
                let text = std::fs::read_to_string(&file).map_err(|e| {
                    src.error(&obj_key, format!("cannot read `{}`: {e}", file.display()))
                })?;
                check_obj_indices(&text)
                    .map_err(|e| src.error(&obj_key, format!("`{}` {e}", file.display())))?;
                let options = tobj::LoadOptions {
                    triangulate: true,
                    single_index: true,
                    ..Default::default()
                };
                let (models, _) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
                    Err(tobj::LoadError::OpenFileFailed) // materials are not used
                })
                .map_err(|e| {
                    src.error(&obj_key, format!("cannot load `{}`: {e}", file.display()))
                })?;
                let mut all_closed = true;
                let mut tris = Vec::new();
                for m in &models {
                    let pos: Vec<Vec3> = m
                        .mesh
                        .positions
                        .chunks_exact(3)
                        .map(|c| Vec3::new(c[0], c[1], c[2]))
                        .collect();
                    let idx = &m.mesh.indices;
                    if idx.iter().any(|&k| k as usize >= pos.len()) {
                        return Err(src.error(
                            &obj_key,
                            format!("`{}`: a face index is out of range", file.display()),
                        ));
                    }
                    if pos.iter().any(|p| !p.is_finite()) {
                        return Err(src.error(
                            &obj_key,
                            format!("`{}`: a vertex is not finite", file.display()),
                        ));
                    }
                    all_closed &= mesh_is_closed(&pos, idx);
                    tris.extend(idx.chunks_exact(3).filter_map(|t| {
                        Triangle::new(pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize])
                    }));
                }
                if tris.is_empty() {
                    return Err(
                        src.error(&obj_key, format!("`{}` has no triangles", file.display()))
                    );
                }
                closed = all_closed;
                if closed && common.interior.is_some() && signed_volume(&tris) < 0.0 {
                    return Err(src.error(
                        &obj_key,
                        format!(
                            "`{}` is wound inside out (its normals point inwards), so `interior` would be outside; reverse the faces' vertex order",
                            file.display()
                        ),
                    ));
                }
                new.extend(tris.into_iter().map(Primitive::Triangle));
            }
        }
        if common.interior.is_some() && !closed {
            return Err(src.error(
                &key.clone().key("interior"),
                format!(
                    "a {} is not a closed shape (a mesh is closed when every edge joins exactly two consistently wound triangles), so it has no inside to hold a medium",
                    s.kind()
                ),
            ));
        }
        let shape_id = shapes.len() as u32;
        let light = emission.map(|radiance| {
            let first = prims.len() as u32;
            let ids: Vec<u32> = (first..first + new.len() as u32).collect();
            let areas: Vec<f32> = new.iter().map(Primitive::area).collect();
            lights.push(Light::Area {
                shape: shape_id,
                prims: ids,
                distr: Distribution1D::new(&areas),
                area: areas.iter().sum(),
                radiance,
            });
            (lights.len() - 1) as u32
        });
        for p in new {
            prims.push(p);
            prim_shape.push(shape_id);
        }
        shapes.push(ShapeInfo {
            bsdf,
            light,
            interior,
            exterior,
            interface,
            label: format!("shapes[{i}] ({})", s.kind()),
        });
    }

    let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()));
    let (center, radius) = if bounds.is_empty() {
        (Vec3::ZERO, 1.0)
    } else {
        (
            bounds.centroid(),
            (0.5 * bounds.extent().length()).max(1e-3),
        )
    };

    // delta and infinite lights
    let mut environment = None;
    for (i, l) in desc.lights.iter().enumerate() {
        let key = path("lights").index(i);
        let light = match l {
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
                intensity: non_negative(
                    src,
                    &key.clone().key("intensity"),
                    *intensity,
                    "intensity",
                )?,
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
            LightDesc::Environment {
                radiance,
                zenith,
                horizon,
                nadir,
            } => {
                if environment.is_some() {
                    return Err(src.error(&key, "only one environment light is allowed"));
                }
                let env = match (radiance, zenith, horizon, nadir) {
                    (Some(r), None, None, None) => {
                        Environment::Constant(non_negative(src, &key.clone().key("radiance"), *r, "radiance")?)
                    }
                    (None, Some(z), Some(h), Some(n)) => Environment::Gradient {
                        zenith: non_negative(src, &key.clone().key("zenith"), *z, "zenith")?,
                        horizon: non_negative(src, &key.clone().key("horizon"), *h, "horizon")?,
                        nadir: non_negative(src, &key.clone().key("nadir"), *n, "nadir")?,
                    },
                    _ => {
                        return Err(src.error(
                            &key,
                            "an environment takes either `radiance` or all of `zenith`, `horizon`, `nadir`",
                        ))
                    }
                };
                environment = Some(lights.len() as u32);
                Light::Environment(env)
            }
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

    let prim_opaque: Vec<bool> = prim_shape
        .iter()
        .map(|&s| !shapes[s as usize].is_null())
        .collect();
    let has_null = prim_opaque.iter().any(|o| !o);
    let bvh = Bvh::build(&prims);

    let mut scene = Scene {
        prims,
        prim_shape,
        prim_opaque,
        bvh,
        shapes,
        media,
        medium_names,
        lights,
        light_distr,
        environment,
        camera: None,
        camera_medium: None,
        sensors: Vec::new(),
        bounds,
        center,
        radius,
        has_null,
        hash: src.hash(),
        source_name: src.name.clone(),
        adjoint: None,
        guide: None,
    };

    if let Some(file::CameraDesc::Pinhole {
        eye,
        look_at,
        up,
        fov_deg,
        resolution,
    }) = &desc.camera
    {
        let key = path("camera");
        let eye = finite3(src, &key.clone().key("eye"), *eye)?;
        let look_at = finite3(src, &key.clone().key("look_at"), *look_at)?;
        let up = finite3(src, &key.clone().key("up"), *up)?;
        if !(*fov_deg > 0.0 && *fov_deg < 180.0) {
            return Err(src.error(
                &key.clone().key("fov_deg"),
                format!("fov_deg = {fov_deg} must be in (0, 180)"),
            ));
        }
        if resolution[0] == 0
            || resolution[1] == 0
            || resolution[0] > 16384
            || resolution[1] > 16384
        {
            return Err(src.error(
                &key.clone().key("resolution"),
                format!("resolution {resolution:?} must be in 1..=16384"),
            ));
        }
        if (look_at - eye).length_squared() == 0.0 {
            return Err(src.error(
                &key.clone().key("look_at"),
                "look_at equals eye: the camera looks nowhere",
            ));
        }
        let cam = Camera::new(eye, look_at, up, *fov_deg, resolution[0], resolution[1])
            .ok_or_else(|| {
                src.error(
                    &key.clone().key("up"),
                    "up is zero or parallel to the viewing direction look_at - eye",
                )
            })?;
        scene.camera_medium = scene.medium_at(eye);
        scene.camera = Some(cam);
    }
    for (i, s) in desc.sensors.iter().enumerate() {
        let key = path("sensors").index(i);
        match s {
            SensorDesc::IrradianceMeter { name, origin, u, v } => {
                let o = finite3(src, &key.clone().key("origin"), *origin)?;
                let u = finite3(src, &key.clone().key("u"), *u)?;
                let v = finite3(src, &key.clone().key("v"), *v)?;
                let quad = Quad::new(o, u, v).ok_or_else(|| {
                    src.error(
                        &key.clone().key("u"),
                        "u and v are parallel: the meter has no area",
                    )
                })?;
                if scene
                    .sensors
                    .iter()
                    .any(|m: &IrradianceMeter| &m.name == name)
                {
                    return Err(src.error(
                        &key.clone().key("name"),
                        format!("two sensors are called `{name}`"),
                    ));
                }
                let centre = o + 0.5 * (u + v);
                let medium = scene.medium_at(centre);
                scene.sensors.push(IrradianceMeter {
                    name: name.clone(),
                    quad,
                    medium,
                });
            }
        }
    }
    if scene.camera.is_none() && scene.sensors.is_empty() {
        return Err(src.error(&path("camera"), "the scene has neither a camera nor a sensor, so nothing would be measured: add a [camera] table or a [[sensors]] entry"));
    }
    Ok(scene)
}
