//! `[media.NAME]`: Table 1's media, homogeneous (left column) and inhomogeneous (right
//! column: density grids and procedural fields, ray marching or delta tracking), with the
//! checks that report a bad value at its line and key.

use glam::Vec3;
use std::collections::HashMap;

use super::values::{finite3, key_of, non_negative};
use crate::geometry::Aabb;
use crate::medium::grid::read_grid_file_hashed;
use crate::medium::vdb::read_vdb_file_hashed;
use crate::medium::{Axis, Density, Fbm, Field, Grid, Heterogeneous, Homogeneous, LineIntegral};
use crate::medium::{Medium, MediumError, Phase};
use crate::scene::file::{
    path, AxisDesc, DensityDesc, KeyPath, MediumDesc, PhaseDesc, PropagationDesc, RgbValue,
    SceneFile,
};
use crate::scene::{SceneError, SceneSource};

/// Default marching step, as a fraction of the medium box's largest side.
pub const DEFAULT_RELATIVE_STEP: f32 = 1.0 / 64.0;
/// The grid a `vdb` medium reads when `grid` is not given (the name OpenVDB tools give smoke).
pub const DEFAULT_VDB_GRID: &str = "density";
/// Default fBm parameters of the procedural cloud and plume.
pub const DEFAULT_OCTAVES: u32 = 5;
pub const DEFAULT_FREQUENCY: f32 = 4.0;
/// Accepted fBm octaves (more are below f32 resolution of the lattice hash).
pub const MAX_OCTAVES: u32 = 12;
/// Largest accepted bake resolution (vertices per axis): 256^3 floats are 64 MiB.
pub const MAX_BAKE_RESOLUTION: u32 = 256;

/// A phase function of eq. (1), `mix` lobes checked one by one.
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

/// The media of the file, in the order of their names, and how shapes find them.
pub(super) struct Media {
    /// The media, indexed by `Scene::media`'s index.
    pub(super) media: Vec<Medium>,
    /// Their names, for messages.
    pub(super) names: Vec<String>,
    index: HashMap<String, u32>,
}

impl Media {
    /// Builds every `[media.NAME]` table.
    pub(super) fn build(src: &SceneSource, desc: &SceneFile) -> Result<Self, SceneError> {
        let mut media = Vec::new();
        let mut names = Vec::new();
        let mut index: HashMap<String, u32> = HashMap::new();
        for (name, m) in &desc.media {
            let key = path("media").key(name);
            let medium = match m {
                MediumDesc::Homogeneous {
                    sigma_a,
                    sigma_s,
                    phase: ph,
                    ..
                } => {
                    let sa = non_negative(src, &key.clone().key("sigma_a"), *sigma_a, "sigma_a")?;
                    let ss = non_negative(src, &key.clone().key("sigma_s"), *sigma_s, "sigma_s")?;
                    let ph = phase(src, &key.clone().key("phase"), ph)?;
                    Medium::Homogeneous(
                        Homogeneous::new(sa, ss, ph).map_err(|e| src.error(&key, e.to_string()))?,
                    )
                }
                MediumDesc::Grid {
                    sigma_a,
                    sigma_s,
                    phase,
                    propagation,
                    step,
                    file,
                    min,
                    max,
                    ..
                } => {
                    let coefficients = (sigma_a, sigma_s, phase, propagation, step);
                    heterogeneous(src, &key, coefficients, || grid(src, &key, file, min, max))?
                }
                MediumDesc::Procedural {
                    sigma_a,
                    sigma_s,
                    phase,
                    propagation,
                    step,
                    ..
                } => {
                    let coefficients = (sigma_a, sigma_s, phase, propagation, step);
                    heterogeneous(src, &key, coefficients, || procedural(src, &key, m))?
                }
                MediumDesc::Vdb {
                    sigma_a,
                    sigma_s,
                    phase,
                    propagation,
                    step,
                    file,
                    grid,
                    ..
                } => {
                    let coefficients = (sigma_a, sigma_s, phase, propagation, step);
                    heterogeneous(src, &key, coefficients, || vdb(src, &key, file, grid))?
                }
            };
            let medium = emitting(src, &key, medium, m)?;
            index.insert(name.clone(), media.len() as u32);
            media.push(medium);
            names.push(name.clone());
        }
        Ok(Media {
            media,
            names,
            index,
        })
    }

