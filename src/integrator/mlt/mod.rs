//! Metropolis light transport for participating media (Pauly, Kollig, Keller 2000, sec. 5;
//! Veach 1997 ch. 11): a random walk x_0, x_1, ... through path space whose stationary density
//! is f*/b, with f* the luminance of the image contribution f (f_j = h_j f) and
//! b = integral of f* over path space. Each step proposes y by a mutation chosen at random,
//! accepts it with alpha of eq. (8), and deposits b/N at the image positions: with Veach's
//! expected-value splatting, alpha (b/N) f(y)/f*(y) at y's pixel and (1 - alpha) (b/N)
//! f(x)/f*(x) at x's.
//!
//! - `contribution`: f with singular scattering, densities of vertices (Dirac-free);
//! - `init`: the BDPT pre-pass that estimates b and seeds the chains (sec. 5.1);
//! - `acceptance`: eq. (8);
//! - `mutation`: bidirectional, sensor (lens), light (caustic), propagation, multi-chain;
//!   a thin lens's point is the path's camera vertex, redrawn by the bidirectional mutation
//!   and kept by the perturbations (the sensor perturbation moves the film point about it);
//! - `trace`: local sampling and deterministic retracing of vertices.
//!
//! Chains are independent, each with its own seed path and random stream
//! (`Sampler::new(seed, chain, 0)`), run in parallel and merged in chain order: an image depends
//! on the seed and the chain count, never on the thread count.
//! Book: "Metropolis light transport".

pub mod acceptance;
pub mod contribution;
pub mod init;
pub mod mutation;
pub mod trace;

use glam::Vec2;
use rayon::prelude::*;

use crate::bidir::{Bdpt, Strategies};
use crate::film::Film;
use crate::math::Sampler;
use crate::path::{LocalSampling, Vertex};
use crate::scene::Scene;
use crate::spectrum::Rgb;

use super::mixing::Recorder;
use acceptance::acceptance;
use contribution::{image_contribution_reusing, scalar_contribution, EdgeFactors};
use init::Bootstrap;
use mutation::{
    Bidirectional, InverseDistance, LightPerturbation, MultiChainPerturbation, Mutation,
    MutationKind, PerMutation, PropagationPerturbation, SensorPerturbation, Workspace,
};

/// Salt that keeps chain streams apart from pixel streams.
const CHAIN_STREAM_SALT: u64 = 0x0063_6861_696e_0000;
/// Seed draws a chain tries before giving up (a pre-pass path whose f is zero when re-evaluated
/// with singular vertices checked, e.g. a specular relation off by more than the tolerance).
pub const DEFAULT_SEED_DRAWS: u32 = 64;

/// MLT settings (the scene's `[render.mlt]` table and the CLI flags).
#[derive(Clone, Debug, PartialEq)]
pub struct MltSettings {
    /// Pre-pass samples n (sec. 5.1).
    pub bootstrap: u64,
    /// Independent chains.
    pub chains: u32,
    /// Selection weights of the mutations, in `MutationKind::ALL` order (normalized when used).
    pub weights: PerMutation<f64>,
    /// Sensor perturbation film offset [D_min, D_max] in pixels.
    pub sensor_offset: (f32, f32),
    /// Light and multi-chain perturbation angle [theta_min, theta_max] in radians.
    pub light_angle: (f32, f32),
    /// Propagation perturbation distance [D_min, D_max] as fractions of the scene's radius.
    pub propagation_distance: (f32, f32),
    /// BDPT samples per mutation that keep refining the estimate of b during the run (0: b is
    /// the pre-pass estimate b_n for the whole run, as in sec. 5.1).
    pub b_refine: f64,
    /// Pre-pass paths a chain draws for its seed before it gives up (`DEFAULT_SEED_DRAWS`).
    pub seed_draws: u32,
}

