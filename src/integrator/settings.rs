//! The render settings of a scene file's `[render]` table, apart from the [`Scene`]: loading a
//! scene file yields the scene and its settings separately ([`load`]), so the scene (a lower
//! layer) knows nothing of the integrators that render it, and the settings (which name the
//! integrators' own structs) live with the integrators.
//! Book: "Scenes" (the `[render]` table); tests: `tests/inputs/scene_errors.rs`, `tests/spec/integrator/settings/smc.rs`.

use serde::{Deserialize, Serialize};

use crate::bidir::MisHeuristic;
use crate::enlightened::adjoint::AdjointEstimator;
use crate::enlightened::guide::ParticleSampler;
use crate::enlightened::{AdjointError, AdjointSettings, GuideError, GuideKind, GuideSettings};
use crate::integrator::mlt::{MltOptions, MltSettings};
use crate::integrator::path::DistanceSampling;
use crate::integrator::pssmlt::{PssmltOptions, PssmltSettings};
use crate::integrator::smc::{OptionError, SmcOptions, SmcSettings};
use crate::integrator::{IntegratorKind, PixelSamples};
use crate::medium::TransmittanceEstimator;
use crate::scene::file::{self, path};
use crate::scene::light::LightPointDraw;
use crate::scene::LightSelectionKind;
use crate::scene::{Scene, SceneError, SceneSource};

/// The render settings' view of a scene file: its `[render]` table (the rest is the scene's).
#[derive(Debug, Clone, Default, Deserialize)]
struct RenderFile {
    #[serde(default)]
    render: RenderOptions,
}

