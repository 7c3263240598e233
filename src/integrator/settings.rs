//! The render settings of a scene file's `[render]` table, apart from the [`Scene`]: loading a
//! scene file yields the scene and its settings separately ([`load`]), so the scene (a lower
//! layer) knows nothing of the integrators that render it, and the settings (which name the
//! integrators' own structs) live with the integrators.
//! Book: "Scenes" (the `[render]` table); tests: `tests/scene_errors.rs`, `tests/smc_settings.rs`.

use serde::Deserialize;

use crate::enlightened::{AdjointSettings, GuideSettings};
use crate::integrator::mlt::{MltOptions, MltSettings};
use crate::integrator::smc::{SmcOptions, SmcSettings};
use crate::scene::file::{self, path};
use crate::scene::{Scene, SceneError, SceneSource};

/// The render settings' view of a scene file: its `[render]` table (the rest is the scene's).
#[derive(Debug, Clone, Default, Deserialize)]
struct RenderFile {
    #[serde(default)]
    render: RenderDesc,
}

/// `[render]`: the scene file's defaults for the command-line options.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    #[serde(default = "default_integrator")]
    pub integrator: String,
    #[serde(default = "default_spp")]
    pub spp: u32,
    #[serde(default = "default_seed")]
    pub seed: u64,
    pub max_depth: Option<u32>,
    /// Samples per irradiance meter per pixel-sample pass (default 4096).
    pub meter_samples: Option<u32>,
    /// `[render.mlt]`: Metropolis light transport settings (the `--mlt-*` options).
    pub mlt: Option<MltOptions>,
    /// `[render.smc]`: sequential Monte Carlo settings (the `--smc-*` options).
    pub smc: Option<SmcOptions>,
    /// `[render.guide]`: guided local sampling (enlightened local path sampling).
    pub guide: Option<GuideDesc>,
    /// Sample area-light start points from the adjoint image (bdpt, light, mlt; Kristensen
    /// 2010, sec. 5.3.1).
    pub adjoint_image: Option<bool>,
    /// `[render.adjoint]`: the adjoint image's grid, pre-pass size and floor.
    pub adjoint: Option<AdjointDesc>,
}

/// `[render.adjoint]`: the keys of the `--adjoint-*` options (defaults in
/// `enlightened::adjoint`), which override them.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AdjointDesc {
    /// Grid [columns, rows]; columns are rounded up to a multiple of the area lights.
    pub resolution: Option<[u32; 2]>,
    /// Pre-pass BDPT samples per grid cell.
    pub samples_per_cell: Option<u32>,
    /// Floor added to every cell, as a fraction of the mean cell value.
    pub epsilon: Option<f32>,
    /// `bdpt` (default) or `metropolis`: how the pre-pass estimates the cells.
    pub estimator: Option<String>,
}

/// `[render.guide]`: the keys of the `--guide*` options (defaults in `enlightened::guide`),
/// which override them.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GuideDesc {
    /// `off`, `surface`, `volume` or `both`.
    pub vertices: Option<String>,
    /// Map resolution `COLSxROWS` (default `32x16`).
    pub map: Option<String>,
    /// Regions per quantity (k-means centres).
    pub regions: Option<usize>,
    /// Light and eye subpaths traced for the photons and importons.
    pub particles: Option<usize>,
    /// c2 of eqs. (5.17)-(5.19): probability of sampling the map, in (0, 1).
    pub weight: Option<f32>,
    /// alpha of eq. (5.16) per unit length (default 20 / scene radius).
    pub alpha: Option<f32>,
    /// Guided Russian roulette with this normalization (absent: the ordinary roulette).
    pub roulette: Option<f32>,
    /// Only particles at this depth or deeper shape the maps (1: all, 2: indirect only).
    pub min_depth: Option<u32>,
    /// Particle sampler: `classical`, `bidirectional` or `metropolis`.
    pub sampler: Option<String>,
    /// Metropolis particles: small-step deviation in primary sample space.
    pub sigma: Option<f64>,
    /// Metropolis particles: weight of the defensive part of the target.
    pub defensive: Option<f64>,
}

fn default_integrator() -> String {
    "path".into()
}
fn default_spp() -> u32 {
    64
}
fn default_seed() -> u64 {
    1
}

impl Default for RenderDesc {
    fn default() -> Self {
        RenderDesc {
            integrator: default_integrator(),
            spp: default_spp(),
            seed: default_seed(),
            max_depth: None,
            meter_samples: None,
            mlt: None,
            smc: None,
            guide: None,
            adjoint_image: None,
            adjoint: None,
        }
    }
}

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
            &RenderDesc::default(),
            scene.radius,
        )
        .expect("the defaults are valid")
    }

    /// The settings of `src`'s `[render]` table for a scene of radius `radius`, every value
    /// checked and a bad one reported at its line and key.
    pub fn from_source(src: &SceneSource, radius: f32) -> Result<Self, SceneError> {
        let desc: RenderFile = file::parse_as(&src.text, &src.name)?;
        Self::from_desc(src, &desc.render, radius)
    }

    fn from_desc(src: &SceneSource, desc: &RenderDesc, radius: f32) -> Result<Self, SceneError> {
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

/// MLT settings from `[render.mlt]`, defaults where a key is absent (checked by the caller).
fn mlt_settings(desc: Option<&MltOptions>) -> MltSettings {
    let mut m = MltSettings::default();
    if let Some(d) = desc {
        d.apply(&mut m);
    }
    m
}

/// Guide settings from `[render.guide]`, defaults where a key is absent; every value is checked
/// here so that a bad one is reported at its line and key.
fn guide_settings(
    src: &SceneSource,
    desc: Option<&GuideDesc>,
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
    desc: Option<&AdjointDesc>,
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
fn smc_settings(src: &SceneSource, desc: Option<&SmcOptions>) -> Result<SmcSettings, SceneError> {
    let Some(d) = desc else {
        return Ok(SmcSettings::default());
    };
    d.apply(SmcSettings::default(), &|k| k.to_string())
        .map_err(|e| src.error(&path("render").key("smc").key(e.key), e.message))
}