/// Default pre-pass size ([K] draws 65536; a quarter keeps previews quick).
pub const DEFAULT_BOOTSTRAP: u64 = 16384;
/// Default chain count: enough to keep both cores busy, few enough for long chains.
pub const DEFAULT_CHAINS: u32 = 16;
/// Veach's lens perturbation range: 0.1 pixel to a tenth of a typical image (sec. 11.4.2 uses
/// r1 = 0.1 pixels and r2 = 10% of the image size).
pub const DEFAULT_SENSOR_OFFSET: (f32, f32) = (0.1, 25.0);
/// Caustic perturbation angles (Veach 1997 sec. 11.4.3 names 0.0001 and 0.1 radians).
pub const DEFAULT_LIGHT_ANGLE: (f32, f32) = (1e-4, 0.1);
/// Propagation perturbation distances relative to the scene radius (Pauly et al. leave D_min
/// and D_max open; these mirror the sensor range's 1 : 250 ratio).
pub const DEFAULT_PROPAGATION_DISTANCE: (f32, f32) = (4e-4, 0.1);
/// One BDPT sample per 32 mutations refines b: about a tenth of the run's time (a BDPT sample
/// with all its strategies costs three to four mutations), and b's error no longer sets a floor
/// under the error of long runs (book: "MLT experiments").
pub const DEFAULT_B_REFINE: f64 = 1.0 / 32.0;

impl Default for MltSettings {
    fn default() -> Self {
        MltSettings {
            bootstrap: DEFAULT_BOOTSTRAP,
            chains: DEFAULT_CHAINS,
            // Pauly et al. 2000 sec. 6: "all images ... rendered with equal weights"
            weights: [1.0; MutationKind::COUNT],
            sensor_offset: DEFAULT_SENSOR_OFFSET,
            light_angle: DEFAULT_LIGHT_ANGLE,
            propagation_distance: DEFAULT_PROPAGATION_DISTANCE,
            b_refine: DEFAULT_B_REFINE,
            seed_draws: DEFAULT_SEED_DRAWS,
        }
    }
}

impl MltSettings {
    /// Checks every value; the message names the setting.
    pub fn validate(&self) -> Result<(), MltError> {
        if self.bootstrap == 0 {
            return Err(MltError::NoBootstrap);
        }
        if self.chains == 0 {
            return Err(MltError::NoChains);
        }
        for (w, k) in self.weights.iter().zip(MutationKind::ALL) {
            if !(w.is_finite() && *w >= 0.0) {
                return Err(MltError::BadWeight(k.name(), *w));
            }
        }
        if !(self.b_refine.is_finite() && self.b_refine >= 0.0) {
            return Err(MltError::BadBRefine(self.b_refine));
        }
        if self.seed_draws == 0 {
            return Err(MltError::NoSeedDraws);
        }
        if self.weights.iter().sum::<f64>() <= 0.0 {
            return Err(MltError::NoPositiveWeight);
        }
        InverseDistance::new(self.sensor_offset.0, self.sensor_offset.1)?;
        InverseDistance::new(self.light_angle.0, self.light_angle.1)?;
        InverseDistance::new(self.propagation_distance.0, self.propagation_distance.1)?;
        Ok(())
    }

    /// Parses `name=weight,...` (e.g. `bidirectional=1,sensor=100`); unnamed kinds get 0.
    pub fn parse_weights(s: &str) -> Result<PerMutation<f64>, MltError> {
        let mut w = [0.0; MutationKind::COUNT];
        for part in s.split(',').filter(|p| !p.trim().is_empty()) {
            let (name, value) = part
                .split_once('=')
                .ok_or_else(|| MltError::NotNameWeight(part.into()))?;
            let kind = MutationKind::ALL
                .iter()
                .find(|k| k.name() == name.trim())
                .ok_or_else(|| {
                    let names: Vec<&str> = MutationKind::ALL.iter().map(|k| k.name()).collect();
                    MltError::UnknownMutation(name.trim().into(), names.join(", "))
                })?;
            w[kind.index()] = value
                .trim()
                .parse::<f64>()
                .map_err(|_| MltError::NotANumber(value.into()))?;
        }
        Ok(w)
    }
}