    /// The medium `name` of a shape's `interior` or `exterior` (`None` and `vacuum` are no
    /// medium), or an error at `key` naming the defined ones.
    pub(super) fn find(
        &self,
        src: &SceneSource,
        desc: &SceneFile,
        key: &KeyPath,
        name: &Option<String>,
    ) -> Result<Option<u32>, SceneError> {
        match name {
            None => Ok(None),
            Some(n) if n == "vacuum" => Ok(None),
            Some(n) => self.index.get(n).copied().map(Some).ok_or_else(|| {
                let known: Vec<&str> = desc.media.keys().map(String::as_str).collect();
                src.error(
                    key,
                    format!("unknown medium `{n}` (defined: {known:?}, or `vacuum`)"),
                )
            }),
        }
    }
}

/// `medium` with the table's `emission` (L_e,V0 of eq. 1, per unit density in an
/// inhomogeneous medium), checked at its key.
fn emitting(
    src: &SceneSource,
    key: &KeyPath,
    medium: Medium,
    m: &MediumDesc,
) -> Result<Medium, SceneError> {
    let (MediumDesc::Homogeneous { emission, .. }
    | MediumDesc::Grid { emission, .. }
    | MediumDesc::Procedural { emission, .. }
    | MediumDesc::Vdb { emission, .. }) = m;
    let Some(e) = emission else {
        return Ok(medium);
    };
    let at = key_of(key, "emission");
    let e = non_negative(src, &at, *e, "emission (L_e,V0, radiance per unit length)")?;
    medium
        .with_emission(e)
        .map_err(|err| src.error(&at, err.to_string()))
}

/// The keys an inhomogeneous medium shares: `sigma_a`, `sigma_s`, `phase`, `propagation` and
/// `step`.
type Coefficients<'a> = (
    &'a RgbValue,
    &'a RgbValue,
    &'a PhaseDesc,
    &'a PropagationDesc,
    &'a Option<f32>,
);

/// A `grid` or `procedural` medium: its shared keys checked, then its density and box.
fn heterogeneous(
    src: &SceneSource,
    key: &KeyPath,
    (sigma_a, sigma_s, ph, propagation, step): Coefficients,
    density: impl FnOnce() -> Result<(Density, Aabb), SceneError>,
) -> Result<Medium, SceneError> {
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
    let (density, aabb) = density()?;
    let h = Heterogeneous::new(density, aabb, sa, ss, ph, line_integral, step).map_err(|e| {
        // the work bounds name the key that sets them
        let at = match e {
            MediumError::MarchSteps { .. } => key_of(key, "step"),
            MediumError::TrackingDepth { .. } if sa.max_element() >= ss.max_element() => {
                key_of(key, "sigma_a")
            }
            MediumError::TrackingDepth { .. } => key_of(key, "sigma_s"),
            _ => key.clone(),
        };
        src.error(&at, e.to_string())
    })?;
    Ok(Medium::Heterogeneous(Box::new(h)))
}

/// The box [lo, hi] of an inhomogeneous medium, finite with lo < hi on every axis, or an error
/// at the key `at`.
fn medium_box(
    src: &SceneSource,
    key: &KeyPath,
    lo: Vec3,
    hi: Vec3,
    at: &str,
) -> Result<Aabb, SceneError> {
    if lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all() {
        Ok(Aabb { min: lo, max: hi })
    } else {
        Err(src.error(
            &key_of(key, at),
            format!("the medium box {lo} .. {hi} must be finite with min < max on every axis"),
        ))
    }
}

