//! The render settings of a scene file's `[render]` table, apart from the [`Scene`]: loading a
//! scene file yields the scene and its settings separately ([`load`]), so the scene (a lower
//! layer) knows nothing of the integrators that render it, and the settings (which name the
//! integrators' own structs) live with the integrators.
//! Book: "Scenes" (the `[render]` table); tests: `tests/scene_errors.rs`, `tests/smc_settings.rs`.

use serde::Deserialize;

use crate::enlightened::{AdjointSettings, GuideError, GuideSettings};
use crate::integrator::mlt::{MltOptions, MltSettings};
use crate::integrator::smc::{OptionError, SmcOptions, SmcSettings};
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
    pub guide: Option<GuideOptions>,
    /// Sample area-light start points from the adjoint image (bdpt, light, mlt; Kristensen
    /// 2010, sec. 5.3.1).
    pub adjoint_image: Option<bool>,
    /// `[render.adjoint]`: the adjoint image's grid, pre-pass size and floor.
    pub adjoint: Option<AdjointOptions>,
}

/// The adjoint image's options (Kristensen 2010, sec. 5.3.1), declared once: the
/// `[render.adjoint]` keys (serde) and the `--adjoint-*` flags (clap) are the same fields with
/// the same docs (defaults in `enlightened::adjoint`); [`AdjointOptions::apply_keys`] puts the
/// file's over the defaults, [`AdjointOptions::apply`] the flags over the file's, both checked by
/// [`AdjointSettings::validate`].
#[derive(clap::Args, Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AdjointOptions {
    /// Adjoint grid COLSxROWS (`[columns, rows]` in the file; columns rounded up to a multiple
    /// of the area lights; default 64x64).
    #[arg(id = "adjoint_resolution", long = "adjoint-resolution", value_parser = parse_grid)]
    pub resolution: Option<[u32; 2]>,
    /// Pre-pass samples (BDPT) or chain steps (Metropolis) per adjoint cell (default 8).
    #[arg(
        id = "adjoint_samples_per_cell",
        long = "adjoint-samples-per-cell",
        visible_alias = "adjoint-samples"
    )]
    pub samples_per_cell: Option<u32>,
    /// Floor added to every adjoint cell, as a fraction of the mean cell (default 0.5).
    #[arg(id = "adjoint_epsilon", long = "adjoint-epsilon")]
    pub epsilon: Option<f32>,
    /// How the pre-pass estimates the cells: `bdpt` (default) or `metropolis` (chains of the
    /// Metropolis particle sampler).
    #[arg(id = "adjoint_estimator", long = "adjoint-estimator")]
    pub estimator: Option<String>,
}

impl AdjointOptions {
    /// True when any option was given.
    pub fn any(&self) -> bool {
        *self != AdjointOptions::default()
    }

    /// `base` with these options as flags over it, checked (the messages name the flags).
    pub fn apply(&self, base: AdjointSettings) -> Result<AdjointSettings, String> {
        base.overridden(
            self.resolution.map(|[c, r]| (c, r)),
            self.samples_per_cell,
            self.epsilon,
            self.estimator.as_deref(),
        )
        .map_err(String::from)
    }

    /// `base` with these options as file keys over it, each value checked alone so that a bad
    /// one is reported at its key.
    pub fn apply_keys(&self, base: AdjointSettings) -> Result<AdjointSettings, OptionError> {
        let err = |key: &'static str, message: String| OptionError { key, message };
        let alone = |key: &'static str, one: AdjointSettings| {
            one.validate().map_err(|e| err(key, e.to_string()))
        };
        let mut s = base;
        if let Some([c, r]) = self.resolution {
            s.resolution = (c, r);
            let one = AdjointSettings {
                resolution: (c, r),
                ..Default::default()
            };
            alone("resolution", one)?;
        }
        if let Some(n) = self.samples_per_cell {
            s.samples_per_cell = n;
            let one = AdjointSettings {
                samples_per_cell: n,
                ..Default::default()
            };
            alone("samples_per_cell", one)?;
        }
        if let Some(e) = self.epsilon {
            s.epsilon = e;
            let one = AdjointSettings {
                epsilon: e,
                ..Default::default()
            };
            alone("epsilon", one)?;
        }
        if let Some(e) = &self.estimator {
            s.estimator = crate::enlightened::adjoint::AdjointEstimator::parse(e)
                .map_err(|m| err("estimator", m.to_string()))?;
        }
        Ok(s)
    }
}