/// The MLT options, declared once: the `[render.mlt]` keys (serde) and the `--mlt-*` flags
/// (clap) are the same fields, with the same docs; [`MltOptions::apply`] puts them over the
/// settings (the file's over the defaults, the flags over the file's) and
/// [`MltSettings::validate`] checks the result. The flags without a prefix of earlier releases
/// (`--chains`, `--bootstrap`, `--b-refine`, `--mutation-weights`) are hidden aliases.
#[derive(clap::Args, serde::Deserialize, serde::Serialize, Debug, Clone, Default, PartialEq)]
#[serde(deny_unknown_fields)]
#[command(next_help_heading = "MLT: Metropolis light transport (--integrator mlt; [render.mlt])")]
pub struct MltOptions {
    /// MLT: BDPT pre-pass samples n that estimate b (default 16384).
    #[arg(long = "mlt-bootstrap", alias = "bootstrap")]
    pub bootstrap: Option<u64>,
    /// MLT: independent chains (default 16).
    #[arg(long = "mlt-chains", alias = "chains")]
    pub chains: Option<u32>,
    /// MLT: BDPT samples per mutation that keep refining b during the run; 0 keeps the
    /// pre-pass estimate (default 1/32).
    #[arg(long = "mlt-b-refine", alias = "b-refine")]
    pub b_refine: Option<f64>,
    /// MLT: selection weight of the bidirectional mutation (default 1).
    #[arg(long = "mlt-bidirectional")]
    pub bidirectional: Option<f64>,
    /// MLT: selection weight of the sensor (lens) perturbation (default 1).
    #[arg(long = "mlt-sensor")]
    pub sensor: Option<f64>,
    /// MLT: selection weight of the light (caustic) perturbation (default 1).
    #[arg(long = "mlt-light")]
    pub light: Option<f64>,
    /// MLT: selection weight of the propagation perturbation (default 1).
    #[arg(long = "mlt-propagation")]
    pub propagation: Option<f64>,
    /// MLT: selection weight of the multi-chain perturbation (default 1).
    #[arg(long = "mlt-multichain")]
    pub multichain: Option<f64>,
    /// MLT: every mutation selection weight at once, e.g. `bidirectional=1,sensor=100,light=100`
    /// (unnamed types get 0; the per-type options above override it).
    #[arg(long = "mlt-mutation-weights", alias = "mutation-weights", value_parser = MltSettings::parse_weights)]
    #[serde(default, with = "weights_text")]
    pub mutation_weights: Option<PerMutation<f64>>,
    /// MLT: sensor perturbation film offset MIN,MAX in pixels (default 0.1,25).
    #[arg(long = "mlt-sensor-offset", value_name = "MIN,MAX", value_parser = parse_range)]
    #[serde(default, deserialize_with = "crate::scene::file::exact_opt")]
    pub sensor_offset: Option<[f32; 2]>,
    /// MLT: light and multi-chain perturbation angle MIN,MAX in radians (default 1e-4,0.1).
    #[arg(long = "mlt-light-angle", value_name = "MIN,MAX", value_parser = parse_range)]
    #[serde(default, deserialize_with = "crate::scene::file::exact_opt")]
    pub light_angle: Option<[f32; 2]>,
    /// MLT: propagation perturbation distance MIN,MAX as fractions of the scene radius
    /// (default 4e-4,0.1).
    #[arg(long = "mlt-propagation-distance", value_name = "MIN,MAX", value_parser = parse_range)]
    #[serde(default, deserialize_with = "crate::scene::file::exact_opt")]
    pub propagation_distance: Option<[f32; 2]>,
    /// MLT: pre-pass paths a chain draws for its seed before it gives up (default 64; more for
    /// scenes whose pre-pass paths often fail the re-evaluation, e.g. near-specular relations).
    #[arg(long = "mlt-seed-draws")]
    pub seed_draws: Option<u32>,
}

/// `mutation_weights` in a file or a render's record: the flag's `name=weight,...` text.
mod weights_text {
    use super::{MltSettings, MutationKind, PerMutation};
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(w: &Option<PerMutation<f64>>, s: S) -> Result<S::Ok, S::Error> {
        match w {
            None => s.serialize_none(),
            Some(w) => {
                let parts: Vec<String> = MutationKind::ALL
                    .iter()
                    .map(|k| format!("{}={}", k.name(), w[k.index()]))
                    .collect();
                s.serialize_str(&parts.join(","))
            }
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<PerMutation<f64>>, D::Error> {
        let text = Option::<String>::deserialize(d)?;
        text.map(|t| MltSettings::parse_weights(&t).map_err(D::Error::custom))
            .transpose()
    }
}

/// Parses `MIN,MAX` (a perturbation range).
pub fn parse_range(s: &str) -> Result<[f32; 2], MltError> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| MltError::NotMinMax(s.into()))?;
    let num = |v: &str| {
        v.trim()
            .parse::<f32>()
            .map_err(|_| MltError::RangeNotANumber(v.into(), s.into()))
    };
    Ok([num(a)?, num(b)?])
}

