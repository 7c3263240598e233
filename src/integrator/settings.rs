//! The render settings of a scene file's `[render]` table, apart from the [`Scene`]: loading a
//! scene file yields the scene and its settings separately ([`load`]), so the scene (a lower
//! layer) knows nothing of the integrators that render it, and the settings (which name the
//! integrators' own structs) live with the integrators.
//! Book: "Scenes" (the `[render]` table); tests: `tests/scene_errors.rs`, `tests/smc_settings.rs`.

use crate::enlightened::{AdjointSettings, GuideSettings};
use crate::integrator::mlt::MltSettings;
use crate::integrator::smc::SmcSettings;
use crate::scene::file::{self, path};
use crate::scene::{Scene, SceneError, SceneSource};

/// Default number of irradiance-meter samples per pass.
pub const DEFAULT_METER_SAMPLES: u32 = 4096;

/// Rendering defaults from the scene's `[render]` table; the command line overrides them.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub integrator: String,
    pub spp: u32,
    pub seed: u64,
    pub max_depth: Option<u32>,
    pub meter_samples: u32,
    /// Metropolis light transport settings (`[render.mlt]`).
    pub mlt: MltSettings,
    /// Sequential Monte Carlo settings (`[render.smc]`, defaults where a key is absent); the
    /// `--smc-*` options override them.
    pub smc: SmcSettings,
    /// Guided local sampling (`[render.guide]`; `--guide*` options override it).
    pub guide: GuideSettings,
    /// `[render] adjoint_image`: sample area-light starts from the adjoint image.
    pub adjoint_image: bool,
    /// `[render.adjoint]` (defaults where a key is absent); `--adjoint-*` override them.
    pub adjoint: AdjointSettings,
}

impl RenderSettings {
    /// The settings of an empty `[render]` table for `scene` (the guide's alpha depends on the
    /// scene's radius): what programs that build their own renderers start from.
    pub fn for_scene(scene: &Scene) -> Self {
        Self::from_desc(
            &SceneSource::embedded("defaults", ""),
            &file::RenderDesc::default(),
            scene.radius,
        )
        .expect("the defaults are valid")
    }

    /// The settings of `src`'s `[render]` table for a scene of radius `radius`, every value
    /// checked and a bad one reported at its line and key.
    pub fn from_source(src: &SceneSource, radius: f32) -> Result<Self, SceneError> {
        let desc = file::parse(&src.text, &src.name)?;
        Self::from_desc(src, &desc.render, radius)
    }

    fn from_desc(
        src: &SceneSource,
        desc: &file::RenderDesc,
        radius: f32,
    ) -> Result<Self, SceneError> {
        let render = RenderSettings {
            integrator: desc.integrator.clone(),
            spp: desc.spp,
            seed: desc.seed,
            max_depth: desc.max_depth,
            meter_samples: desc.meter_samples.unwrap_or(DEFAULT_METER_SAMPLES),
            mlt: mlt_settings(desc.mlt.as_ref()),
            smc: smc_settings(src, desc.smc.as_ref())?,
            guide: guide_settings(src, desc.guide.as_ref(), radius)?,
            adjoint_image: desc.adjoint_image.unwrap_or(false),
            adjoint: adjoint_settings(src, desc.adjoint.as_ref())?,
        };
        if render.spp == 0 {
            return Err(src.error(&path("render").key("spp"), "spp must be at least 1"));
        }
        if let Err(e) = render.mlt.validate() {
            return Err(src.error(&path("render").key("mlt"), e));
        }
        Ok(render)
    }
}

/// Loads a scene file: the scene, and its `[render]` settings apart from it.
pub fn load(src: &SceneSource) -> Result<(Scene, RenderSettings), SceneError> {
    let scene = Scene::load(src)?;
    let settings = RenderSettings::from_source(src, scene.radius)?;
    Ok((scene, settings))
}

/// MLT settings from `[render.mlt]`, defaults where a key is absent.
fn mlt_settings(desc: Option<&file::MltDesc>) -> MltSettings {
    let mut m = MltSettings::default();
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
    desc: Option<&file::GuideDesc>,
    radius: f32,
) -> Result<GuideSettings, SceneError> {
    use crate::enlightened::GuideKind;
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
    desc: Option<&file::AdjointDesc>,
) -> Result<AdjointSettings, SceneError> {
    let mut s = AdjointSettings::default();
    let Some(d) = desc else { return Ok(s) };
    let key = |k: &str| path("render").key("adjoint").key(k);
    if let Some([c, r]) = d.resolution {
        s.resolution = (c, r);
        AdjointSettings {
            resolution: (c, r),
            ..Default::default()
        }
        .validate()
        .map_err(|e| src.error(&key("resolution"), e))?;
    }
    if let Some(n) = d.samples_per_cell {
        s.samples_per_cell = n;
        AdjointSettings {
            samples_per_cell: n,
            ..Default::default()
        }
        .validate()
        .map_err(|e| src.error(&key("samples_per_cell"), e))?;
    }
    if let Some(e) = d.epsilon {
        s.epsilon = e;
        AdjointSettings {
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
    desc: Option<&file::SmcDesc>,
) -> Result<SmcSettings, SceneError> {
    use crate::integrator::smc::{parse_bytes, EstimatorForm, Variant};
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