/// The render options, declared once: each field is a `[render]` key of the scene file (serde)
/// and a flag of `pathspace render` (clap) with one doc, its default in
/// [`RenderOptions::defaults`].
/// [`RenderSettings::apply`] puts a set of them over the settings and checks every value: the
/// file's over the defaults at load, the flags over the file's on the command line. The
/// integrators' own options are the nested tables (`[render.mlt]`: `--mlt-*`, ...); a render
/// records the options it was given ([`RenderOptions::over`]) in its `--json` and EXR header.
#[derive(clap::Args, Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[command(next_help_heading = "Render (each also a [render] key of the scene file)")]
pub struct RenderOptions {
    /// Integrator (default path).
    #[arg(long)]
    pub integrator: Option<IntegratorKind>,
    /// Samples per pixel (default 64); for mlt, mutations per pixel.
    #[arg(long, conflicts_with_all = ["time", "mutations_per_pixel"])]
    pub spp: Option<u32>,
    /// Random seed (default 1).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Maximum number of scattering vertices (default: unlimited, Russian roulette).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Samples per irradiance meter per pixel-sample pass (default 4096).
    #[arg(long)]
    pub meter_samples: Option<u32>,
    /// path: distance sampling on the walk's rays, `free-flight` (default) or `equiangular-mis`
    /// (free flight and equiangular sampling toward a light point, Kulla and Fajardo 2012,
    /// combined by MIS on every ray; homogeneous or tracked media, not marched ones).
    #[arg(long)]
    pub distance: Option<DistanceSampling>,
    /// path: light selection for next-event estimation, `tree` (default: a light hierarchy
    /// weighing lights by what they can deliver to the shading point, Conty Estevez and Kulla
    /// 2018) or `power` (proportional to power everywhere).
    #[arg(long)]
    pub light_selection: Option<LightSelectionKind>,
    /// path: how next-event estimation draws a point on an area light, `solid-angle-near`
    /// (default: uniform by solid angle over a quad or triangle whose centre is within one side
    /// of the shading point, by area elsewhere) or `area` (uniform by area, as light subpaths start;
    /// always so with `--distance equiangular-mis`).
    #[arg(long)]
    pub light_point: Option<LightPointDraw>,
    /// path: the probability, in [0, 1), with which a medium vertex or a surface without a
    /// Dirac lobe draws its direction uniformly in the cone toward the halo (the bounding
    /// sphere) of a light chosen as next-event estimation chooses it, instead of by its own
    /// sampling (default 0.0: never; 0.1 suits a few lamps in open fog). Refused with the guide.
    #[arg(long)]
    pub halo_cone: Option<f32>,
    /// path, bdpt, smc: where each camera sample's film position lies in its pixel,
    /// `stratified` (default: the pixel's points of a (0, 2)-sequence, digitally shifted per
    /// pixel and seed) or `independent` (uniform and independent: the variance layers then
    /// estimate the variance of each pixel's mean, which stratified positions make them
    /// overstate across edges).
    #[arg(long)]
    pub pixel_samples: Option<PixelSamples>,
    /// bdpt, pssmlt, mmlt: how BDPT's strategies share each path, `balance` (default: the
    /// balance heuristic) or `power` (the power heuristic, Veach 1997, sec. 9.2).
    #[arg(long)]
    pub mis_heuristic: Option<MisHeuristic>,
    /// path: next-event estimation toward emitting media, a point of the glowing media sampled
    /// as a light and combined by MIS with the emission the walk collects (default true;
    /// `--volume-next-event=false` collects the emission along free flights alone).
    #[arg(long, num_args = 0..=1, require_equals = true, default_missing_value = "true", value_name = "BOOL")]
    pub volume_next_event: Option<bool>,
    /// Transmittance estimator of media propagated by delta tracking, for shadow rays and
    /// connections (path, light, bdpt, smc): `ratio-tracking` (default) or `delta-tracking`
    /// (1 or 0 per channel: cheaper walks, more variance). MLT's target uses the exact value.
    #[arg(long)]
    pub transmittance: Option<TransmittanceEstimator>,
    /// bdpt, light, mlt: sample area-light start points from the adjoint image (Kristensen
    /// 2010, sec. 5.3.1), estimated by a BDPT pre-pass first (default false;
    /// `--adjoint-image=false` turns off the file's).
    #[arg(long, num_args = 0..=1, require_equals = true, default_missing_value = "true", value_name = "BOOL")]
    pub adjoint_image: Option<bool>,
    /// `[render.mlt]`: Metropolis light transport (the `--mlt-*` options).
    #[command(flatten)]
    #[serde(default, skip_serializing_if = "is_default")]
    pub mlt: MltOptions,
    /// `[render.pssmlt]`: primary-sample-space MLT (the `--pssmlt-*` options).
    #[command(flatten)]
    #[serde(default, skip_serializing_if = "is_default")]
    pub pssmlt: PssmltOptions,
    /// `[render.smc]`: sequential Monte Carlo (the `--smc-*` options).
    #[command(flatten)]
    #[serde(default, skip_serializing_if = "is_default")]
    pub smc: SmcOptions,
    /// `[render.guide]`: guided local sampling, enlightened local path sampling (the
    /// `--guide*` options).
    #[command(flatten)]
    #[serde(default, skip_serializing_if = "is_default")]
    pub guide: GuideOptions,
    /// `[render.adjoint]`: the adjoint image's grid, pre-pass size and floor (the
    /// `--adjoint-*` options).
    #[command(flatten)]
    #[serde(default, skip_serializing_if = "is_default")]
    pub adjoint: AdjointOptions,
}

fn is_default<T: Default + PartialEq>(t: &T) -> bool {
    *t == T::default()
}

impl RenderOptions {
    /// The default of every `[render]` key, written once: [`RenderSettings`] starts from them,
    /// and tests check the flags' help and the book's key table against them (`max_depth`'s
    /// `None` is unlimited; the nested tables' defaults are their settings' own).
    pub fn defaults() -> RenderOptions {
        RenderOptions {
            integrator: Some(IntegratorKind::Path),
            spp: Some(64),
            seed: Some(1),
            max_depth: None,
            meter_samples: Some(DEFAULT_METER_SAMPLES),
            distance: Some(DistanceSampling::FreeFlight),
            light_selection: Some(LightSelectionKind::Tree),
            light_point: Some(LightPointDraw::SolidAngleNear),
            halo_cone: Some(DEFAULT_HALO_CONE),
            pixel_samples: Some(PixelSamples::Stratified),
            mis_heuristic: Some(MisHeuristic::Balance),
            volume_next_event: Some(true),
            transmittance: Some(TransmittanceEstimator::RatioTracking),
            adjoint_image: Some(false),
            ..Default::default()
        }
    }