impl MltOptions {
    /// `base` with every given option replacing its setting (unchecked: see
    /// [`MltSettings::validate`]).
    pub fn apply(&self, base: &mut MltSettings) {
        if let Some(v) = self.bootstrap {
            base.bootstrap = v;
        }
        if let Some(v) = self.chains {
            base.chains = v;
        }
        if let Some(v) = self.b_refine {
            base.b_refine = v;
        }
        if let Some(w) = self.mutation_weights {
            base.weights = w;
        }
        for (i, w) in [
            self.bidirectional,
            self.sensor,
            self.light,
            self.propagation,
            self.multichain,
        ]
        .into_iter()
        .enumerate()
        {
            if let Some(w) = w {
                base.weights[i] = w;
            }
        }
        if let Some([a, b]) = self.sensor_offset {
            base.sensor_offset = (a, b);
        }
        if let Some([a, b]) = self.light_angle {
            base.light_angle = (a, b);
        }
        if let Some([a, b]) = self.propagation_distance {
            base.propagation_distance = (a, b);
        }
        if let Some(n) = self.seed_draws {
            base.seed_draws = n;
        }
    }
}

/// The set of mutations with their parameters.
pub struct Mutations {
    pub bidirectional: Bidirectional,
    pub sensor: SensorPerturbation,
    pub light: LightPerturbation,
    pub propagation: PropagationPerturbation,
    pub multichain: MultiChainPerturbation,
}

impl Mutations {
    pub fn get(&self, kind: MutationKind) -> &dyn Mutation {
        match kind {
            MutationKind::Bidirectional => &self.bidirectional,
            MutationKind::Sensor => &self.sensor,
            MutationKind::Light => &self.light,
            MutationKind::Propagation => &self.propagation,
            MutationKind::MultiChain => &self.multichain,
        }
    }
}

/// Counts of one mutation type.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MutationStats {
    /// Times the type was chosen.
    pub attempted: u64,
    /// Times it produced a path (it applied and did not leave path space).
    pub proposed: u64,
    /// Times the chain moved.
    pub accepted: u64,
}

impl MutationStats {
    /// accepted / attempted (what the chain experiences).
    pub fn acceptance_rate(&self) -> f64 {
        self.accepted as f64 / self.attempted.max(1) as f64
    }

    fn add(&mut self, o: &MutationStats) {
        self.attempted += o.attempted;
        self.proposed += o.proposed;
        self.accepted += o.accepted;
    }
}

/// What one chain produced in a pass: its deposits and counts.
type ChainPass = (Vec<(Vec2, Rgb)>, PerMutation<MutationStats>);

/// One Markov chain: its stream and its current path with f and the pixel.
pub struct Chain {
    pub sampler: Sampler,
    pub x: Vec<Vertex>,
    pub f: Rgb,
    pub raster: Vec2,
    /// The edge factors of `x`, reused for the edges a proposal shares with it.
    pub edges: EdgeFactors,
    /// Scratch for a proposal's edge factors (swapped with `edges` on acceptance).
    scratch: EdgeFactors,
    /// The proposal y (swapped with `x` on acceptance) and the mutations' buffers: a chain
    /// allocates while its paths grow, not per mutation.
    proposal: Vec<Vertex>,
    work: Workspace,
}

impl Chain {
    /// A chain at path `x` with stream `sampler`; `None` when f(x) = 0.
    pub fn new(scene: &Scene, sampler: Sampler, x: Vec<Vertex>) -> Option<Chain> {
        let mut edges = EdgeFactors::new();
        let (f, raster) = image_contribution_reusing(scene, &x, None, &mut edges)?;
        Some(Chain {
            sampler,
            x,
            f,
            raster,
            edges,
            scratch: EdgeFactors::new(),
            proposal: Vec::new(),
            work: Workspace::default(),
        })
    }
}

/// The MLT engine: settings, the pre-pass result, the chains and their statistics.
pub struct Mlt<'t> {
    pub settings: MltSettings,
    pub mutations: Mutations,
    /// The pre-pass's BDPT, with the technique every mutation samples and evaluates by.
    pub bdpt: Bdpt<'t>,
    pub seed: u64,
    /// The current estimate of b (luminance): b_n of the pre-pass (sec. 5.1), refined by
    /// `b_refine` BDPT samples per mutation as the run goes on.
    pub b: f64,
    /// Sum of the film weights of every BDPT sample behind `b`, and their count.
    b_sum: f64,
    b_samples: u64,
    pub chains: Vec<Chain>,
    pub stats: PerMutation<MutationStats>,
    pub initialized: bool,
    /// Mutations run so far (N).
    pub mutations_done: u64,
    cdf: PerMutation<f64>,
    /// The chains' deposits per image block, for the mixing diagnostics.
    pub mixing: Recorder,
}

