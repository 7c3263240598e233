//! From a parsed scene file to a [`Scene`]: semantic validation (physics and references) and
//! construction of primitives, lights and the BVH. One file per part of the scene file:
//! `materials` (eq. 2's BSDFs), `media` (Table 1), `shapes` (primitives and area lights),
//! `lights` (delta and infinite lights, selection by power), `sensors` (camera and meters);
//! `values` checks the numbers they share. Every error names its line and key.

mod lights;
mod materials;
mod media;
mod sensors;
mod shapes;
mod values;

use glam::Vec3;

pub use media::{
    DEFAULT_FREQUENCY, DEFAULT_OCTAVES, DEFAULT_RELATIVE_STEP, MAX_BAKE_RESOLUTION, MAX_OCTAVES,
};

use super::file::{self, path};
use super::{RenderSettings, Scene, SceneError, SceneSource};
use crate::geometry::{Aabb, Bvh};

/// Default number of irradiance-meter samples per pass.
pub const DEFAULT_METER_SAMPLES: u32 = 4096;

/// Builds the scene described by `src`.
pub fn build(src: &SceneSource) -> Result<Scene, SceneError> {
    let desc = file::parse(&src.text, &src.name)?;
    let materials = materials::materials(src, &desc)?;
    let media = media::Media::build(src, &desc)?;
    let shapes::Surfaces {
        prims,
        prim_shape,
        shapes,
        lights,
    } = shapes::shapes(src, &desc, &materials, &media)?;
    let media::Media {
        media,
        names: medium_names,
        ..
    } = media;

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
    let lights::Lights {
        lights,
        environment,
        light_distr,
    } = lights::build(src, &desc, lights, radius)?;

    let prim_opaque: Vec<bool> = prim_shape
        .iter()
        .map(|&s| !shapes[s as usize].is_null())
        .collect();
    let has_null = prim_opaque.iter().any(|o| !o);
    let bvh = Bvh::build(&prims);

    let render = RenderSettings {
        integrator: desc.render.integrator.clone(),
        spp: desc.render.spp,
        seed: desc.render.seed,
        max_depth: desc.render.max_depth,
        meter_samples: desc.render.meter_samples.unwrap_or(DEFAULT_METER_SAMPLES),
        mlt: mlt_settings(desc.render.mlt.as_ref()),
        smc: smc_settings(src, desc.render.smc.as_ref())?,
        guide: guide_settings(src, desc.render.guide.as_ref(), radius)?,
        adjoint_image: desc.render.adjoint_image.unwrap_or(false),
        adjoint: adjoint_settings(src, desc.render.adjoint.as_ref())?,
    };
    if render.spp == 0 {
        return Err(src.error(&path("render").key("spp"), "spp must be at least 1"));
    }
    if let Err(e) = render.mlt.validate() {
        return Err(src.error(&path("render").key("mlt"), e));
    }

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
        render,
        bounds,
        center,
        radius,
        has_null,
        hash: src.hash(),
        source_name: src.name.clone(),
        adjoint: None,
        guide: None,
    };

    sensors::camera(src, &desc, &mut scene)?;
    sensors::meters(src, &desc, &mut scene)?;
    if scene.camera.is_none() && scene.sensors.is_empty() {
        return Err(src.error(&path("camera"), "the scene has neither a camera nor a sensor, so nothing would be measured: add a [camera] table or a [[sensors]] entry"));
    }
    Ok(scene)
}

/// MLT settings from `[render.mlt]`, defaults where a key is absent.
fn mlt_settings(desc: Option<&crate::scene::file::MltDesc>) -> crate::integrator::mlt::MltSettings {
    let mut m = crate::integrator::mlt::MltSettings::default();
    let Some(d) = desc else { return m };
    if let Some(v) = d.bootstrap {
        m.bootstrap = v;
    }
    if let Some(v) = d.chains {
        m.chains = v;
    }
    if let Some(v) = d.b_refine {
        m.b_refine = v;
    }
    for (i, w) in [
        d.bidirectional,
        d.sensor,
        d.light,
        d.propagation,
        d.multichain,
    ]
    .into_iter()
    .enumerate()
    {
        if let Some(w) = w {
            m.weights[i] = w;
        }
    }
    if let Some([a, b]) = d.sensor_offset {
        m.sensor_offset = (a, b);
    }
    if let Some([a, b]) = d.light_angle {
        m.light_angle = (a, b);
    }
    if let Some([a, b]) = d.propagation_distance {
        m.propagation_distance = (a, b);
    }
    m
}