    /// These options over `base` (each given one replaces base's, at any depth): the flags
    /// over the file's, as a render records them. Generic over the fields, so a new option
    /// needs no edit here.
    pub fn over(&self, base: &RenderOptions) -> RenderOptions {
        fn merge(base: &mut serde_json::Value, top: serde_json::Value) {
            match (base, top) {
                (serde_json::Value::Object(b), serde_json::Value::Object(t)) => {
                    for (k, v) in t {
                        merge(b.entry(k).or_insert(serde_json::Value::Null), v);
                    }
                }
                (_, serde_json::Value::Null) => {}
                (b, t) => *b = t,
            }
        }
        let to_value = |o: &RenderOptions| serde_json::to_value(o).expect("options serialize");
        let mut merged = to_value(base);
        merge(&mut merged, to_value(self));
        serde_json::from_value(merged).expect("merged options deserialize")
    }

    /// The given options as a JSON object, the absent ones left out (`--json`'s `options`).
    pub fn to_json(&self) -> serde_json::Value {
        fn prune(v: serde_json::Value) -> Option<serde_json::Value> {
            match v {
                serde_json::Value::Null => None,
                serde_json::Value::Object(m) => {
                    let m: serde_json::Map<_, _> = m
                        .into_iter()
                        .filter_map(|(k, v)| Some((k, prune(v)?)))
                        .collect();
                    (!m.is_empty()).then_some(serde_json::Value::Object(m))
                }
                v => Some(v),
            }
        }
        prune(serde_json::to_value(self).expect("options serialize"))
            .unwrap_or_else(|| serde_json::json!({}))
    }

    /// The given options as the `[render]` table that repeats them (the EXR header's
    /// `render_options`: paste it into the scene file to render the same image again).
    pub fn to_toml(&self) -> String {
        #[derive(Serialize)]
        struct Table<'a> {
            render: &'a RenderOptions,
        }
        toml::to_string(&Table { render: self }).unwrap_or_else(|e| format!("# {e}"))
    }
}

/// A render option whose value is refused: where it is (`table` under `[render]`, empty for
/// `[render]` itself, and the key when the message is about one) and why, the message naming
/// it as the caller spells it (a file key or a flag).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct SettingError {
    pub table: &'static str,
    pub key: Option<&'static str>,
    pub message: String,
}

impl SettingError {
    fn at(table: &'static str, key: Option<&'static str>, message: impl ToString) -> Self {
        SettingError {
            table,
            key,
            message: message.to_string(),
        }
    }
}

/// The adjoint image's options (Kristensen 2010, sec. 5.3.1), declared once: the
/// `[render.adjoint]` keys (serde) and the `--adjoint-*` flags (clap) are the same fields with
/// the same docs (defaults in `enlightened::adjoint`); [`AdjointOptions::apply_spelled`] puts the
/// file's over the defaults, [`AdjointOptions::apply`] the flags over the file's, both checked by
/// [`AdjointSettings::validate`].
#[derive(clap::Args, Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[command(next_help_heading = "Adjoint image (bdpt, light, mlt; [render.adjoint])")]
pub struct AdjointOptions {
    /// Adjoint grid COLSxROWS (`[columns, rows]` in the file; columns rounded up to a multiple
    /// of the area lights; default 64x64).
    #[arg(id = "adjoint_resolution", long = "adjoint-resolution", value_parser = parse_grid)]
    #[serde(default, deserialize_with = "crate::scene::file::exact_opt")]
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
    pub estimator: Option<AdjointEstimator>,
}

impl AdjointOptions {
    /// True when any option was given.
    pub fn any(&self) -> bool {
        *self != AdjointOptions::default()
    }

    /// `base` with these options as flags over it, checked (the messages name the flags).
    pub fn apply(&self, base: AdjointSettings) -> Result<AdjointSettings, AdjointError> {
        self.apply_spelled(base, Spelling::Flag)
            .map_err(|e| AdjointError::Option(e.message))
    }

    /// `base` with these options over it, each value checked alone so that a bad one is
    /// reported at its key or flag, as `spelling` names it.
    pub fn apply_spelled(
        &self,
        base: AdjointSettings,
        spelling: Spelling,
    ) -> Result<AdjointSettings, OptionError> {
        let alone = |key: &'static str, one: AdjointSettings| {
            one.validate()
                .map_err(|e| spelling.refusal("adjoint", key, e))
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
        if let Some(e) = self.estimator {
            s.estimator = e;
        }
        Ok(s)
    }
}