/// Why MLT refuses its settings or its scene (the messages name the setting or the missing
/// piece: they are what the command line and the scene-file errors print).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MltError {
    /// n = 0: the pre-pass needs a sample to estimate b (Pauly et al. 2000 sec. 5.1).
    #[error("mlt bootstrap must be at least 1 sample")]
    NoBootstrap,
    /// No chain to run.
    #[error("mlt chains must be at least 1")]
    NoChains,
    /// A mutation's weight is negative or not finite (the mutation's name, the weight).
    #[error("mutation weight {0} = {1} must be finite and >= 0")]
    BadWeight(&'static str, f64),
    /// The BDPT samples per mutation that refine b are negative or not finite.
    #[error("mlt b_refine = {0} must be finite and >= 0 (BDPT samples per mutation)")]
    BadBRefine(f64),
    /// A chain needs at least one pre-pass draw for its seed.
    #[error("mlt seed_draws must be at least 1")]
    NoSeedDraws,
    /// All weights 0: no mutation to choose.
    #[error("at least one mutation weight must be positive")]
    NoPositiveWeight,
    /// A perturbation range outside 0 < min < max (min, max).
    #[error("perturbation range [{0}, {1}] must satisfy 0 < min < max")]
    BadRange(f32, f32),
    /// A `--mlt-mutation-weights` part without `=`.
    #[error("`{0}` is not NAME=WEIGHT")]
    NotNameWeight(String),
    /// A mutation name that is none (the name, the available ones).
    #[error("unknown mutation `{0}` (available: {1})")]
    UnknownMutation(String, String),
    /// A weight that does not parse.
    #[error("`{0}` is not a number")]
    NotANumber(String),
    /// A range without a comma.
    #[error("`{0}` is not MIN,MAX")]
    NotMinMax(String),
    /// A range bound that does not parse (the bound, the range).
    #[error("`{0}` in `{1}` is not a number")]
    RangeNotANumber(String, String),
    /// MLT renders images (Pauly et al. 2000 sec. 3: the measurement is a pixel's).
    #[error("mlt renders images: the scene needs a camera")]
    NoCamera,
    /// A material with a Dirac and a regular lobe: MLT classifies a vertex's lobe by its
    /// neighbours (`contribution::lobe_between`) and its f and densities by whole materials.
    #[error(
        "mlt does not support plastic (the material of {0}): a Dirac coat over a regular \
         lobe, where its mutations and densities classify a vertex by its whole material"
    )]
    MixedLobes(String),
}

impl From<MltError> for String {
    fn from(e: MltError) -> Self {
        e.to_string()
    }
}

impl From<MltError> for super::IntegratorError {
    fn from(e: MltError) -> Self {
        super::IntegratorError::Refused(e.to_string())
    }
}

/// Checks that MLT can render `scene`: a camera, no plastic. Lights at infinity are path
/// vertices in the directional measure (`contribution::anchor_infinite`); a thin lens's point
/// is the camera vertex x_k in the area measure of the aperture (the bidirectional mutation
/// redraws it, the perturbations keep it).
pub fn check_scene(scene: &Scene) -> Result<(), MltError> {
    if scene.camera.is_none() {
        return Err(MltError::NoCamera);
    }
    let mixed = scene.shapes.iter().find(|s| {
        s.bsdf
            .as_ref()
            .is_some_and(|b| b.has_dirac_lobe() && b.has_regular_lobe())
    });
    if let Some(s) = mixed {
        return Err(MltError::MixedLobes(s.label.clone()));
    }
    Ok(())
}