/// Parses a grid `COLSxROWS` into the `[columns, rows]` of the file's key.
fn parse_grid(s: &str) -> Result<[u32; 2], String> {
    parse_size(s).map(|(c, r)| [c, r])
}

/// Parses `WxH` (a camera resolution or a grid), each size in 1..=16384.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WIDTHxHEIGHT, e.g. 64x64"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| format!("`{v}` in `{s}` is not a size in 1..=16384"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// How an option is spelled in the messages of [`GuideOptions::apply`]: as a file key (the
/// caller adds the file, line and key) or as a `--guide-*` flag.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spelling {
    Key,
    Flag,
}

/// The options of guided local sampling (Kristensen 2010, sec. 5.3; book chapter "Enlightened
/// local path sampling: guiding"), declared once: the `[render.guide]` keys (serde) and the
/// `--guide-*` flags (clap; `vertices` is `--guide`) are the same fields with the same docs
/// (defaults in `enlightened::guide`); [`GuideOptions::apply`] puts them over the settings
/// and checks every value.
#[derive(clap::Args, Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GuideOptions {
    /// Guide directions at `surface`, `volume` (medium) or `both` kinds of vertices, or `off`.
    #[arg(id = "guide_vertices", long = "guide", alias = "guide-vertices")]
    pub vertices: Option<String>,
    /// Direction map resolution COLSxROWS (default 32x16, the thesis's).
    #[arg(id = "guide_map", long = "guide-map")]
    pub map: Option<String>,
    /// Regions (k-means centres) per quantity (default 512).
    #[arg(id = "guide_regions", long = "guide-regions")]
    pub regions: Option<usize>,
    /// Light and eye subpaths traced for photons and importons (default 200000 each).
    #[arg(id = "guide_particles", long = "guide-particles")]
    pub particles: Option<usize>,
    /// c2 of eqs. (5.17)-(5.19), the probability of sampling the map, in (0, 1) (default 0.5).
    #[arg(id = "guide_weight", long = "guide-weight")]
    pub weight: Option<f32>,
    /// alpha of eq. (5.16) per unit length (default 20 / scene radius).
    #[arg(id = "guide_alpha", long = "guide-alpha")]
    pub alpha: Option<f32>,
    /// Guided Russian roulette with this normalization (default: the ordinary roulette).
    #[arg(id = "guide_roulette", long = "guide-roulette")]
    pub roulette: Option<f32>,
    /// Only particles at this depth or deeper shape the maps (default 1: all; 2: indirect
    /// light and importance only).
    #[arg(id = "guide_min_depth", long = "guide-min-depth")]
    pub min_depth: Option<u32>,
    /// Particle sampler of the guide: `classical` (default), `bidirectional` or `metropolis`.
    #[arg(id = "guide_sampler", long = "guide-sampler")]
    pub sampler: Option<String>,
    /// Metropolis particles: small-step deviation in primary sample space (default 1/64).
    #[arg(id = "guide_sigma", long = "guide-sigma")]
    pub sigma: Option<f64>,
    /// Metropolis particles: weight delta of the defensive part of the target (default 0.1;
    /// 0 is the thesis's eq. (5.15) alone).
    #[arg(id = "guide_defensive", long = "guide-defensive")]
    pub defensive: Option<f64>,
}

impl GuideOptions {
    /// True when any option was given.
    pub fn any(&self) -> bool {
        *self != GuideOptions::default()
    }

    /// The flags' spelling of key `k` (`--guide` for `vertices`).
    fn flag(k: &str) -> String {
        match k {
            "vertices" => "--guide".into(),
            k => format!("--guide-{}", k.replace('_', "-")),
        }
    }

    /// `base` with these options as flags over it, checked (the messages name the flags).
    pub fn apply_flags(&self, base: GuideSettings) -> Result<GuideSettings, String> {
        self.apply(base, Spelling::Flag).map_err(|e| e.message)
    }

