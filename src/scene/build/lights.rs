//! `[[lights]]`: delta lights (directional, point, spot) and the environment, appended after
//! the area lights of the shapes, and the power distribution that picks a light for
//! next-event estimation and light paths.

use super::values::{finite3, non_negative};
use crate::math::{Distribution1D, Frame};
use crate::scene::file::{path, KeyPath, LightDesc, RgbValue, SceneFile};
use crate::scene::{Environment, Light, SceneError, SceneSource};

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
            LightDesc::Environment {
                radiance,
                zenith,
                horizon,
                nadir,
            } => {
                if environment.is_some() {
                    return Err(src.error(&key, "only one environment light is allowed"));
                }
                let env = environment_light(src, &key, radiance, zenith, horizon, nadir)?;
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

/// The environment: constant `radiance`, or the `zenith`/`horizon`/`nadir` gradient.
fn environment_light(
    src: &SceneSource,
    key: &KeyPath,
    radiance: &Option<RgbValue>,
    zenith: &Option<RgbValue>,
    horizon: &Option<RgbValue>,
    nadir: &Option<RgbValue>,
) -> Result<Environment, SceneError> {
    Ok(match (radiance, zenith, horizon, nadir) {
        (Some(r), None, None, None) => Environment::Constant(non_negative(
            src,
            &key.clone().key("radiance"),
            *r,
            "radiance",
        )?),
        (None, Some(z), Some(h), Some(n)) => Environment::Gradient {
            zenith: non_negative(src, &key.clone().key("zenith"), *z, "zenith")?,
            horizon: non_negative(src, &key.clone().key("horizon"), *h, "horizon")?,
            nadir: non_negative(src, &key.clone().key("nadir"), *n, "nadir")?,
        },
        _ => {
            return Err(src.error(
                key,
                "an environment takes either `radiance` or all of `zenith`, `horizon`, `nadir`",
            ))
        }
    })
}