impl<'t> Mlt<'t> {
    /// MLT on `scene` with local-sampling technique `tech` (the pre-pass's walks, the
    /// bidirectional mutation's, and every transition density).
    pub fn new(
        scene: &Scene,
        tech: &'t dyn LocalSampling,
        settings: MltSettings,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, MltError> {
        settings.validate()?;
        check_scene(scene)?;
        // without a depth limit the target is f on the whole, unbounded path space: the
        // bidirectional mutation's length law has an infinite geometric tail
        let bdpt = Bdpt::new(tech, max_depth, Strategies::All);
        let r = scene.radius.max(f32::MIN_POSITIVE);
        let (d0, d1) = settings.propagation_distance;
        let mutations = Mutations {
            bidirectional: Bidirectional {
                max_vertices: max_depth.map_or(usize::MAX, |d| d as usize + 2),
            },
            sensor: SensorPerturbation {
                offset: InverseDistance::new(settings.sensor_offset.0, settings.sensor_offset.1)?,
            },
            light: LightPerturbation {
                angle: InverseDistance::new(settings.light_angle.0, settings.light_angle.1)?,
            },
            propagation: PropagationPerturbation {
                distance: InverseDistance::new(d0 * r, d1 * r)?,
            },
            multichain: MultiChainPerturbation {
                offset: InverseDistance::new(settings.sensor_offset.0, settings.sensor_offset.1)?,
                angle: InverseDistance::new(settings.light_angle.0, settings.light_angle.1)?,
            },
        };
        let total: f64 = settings.weights.iter().sum();
        let mut cdf = [0.0; MutationKind::COUNT];
        let mut acc = 0.0;
        for (i, w) in settings.weights.iter().enumerate() {
            acc += w / total;
            cdf[i] = acc;
        }
        Ok(Mlt {
            settings,
            mutations,
            bdpt,
            seed,
            b: 0.0,
            b_sum: 0.0,
            b_samples: 0,
            chains: Vec::new(),
            stats: [MutationStats::default(); MutationKind::COUNT],
            initialized: false,
            mutations_done: 0,
            cdf,
            mixing: Recorder::new(scene),
        })
    }

    /// The pre-pass and the chains' seed paths (sec. 5.1).
    // ANCHOR: initialize
    pub fn initialize(&mut self, scene: &Scene) {
        self.initialized = true;
        let boot = Bootstrap::run(scene, &self.bdpt, self.settings.bootstrap, self.seed);
        self.b = boot.b;
        self.b_sum = boot.b * boot.samples as f64;
        self.b_samples = boot.samples;
        let chains: Vec<Option<Chain>> = (0..self.settings.chains as u64)
            .into_par_iter()
            .map(|c| {
                let mut sampler = Sampler::new(self.seed, CHAIN_STREAM_SALT ^ c, 0);
                for _ in 0..self.settings.seed_draws {
                    let cand = boot.select(sampler.next_f64())?;
                    let Some(x) = Bootstrap::path_of(scene, &self.bdpt, self.seed, cand) else {
                        continue;
                    };
                    let mut edges = EdgeFactors::new();
                    if let Some((f, raster)) =
                        image_contribution_reusing(scene, &x, None, &mut edges)
                    {
                        return Some(Chain {
                            sampler,
                            x,
                            f,
                            raster,
                            edges,
                            scratch: EdgeFactors::new(),
                            proposal: Vec::new(),
                            work: Workspace::default(),
                        });
                    }
                }
                None
            })
            .collect();
        self.chains = chains.into_iter().flatten().collect();
    }
    // ANCHOR_END: initialize

    fn choose(&self, u: f64) -> MutationKind {
        let i = self.cdf.iter().position(|&c| u < c).unwrap_or_else(|| {
            // u beyond the last cumulative value by rounding: the last type with weight
            self.settings
                .weights
                .iter()
                .rposition(|&w| w > 0.0)
                .unwrap_or(0)
        });
        MutationKind::ALL[i]
    }

    /// One Metropolis step of a chain with expected-value splatting: the deposits go to
    /// `splats` (raster, value; the film divides them by N), the counts to `stats`.
    // ANCHOR: step
    pub fn step(
        &self,
        scene: &Scene,
        chain: &mut Chain,
        splats: &mut Vec<(Vec2, Rgb)>,
        stats: &mut PerMutation<MutationStats>,
    ) {
        let kind = self.choose(chain.sampler.next_f64());
        let st = &mut stats[kind.index()];
        st.attempted += 1;
        let mutation = self.mutations.get(kind);
        let fx = scalar_contribution(chain.f) as f64;
        let mut proposal = None;
        let mut a = 0.0;
        let tech = self.bdpt.tech;
        let (x, y, work) = (&chain.x, &mut chain.proposal, &mut chain.work);
        if mutation
            .sample(scene, tech, x, &mut chain.sampler, work, y)
            .is_some()
        {
            st.proposed += 1;
            let old = Some((x.as_slice(), chain.edges.as_slice()));
            if let Some((fy, ry)) = image_contribution_reusing(scene, y, old, &mut chain.scratch) {
                let t_xy = mutation.transition_density(scene, tech, x, y, work);
                let t_yx = mutation.transition_density(scene, tech, y, x, work);
                a = acceptance(fx, scalar_contribution(fy) as f64, t_xy, t_yx);
                proposal = Some((fy, ry));
            }
        }
        // expected-value splatting: each deposit is b/N in luminance; the deposits here are in
        // units of b (the film's splat scale is b) and the film divides by N
        if a < 1.0 {
            splats.push((chain.raster, chain.f * ((1.0 - a) / fx) as f32));
        }
        if let Some((fy, ry)) = proposal {
            if a > 0.0 {
                let fy_lum = scalar_contribution(fy) as f64;
                splats.push((ry, fy * (a / fy_lum) as f32));
            }
            if chain.sampler.next_f64() < a {
                st.accepted += 1;
                // the old path becomes the next proposal's buffer
                std::mem::swap(&mut chain.x, &mut chain.proposal);
                chain.f = fy;
                chain.raster = ry;
                std::mem::swap(&mut chain.edges, &mut chain.scratch);
            }
        }
    }
    // ANCHOR_END: step

    /// Runs `mutations` Metropolis steps in total over the chains and splats them into `film`
    /// (whose splat count grows by `mutations`).
    pub fn run(&mut self, scene: &Scene, film: &mut Film, mutations: u64) {
        if !self.initialized {
            self.initialize(scene);
        }
        film.splat_count += mutations;
        self.mutations_done += mutations;
        let n = self.chains.len() as u64;
        if n == 0 || self.b <= 0.0 {
            return; // no path reaches the camera: the image is black
        }
        let mut chains = std::mem::take(&mut self.chains);
        let mut traces = self.mixing.take(chains.len());
        let this = &*self;
        let grid = &self.mixing.grid;
        let results: Vec<ChainPass> = chains
            .par_iter_mut()
            .zip(traces.par_iter_mut())
            .enumerate()
            .map(|(c, (chain, trace))| {
                let quota = mutations / n + u64::from((c as u64) < mutations % n);
                let mut splats = Vec::with_capacity(2 * quota as usize);
                let mut stats = [MutationStats::default(); MutationKind::COUNT];
                for _ in 0..quota {
                    let from = splats.len();
                    this.step(scene, chain, &mut splats, &mut stats);
                    trace.step(grid, &splats[from..]);
                }
                (splats, stats)
            })
            .collect();
        self.chains = chains;
        self.mixing.put(traces);
        self.refine_b(scene);
        film.splat_scale = self.b;
        for (splats, stats) in results {
            for (r, l) in splats {
                if l.is_finite() {
                    film.add_splat(r, l);
                }
            }
            for (a, b) in self.stats.iter_mut().zip(&stats) {
                a.add(b);
            }
        }
    }

    /// Adds `b_refine * mutations` BDPT samples to the estimate of b (sample indices continue
    /// after the pre-pass, so a run's b depends on its mutation count, never on threads).
    ///
    /// A DEVIATION from sec. 5.1 (off with `b_refine = 0`): the image sum stays an unbiased
    /// estimate of b, now with an error that shrinks with the run; per pixel, the seeds' start-up
    /// distribution enters with weight m/(n+m) and fades as the chains mix, so the estimator is
    /// consistent rather than unbiased in each pixel.
    // ANCHOR: refine_b
    fn refine_b(&mut self, scene: &Scene) {
        let target = self.settings.bootstrap
            + (self.settings.b_refine * self.mutations_done as f64).round() as u64;
        if target > self.b_samples {
            self.b_sum +=
                Bootstrap::weight_sum(scene, &self.bdpt, self.seed, self.b_samples, target);
            self.b_samples = target;
            self.b = self.b_sum / self.b_samples as f64;
        }
    }
    // ANCHOR_END: refine_b

    /// Mutation types with their statistics.
    pub fn report(&self) -> Vec<(MutationKind, MutationStats)> {
        MutationKind::ALL
            .iter()
            .map(|&k| (k, self.stats[k.index()]))
            .collect()
    }
}

/// Vertices of a chain's current and proposed paths at most (two subpaths' caps).
const PATH_VERTICES: u64 = 2 * crate::bidir::MAX_SUBPATH_VERTICES as u64;

/// MLT's facts: film-wide passes that splat, its chains and bootstrap, light start points,
/// its scene checked before the work, shards as independent runs.
pub struct MltFacts;

impl super::Facts for MltFacts {
    fn prepare<'t>(
        &self,
        setup: &super::Setup<'_, 't>,
    ) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
        prepare(setup)
    }

    fn samples_light_starts(&self) -> bool {
        true
    }

    /// A path's x0 may be a volume vertex of a glowing medium (eq. 5): the pre-pass finds such
    /// paths, the bidirectional mutation regenerates x0, the propagation and multi-chain
    /// perturbations move it, and f carries L_e,V0(x0) (`contribution::start_emission`).
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        None
    }

    fn check(&self, case: &super::Case) -> Result<(), super::IntegratorError> {
        check_scene(case.scene).map_err(super::IntegratorError::from)
    }

    /// A mutation splats its current and its proposed path; no tile results.
    fn pass_footprint(&self, _: &super::Case) -> super::PassFootprint {
        super::PassFootprint {
            tiles: false,
            bytes_per_sample: 2 * super::SPLAT_BYTES,
        }
    }

    fn memory_parts(&self, case: &super::Case) -> Vec<(&'static str, u64)> {
        let chains = case.settings.mlt.chains as u64;
        let paths = chains * 2 * PATH_VERTICES * std::mem::size_of::<Vertex>() as u64;
        let bootstrap = case.settings.mlt.bootstrap * std::mem::size_of::<init::Candidate>() as u64;
        vec![("mlt chains", paths + bootstrap)]
    }

    fn shard_split(&self) -> super::ShardSplit {
        super::ShardSplit::IndependentChains
    }

    fn chains(&self) -> Option<super::ChainCount> {
        Some(super::ChainCount {
            flag: "--mlt-chains",
            get: |s| s.mlt.chains,
            set: |s, c| s.mlt.chains = c,
        })
    }

    fn statistics_key(&self) -> Option<&'static str> {
        Some("mlt")
    }

    /// Its chains splat over the whole film.
    fn pixel_variance(&self) -> bool {
        false
    }
}