    /// `base` with every given option replacing its setting, each checked; a message names
    /// the option as `spelling` does (a bare message for a key, `--guide-map: ...` for a flag).
    pub fn apply(
        &self,
        base: GuideSettings,
        spelling: Spelling,
    ) -> Result<GuideSettings, OptionError> {
        use crate::enlightened::GuideKind;
        let err = |key: &'static str, e: GuideError| OptionError {
            key,
            message: match spelling {
                Spelling::Key => e.to_string(),
                Spelling::Flag => format!("{}: {e}", Self::flag(key)),
            },
        };
        let mut s = base;
        if let Some(v) = &self.vertices {
            s.kind = GuideKind::parse(v).map_err(|e| err("vertices", e))?;
        }
        if let Some(m) = &self.map {
            (s.cols, s.rows) = GuideSettings::parse_map(m).map_err(|e| err("map", e))?;
        }
        s.check_regions(self.regions)
            .map_err(|e| err("regions", e))?;
        if let Some(k) = self.regions {
            s.regions.regions = k;
        }
        s.check_particles(self.particles)
            .map_err(|e| err("particles", e))?;
        if let Some(n) = self.particles {
            s.particles = n;
        }
        if let Some(w) = self.weight {
            s.c_guide = GuideSettings::check_weight(w).map_err(|e| err("weight", e))?;
        }
        if let Some(a) = self.alpha {
            s.regions.alpha = GuideSettings::check_alpha(a).map_err(|e| err("alpha", e))?;
        }
        self.apply_sampler(&mut s, spelling)?;
        if let Some(m) = self.min_depth {
            if !(1..=64).contains(&m) {
                let message = match spelling {
                    Spelling::Key => format!("min_depth = {m} must be in 1..=64"),
                    Spelling::Flag => format!("--guide-min-depth {m} must be in 1..=64"),
                };
                return Err(OptionError {
                    key: "min_depth",
                    message,
                });
            }
            s.min_depth = m;
        }
        if let Some(r) = self.roulette {
            s.roulette = Some(GuideSettings::check_roulette(r).map_err(|e| err("roulette", e))?);
        }
        Ok(s)
    }

    /// The particle sampler and its Metropolis parameters (sigma, defensive), checked.
    fn apply_sampler(&self, s: &mut GuideSettings, spelling: Spelling) -> Result<(), OptionError> {
        if let Some(m) = &self.sampler {
            s.sampler =
                crate::enlightened::guide::ParticleSampler::parse(m).map_err(|e| OptionError {
                    key: "sampler",
                    message: match spelling {
                        Spelling::Key => e.to_string(),
                        Spelling::Flag => format!("--guide-sampler: {e}"),
                    },
                })?;
        }
        let check = |s: &GuideSettings, key: &'static str| {
            s.metropolis.check().map_err(|e| OptionError {
                key,
                message: match spelling {
                    Spelling::Key => e.to_string(),
                    Spelling::Flag => format!("--guide-sigma / --guide-defensive: {e}"),
                },
            })
        };
        if let Some(v) = self.sigma {
            s.metropolis.sigma = v;
            check(s, "sigma")?;
        }
        if let Some(v) = self.defensive {
            s.metropolis.defensive = v;
            check(s, "defensive")?;
        }
        Ok(())
    }
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
    desc: Option<&GuideOptions>,
    radius: f32,
) -> Result<GuideSettings, SceneError> {
    let s = GuideSettings::for_radius(radius);
    let Some(d) = desc else { return Ok(s) };
    d.apply(s, Spelling::Key)
        .map_err(|e| src.error(&path("render").key("guide").key(e.key), e.message))
}

/// Adjoint-image settings from `[render.adjoint]`, defaults where a key is absent; each value
/// is checked here so a bad one is reported at its line and key.
fn adjoint_settings(
    src: &SceneSource,
    desc: Option<&AdjointOptions>,
) -> Result<AdjointSettings, SceneError> {
    let s = AdjointSettings::default();
    let Some(d) = desc else { return Ok(s) };
    d.apply_keys(s)
        .map_err(|e| src.error(&path("render").key("adjoint").key(e.key), e.message))
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