/// Parses a grid `COLSxROWS` into the `[columns, rows]` of the file's key.
fn parse_grid(s: &str) -> Result<[u32; 2], SizeError> {
    parse_size(s).map(|(c, r)| [c, r])
}

/// A `WxH` that is not one: the text, and the part that is not a size.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SizeError {
    /// No `x` between two sizes (the text).
    #[error("`{0}` is not WIDTHxHEIGHT, e.g. 64x64")]
    NotWxH(String),
    /// A side that is no integer in 1..=16384 (the side, the text).
    #[error("`{0}` in `{1}` is not a size in 1..=16384")]
    OutOfRange(String, String),
}

/// Parses `WxH` (a camera resolution or a grid), each size in 1..=16384.
pub fn parse_size(s: &str) -> Result<(u32, u32), SizeError> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| SizeError::NotWxH(s.into()))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| SizeError::OutOfRange(v.into(), s.into()))
    };
    Ok((parse(w)?, parse(h)?))
}

/// How the caller spells an option in its messages: as a file key (the caller adds the file,
/// line and key) or as a flag. The validations build each message once, about the value alone;
/// [`Spelling::refusal`] names the option as the caller spells it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spelling {
    Key,
    Flag,
}

impl Spelling {
    /// Option `key` of table `table` (`""` for `[render]` itself) as this spelling names it:
    /// the key, or its flag (the table a prefix, `--guide` for the guide's `vertices`).
    pub fn name(self, table: &str, key: &str) -> String {
        match (self, table, key) {
            (Spelling::Key, _, k) => k.to_string(),
            (Spelling::Flag, "guide", "vertices") => "--guide".into(),
            (Spelling::Flag, "", k) => format!("--{}", k.replace('_', "-")),
            (Spelling::Flag, t, k) => format!("--{t}-{}", k.replace('_', "-")),
        }
    }

    /// The refusal of option `key` of `table`, `why` its value is refused: bare for a key
    /// (its location names it), after the flag on the command line.
    pub fn refusal(self, table: &str, key: &'static str, why: impl ToString) -> OptionError {
        let why = why.to_string();
        let message = match self {
            Spelling::Key => why,
            Spelling::Flag => format!("{}: {why}", self.name(table, key)),
        };
        OptionError { key, message }
    }
}

/// The options of guided local sampling (Kristensen 2010, sec. 5.3; book chapter "Enlightened
/// local path sampling: guiding"), declared once: the `[render.guide]` keys (serde) and the
/// `--guide-*` flags (clap; `vertices` is `--guide`) are the same fields with the same docs
/// (defaults in `enlightened::guide`); [`GuideOptions::apply`] puts them over the settings
/// and checks every value.
#[derive(clap::Args, Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[command(next_help_heading = "Guiding (path, light, bdpt, mlt, pssmlt, mmlt; [render.guide])")]
pub struct GuideOptions {
    /// Guide directions at `surface`, `volume` (medium) or `both` kinds of vertices, or `off`.
    #[arg(id = "guide_vertices", long = "guide", alias = "guide-vertices")]
    pub vertices: Option<GuideKind>,
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
    pub sampler: Option<ParticleSampler>,
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

    /// The keys of the given options other than `vertices` when `vertices` itself was never
    /// given: nothing guides then, so they would change nothing (an explicit `off` keeps a
    /// file's guide table quiet).
    pub fn without_guiding(&self) -> Vec<String> {
        if self.vertices.is_some() {
            return Vec::new();
        }
        match toml::Value::try_from(self) {
            Ok(toml::Value::Table(t)) => t.keys().cloned().collect(),
            _ => Vec::new(),
        }
    }

    /// `base` with these options as flags over it, checked (the messages name the flags).
    pub fn apply_flags(&self, base: GuideSettings) -> Result<GuideSettings, OptionError> {
        self.apply(base, Spelling::Flag)
    }