/// MLT from the scene file's `[render.mlt]`: refused without a camera or with plastic.
pub fn prepare<'t>(
    setup: &super::Setup<'_, 't>,
) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
    Ok(Box::new(Mlt::new(
        setup.scene,
        setup.technique,
        setup.settings.mlt.clone(),
        setup.seed,
        setup.max_depth,
    )?))
}

impl super::Integrator for Mlt<'_> {
    fn label(&self) -> String {
        "mlt".into()
    }

    /// Film-wide: `spp` mutations per pixel over all chains.
    fn film_pass(&mut self, scene: &Scene, film: &mut Film, spp: u32) -> Option<u64> {
        let n = film.width as u64 * film.height as u64 * spp as u64;
        self.run(scene, film, n);
        film.spp += spp as u64;
        Some(n)
    }

    fn pending_stage(&self) -> Option<String> {
        (!self.initialized).then(|| {
            format!(
                "mlt bootstrap ({} BDPT paths, seed paths of {} chains)",
                self.settings.bootstrap, self.settings.chains
            )
        })
    }

    fn run_stage(&mut self, scene: &Scene) {
        if !self.initialized {
            self.initialize(scene);
        }
    }

    /// b of the pre-pass, each mutation type's counts and the chains' mixing.
    fn statistics(&self) -> super::Statistics {
        let report = self.report();
        let mut muts = serde_json::Map::new();
        let mut lines = vec![format!("  mlt: b = {:.5}", self.b)];
        for (k, st) in &report {
            muts.insert(
                k.name().to_string(),
                serde_json::json!({"attempted": st.attempted, "proposed": st.proposed,
                    "accepted": st.accepted, "acceptance_rate": st.acceptance_rate()}),
            );
            lines.push(format!(
                "  mutation {:<13} attempted {:>10} proposed {:>10} accepted {:>10} acceptance {:.4}",
                k.name(),
                st.attempted,
                st.proposed,
                st.accepted,
                st.acceptance_rate()
            ));
        }
        let mut stats = super::Statistics {
            json: Some(serde_json::json!({"b": self.b, "mutations": muts})),
            lines,
            ..Default::default()
        };
        self.mixing.statistics("mlt", &mut stats);
        stats
    }

    /// The chains (current paths, b, mutation statistics) are not saved in a checkpoint.
    fn resumes_exactly(&self) -> bool {
        false
    }
}