/// A density grid read from `file` (text or Mitsuba `.vol`), over `min`/`max` or the box the
/// `.vol` brings.
fn grid(
    src: &SceneSource,
    key: &KeyPath,
    file: &str,
    min: &Option<[f32; 3]>,
    max: &Option<[f32; 3]>,
) -> Result<(Density, Aabb), SceneError> {
    let fkey = key_of(key, "file");
    let (gf, hash) = read_grid_file_hashed(&src.base_dir.join(file))
        .map_err(|e| src.error(&fkey, e.to_string()))?;
    src.record_input(file, hash);
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
                format!("a text grid has no bounding box: give `min` and `max` for `{file}`"),
            ))
        }
    };
    Ok((Density::Grid(gf.grid), medium_box(src, key, lo, hi, "min")?))
}

/// The float grid `grid` (default `density`) of the OpenVDB `file`, over the world box its
/// transform gives.
fn vdb(
    src: &SceneSource,
    key: &KeyPath,
    file: &str,
    grid: &Option<String>,
) -> Result<(Density, Aabb), SceneError> {
    let name = grid.as_deref().unwrap_or(DEFAULT_VDB_GRID);
    let (gf, hash) = read_vdb_file_hashed(&src.base_dir.join(file), name)
        .map_err(|e| src.error(&key_of(key, "file"), e.to_string()))?;
    src.record_input(file, hash);
    let (lo, hi) = gf.bounds.expect("a VDB grid brings its box");
    Ok((
        Density::Grid(gf.grid),
        medium_box(src, key, lo, hi, "file")?,
    ))
}

/// A procedural density field over [min, max], evaluated on the fly or baked onto a grid; keys
/// of another `density` are refused.
fn procedural(
    src: &SceneSource,
    key: &KeyPath,
    m: &MediumDesc,
) -> Result<(Density, Aabb), SceneError> {
    let MediumDesc::Procedural {
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
    } = m
    else {
        unreachable!("only called for procedural media")
    };
    let aabb = medium_box(
        src,
        key,
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
    let field = match density {
        DensityDesc::Constant => {
            reject(&linear_keys, "linear")?;
            reject(&noise_keys, "cloud or plume")?;
            Field::Constant
        }
        DensityDesc::Linear => {
            reject(&noise_keys, "cloud or plume")?;
            linear(src, key, axis, *from, *to)?
        }
        DensityDesc::Cloud => {
            reject(&linear_keys, "linear")?;
            Field::Cloud(fbm(src, key, *octaves, *frequency, *seed)?)
        }
        DensityDesc::Plume => {
            reject(&linear_keys[1..], "linear")?;
            Field::Plume {
                fbm: fbm(src, key, *octaves, *frequency, *seed)?,
                axis: axis.map_or(Axis::Y, axis_of),
            }
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
    Ok((density, aabb))
}

/// `density = linear`: the axis and the densities at its `min` (`from`) and `max` (`to`) ends.
fn linear(
    src: &SceneSource,
    key: &KeyPath,
    axis: &Option<AxisDesc>,
    from: Option<f32>,
    to: Option<f32>,
) -> Result<Field, SceneError> {
    let need = |k: &str, v: Option<f32>| -> Result<f32, SceneError> {
        match v {
            None => Err(src.error(
                key,
                format!(
                    "density = linear needs `{k}` (the density at the {} end of the axis)",
                    if k == "from" { "min" } else { "max" }
                ),
            )),
            Some(x) if !(x.is_finite() && x >= 0.0) => Err(src.error(
                &key_of(key, k),
                format!("{k} = {x} must be a finite density >= 0"),
            )),
            Some(x) => Ok(x),
        }
    };
    let Some(axis) = axis.map(axis_of) else {
        return Err(src.error(key, "density = linear needs `axis` (\"x\", \"y\" or \"z\")"));
    };
    Ok(Field::Linear {
        axis,
        from: need("from", from)?,
        to: need("to", to)?,
    })
}

fn axis_of(axis: AxisDesc) -> Axis {
    match axis {
        AxisDesc::X => Axis::X,
        AxisDesc::Y => Axis::Y,
        AxisDesc::Z => Axis::Z,
    }
}

/// The fBm parameters of `cloud` and `plume`, defaults where a key is absent.
fn fbm(
    src: &SceneSource,
    key: &KeyPath,
    octaves: Option<u32>,
    frequency: Option<f32>,
    seed: Option<u32>,
) -> Result<Fbm, SceneError> {
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
}