/// Guide settings from `[render.guide]`, defaults where a key is absent; every value is checked
/// here so that a bad one is reported at its line and key.
fn guide_settings(
    src: &SceneSource,
    desc: Option<&crate::scene::file::GuideDesc>,
    radius: f32,
) -> Result<crate::enlightened::GuideSettings, SceneError> {
    use crate::enlightened::{GuideKind, GuideSettings};
    let mut s = GuideSettings::for_radius(radius);
    let Some(d) = desc else { return Ok(s) };
    let key = |k: &str| path("render").key("guide").key(k);
    if let Some(v) = &d.vertices {
        s.kind = GuideKind::parse(v).map_err(|e| src.error(&key("vertices"), e))?;
    }
    if let Some(m) = &d.map {
        (s.cols, s.rows) = GuideSettings::parse_map(m).map_err(|e| src.error(&key("map"), e))?;
    }
    s.check_regions(d.regions)
        .map_err(|e| src.error(&key("regions"), e))?;
    if let Some(k) = d.regions {
        s.regions.regions = k;
    }
    s.check_particles(d.particles)
        .map_err(|e| src.error(&key("particles"), e))?;
    if let Some(n) = d.particles {
        s.particles = n;
    }
    if let Some(w) = d.weight {
        s.c_guide = GuideSettings::check_weight(w).map_err(|e| src.error(&key("weight"), e))?;
    }
    if let Some(a) = d.alpha {
        s.regions.alpha = GuideSettings::check_alpha(a).map_err(|e| src.error(&key("alpha"), e))?;
    }
    if let Some(m) = d.min_depth {
        if !(1..=64).contains(&m) {
            return Err(src.error(
                &key("min_depth"),
                format!("min_depth = {m} must be in 1..=64"),
            ));
        }
        s.min_depth = m;
    }
    if let Some(r) = d.roulette {
        s.roulette =
            Some(GuideSettings::check_roulette(r).map_err(|e| src.error(&key("roulette"), e))?);
    }
    if let Some(m) = &d.sampler {
        s.sampler = crate::enlightened::guide::ParticleSampler::parse(m)
            .map_err(|e| src.error(&key("sampler"), e))?;
    }
    if let Some(v) = d.sigma {
        s.metropolis.sigma = v;
        s.metropolis
            .check()
            .map_err(|e| src.error(&key("sigma"), e))?;
    }
    if let Some(v) = d.defensive {
        s.metropolis.defensive = v;
        s.metropolis
            .check()
            .map_err(|e| src.error(&key("defensive"), e))?;
    }
    Ok(s)
}

/// Adjoint-image settings from `[render.adjoint]`, defaults where a key is absent; each value
/// is checked here so a bad one is reported at its line and key.
fn adjoint_settings(
    src: &SceneSource,
    desc: Option<&crate::scene::file::AdjointDesc>,
) -> Result<crate::enlightened::AdjointSettings, SceneError> {
    let mut s = crate::enlightened::AdjointSettings::default();
    let Some(d) = desc else { return Ok(s) };
    let key = |k: &str| path("render").key("adjoint").key(k);
    if let Some([c, r]) = d.resolution {
        s.resolution = (c, r);
        crate::enlightened::AdjointSettings {
            resolution: (c, r),
            ..Default::default()
        }
        .validate()
        .map_err(|e| src.error(&key("resolution"), e))?;
    }
    if let Some(n) = d.samples_per_cell {
        s.samples_per_cell = n;
        crate::enlightened::AdjointSettings {
            samples_per_cell: n,
            ..Default::default()
        }
        .validate()
        .map_err(|e| src.error(&key("samples_per_cell"), e))?;
    }
    if let Some(e) = d.epsilon {
        s.epsilon = e;
        crate::enlightened::AdjointSettings {
            epsilon: e,
            ..Default::default()
        }
        .validate()
        .map_err(|m| src.error(&key("epsilon"), m))?;
    }
    if let Some(e) = &d.estimator {
        s.estimator = crate::enlightened::adjoint::AdjointEstimator::parse(e)
            .map_err(|m| src.error(&key("estimator"), m))?;
    }
    Ok(s)
}

/// SMC settings from `[render.smc]`, defaults where a key is absent; every value is checked
/// here so that a bad one is reported at its line and key.
fn smc_settings(
    src: &SceneSource,
    desc: Option<&crate::scene::file::SmcDesc>,
) -> Result<crate::integrator::smc::SmcSettings, SceneError> {
    use crate::integrator::smc::{parse_bytes, EstimatorForm, SmcSettings, Variant};
    let mut s = SmcSettings::default();
    let Some(d) = desc else { return Ok(s) };
    let key = |k: &str| path("render").key("smc").key(k);
    if let Some(v) = &d.variant {
        s.variant = Variant::parse(v).map_err(|e| src.error(&key("variant"), e))?;
    }
    if let Some(t) = d.threshold {
        if !(t.is_finite() && t > 0.0) {
            return Err(src.error(
                &key("threshold"),
                format!("threshold = {t} must be a positive number of records"),
            ));
        }
        s.threshold = t;
    }
    if let Some(b) = &d.cache_budget {
        let bytes = match b {
            file::ByteCount::Bytes(n) => {
                usize::try_from(*n).map_err(|_| format!("cache_budget = {n} is not a byte count"))
            }
            file::ByteCount::Text(t) => parse_bytes(t),
        }
        .map_err(|e| src.error(&key("cache_budget"), e))?;
        let root = crate::integrator::smc::cache::RadianceCache::root().bytes();
        if bytes < root {
            return Err(src.error(
                &key("cache_budget"),
                format!(
                    "cache_budget = {bytes} bytes cannot hold even the root cache ({root} bytes)"
                ),
            ));
        }
        s.budget = bytes;
    }
    let estimator = d.estimator.as_deref().unwrap_or(s.form.name());
    if d.step.is_some() && estimator != "march" {
        return Err(src.error(
            &key("step"),
            format!("step applies to the march estimator, not `{estimator}`"),
        ));
    }
    s.form = EstimatorForm::parse(estimator, d.step).map_err(|e| {
        let k = if d.estimator.is_some() && !matches!(estimator, "march" | "distance") {
            "estimator"
        } else {
            "step"
        };
        src.error(&key(k), e)
    })?;
    Ok(s)
}