    /// `base` with every given option replacing its setting, each checked; a message names
    /// the option as `spelling` does (a bare message for a key, `--guide-map: ...` for a flag).
    pub fn apply(
        &self,
        base: GuideSettings,
        spelling: Spelling,
    ) -> Result<GuideSettings, OptionError> {
        let err = |key: &'static str, e: GuideError| spelling.refusal("guide", key, e);
        let mut s = base;
        if let Some(v) = self.vertices {
            s.kind = v;
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
                let why = format!("{m} is not a depth in 1..=64");
                return Err(spelling.refusal("guide", "min_depth", why));
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
        if let Some(m) = self.sampler {
            s.sampler = m;
        }
        let check = |s: &GuideSettings, key: &'static str| {
            s.metropolis
                .check()
                .map_err(|e| spelling.refusal("guide", key, e))
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

/// Default number of irradiance-meter samples per pass.
pub const DEFAULT_METER_SAMPLES: u32 = 4096;

/// The path tracer's default probability of the cone toward a light's halo at a scattering
/// vertex: off, since the cone loses on most of the papers' scenes (book: "Sampling toward
/// lights", section "The scattering direction").
pub const DEFAULT_HALO_CONE: f32 = 0.0;

/// The settings a render runs with: the defaults, the scene's `[render]` table over them and
/// the command line's flags over those ([`RenderSettings::apply`]).
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub integrator: IntegratorKind,
    pub spp: u32,
    pub seed: u64,
    pub max_depth: Option<u32>,
    pub meter_samples: u32,
    /// The path tracer's distance sampling on its rays (`[render] distance`).
    pub distance: DistanceSampling,
    /// The path tracer's light selection for next-event estimation (`[render] light_selection`).
    pub light_selection: LightSelectionKind,
    /// How the path tracer's next-event estimation draws area lights' points
    /// (`[render] light_point`).
    pub light_point: LightPointDraw,
    /// The path tracer's probability of a cone toward a light's halo at medium vertices and
    /// surfaces without a Dirac lobe (`[render] halo_cone`).
    pub halo_cone: f32,
    /// Where each camera sample's film position lies in its pixel (`[render] pixel_samples`).
    pub pixel_samples: PixelSamples,
    /// How BDPT's strategies share a path (`[render] mis_heuristic`).
    pub mis_heuristic: MisHeuristic,
    /// The path tracer's next-event estimation toward emitting media
    /// (`[render] volume_next_event`).
    pub volume_next_event: bool,
    /// The tracking media's transmittance estimator (`[render] transmittance`), set on the
    /// scene's media by [`RenderSettings::prepare`].
    pub transmittance: TransmittanceEstimator,
    /// Metropolis light transport settings (`[render.mlt]`).
    pub mlt: MltSettings,
    /// Primary-sample-space MLT settings (`[render.pssmlt]`).
    pub pssmlt: PssmltSettings,
    /// Sequential Monte Carlo settings (`[render.smc]`).
    pub smc: SmcSettings,
    /// Guided local sampling (`[render.guide]`).
    pub guide: GuideSettings,
    /// Sample area-light starts from the adjoint image (`[render] adjoint_image`).
    pub adjoint_image: bool,
    /// The adjoint image's grid, pre-pass and floor (`[render.adjoint]`).
    pub adjoint: AdjointSettings,
    /// The options these settings were given, in the order applied (a render's record).
    pub given: RenderOptions,
}

impl RenderSettings {
    /// The defaults of every option for a scene of radius `radius` (the guide's alpha
    /// depends on it).
    fn defaults(radius: f32) -> Self {
        let d = RenderOptions::defaults();
        let given = "every top-level default is given";
        RenderSettings {
            integrator: d.integrator.expect(given),
            spp: d.spp.expect(given),
            seed: d.seed.expect(given),
            max_depth: d.max_depth,
            meter_samples: d.meter_samples.expect(given),
            distance: d.distance.expect(given),
            light_selection: d.light_selection.expect(given),
            light_point: d.light_point.expect(given),
            halo_cone: d.halo_cone.expect(given),
            pixel_samples: d.pixel_samples.expect(given),
            mis_heuristic: d.mis_heuristic.expect(given),
            volume_next_event: d.volume_next_event.expect(given),
            transmittance: d.transmittance.expect(given),
            mlt: MltSettings::default(),
            pssmlt: PssmltSettings::default(),
            smc: SmcSettings::default(),
            guide: GuideSettings::for_radius(radius),
            adjoint_image: d.adjoint_image.expect(given),
            adjoint: AdjointSettings::default(),
            given: RenderOptions::default(),
        }
    }

    /// The settings of an empty `[render]` table for `scene`: what programs that build their
    /// own renderers start from.
    pub fn for_scene(scene: &Scene) -> Self {
        Self::defaults(scene.radius)
    }

    /// The settings of `src`'s `[render]` table for a scene of radius `radius`, every value
    /// checked and a bad one reported at its line and key.
    pub fn from_source(src: &SceneSource, radius: f32) -> Result<Self, SceneError> {
        let file: RenderFile = file::parse_as(&src.text, &src.name).map_err(|e| src.relocate(e))?;
        let mut settings = Self::defaults(radius);
        settings.apply(&file.render, Spelling::Key).map_err(|e| {
            let mut at = path("render");
            if !e.table.is_empty() {
                at = at.key(e.table);
            }
            if let Some(k) = e.key {
                at = at.key(k);
            }
            src.error(&at, e.message)
        })?;
        Ok(settings)
    }

    /// Puts every given option of `o` over these settings and checks it; a message names the
    /// option as `spelling` does (`spp` in a file, `--spp` on the command line). Which
    /// integrator takes an option is the caller's to check (a file's keys are defaults for
    /// the integrators they apply to).
    pub fn apply(&mut self, o: &RenderOptions, spelling: Spelling) -> Result<(), SettingError> {
        self.integrator = o.integrator.unwrap_or(self.integrator);
        if let Some(n) = o.spp {
            if n == 0 {
                let m = format!("{} must be at least 1", spelling.name("", "spp"));
                return Err(SettingError::at("", Some("spp"), m));
            }
            self.spp = n;
        }
        self.seed = o.seed.unwrap_or(self.seed);
        self.max_depth = o.max_depth.or(self.max_depth);
        self.meter_samples = o.meter_samples.unwrap_or(self.meter_samples);
        self.distance = o.distance.unwrap_or(self.distance);
        self.light_selection = o.light_selection.unwrap_or(self.light_selection);
        self.light_point = o.light_point.unwrap_or(self.light_point);
        if let Some(a) = o.halo_cone {
            if !(0.0..1.0).contains(&a) {
                let m = format!(
                    "{} must be in [0, 1) (the vertex's own sampling keeps the rest: with 1 no direction outside the cones could be drawn), not {a}",
                    spelling.name("", "halo_cone")
                );
                return Err(SettingError::at("", Some("halo_cone"), m));
            }
            self.halo_cone = a;
        }
        self.pixel_samples = o.pixel_samples.unwrap_or(self.pixel_samples);
        self.mis_heuristic = o.mis_heuristic.unwrap_or(self.mis_heuristic);
        self.volume_next_event = o.volume_next_event.unwrap_or(self.volume_next_event);
        self.transmittance = o.transmittance.unwrap_or(self.transmittance);
        self.adjoint_image = o.adjoint_image.unwrap_or(self.adjoint_image);
        o.mlt.apply(&mut self.mlt);
        self.mlt
            .validate()
            .map_err(|e| SettingError::at("mlt", None, e))?;
        o.pssmlt.apply(&mut self.pssmlt);
        self.pssmlt
            .validate()
            .map_err(|e| SettingError::at("pssmlt", None, e))?;
        let name = |k: &str| spelling.name("smc", k);
        let at = |table, e: OptionError| SettingError::at(table, Some(e.key), e.message);
        self.smc = o.smc.apply(self.smc, &name).map_err(|e| at("smc", e))?;
        self.guide = o
            .guide
            .apply(self.guide, spelling)
            .map_err(|e| at("guide", e))?;
        self.adjoint = o
            .adjoint
            .apply_spelled(self.adjoint, spelling)
            .map_err(|e| at("adjoint", e))?;
        self.given = o.over(&self.given);
        Ok(())
    }
}

impl RenderSettings {
    /// Puts the settings that live in the scene's media on `scene` (the transmittance
    /// estimator of tracking media), before a render of these settings.
    pub fn prepare(&self, scene: &mut Scene) {
        scene.set_transmittance_estimator(self.transmittance);
    }
}

/// Loads a scene file: the scene, and its `[render]` settings apart from it.
pub fn load(src: &SceneSource) -> Result<(Scene, RenderSettings), SceneError> {
    let mut scene = Scene::load(src)?;
    let settings = RenderSettings::from_source(src, scene.radius)?;
    settings.prepare(&mut scene);
    Ok((scene, settings))
}
