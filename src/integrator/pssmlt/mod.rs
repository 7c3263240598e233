//! Primary-sample-space Metropolis light transport (Kelemen, Szirmay-Kalos, Antal, Csonka
//! 2002): Markov chains over the uniform numbers of a BDPT sample instead of over paths. A
//! state u is the vector of numbers a BDPT sample reads (`math::primary_sample`); the sample
//! is a deterministic function of u, so f*(u), the summed luminance of the sample's MIS-weighted
//! strategies (`sample::BdptTarget`), is a target on the unit hypercube, and Kelemen's large
//! and small steps (`kernel`) are symmetric proposals accepted with min(1, f*(y) / f*(x)).
//!
//! Normalization and start as in the path-space MLT (`integrator::mlt`, sec. 5.1): a bootstrap
//! of n independent states estimates b = E_u[f*(u)] and seeds each chain with a state drawn
//! in proportion to f* (Veach's start-up bias elimination); the film's splats are the
//! expected-value deposits times b / N. Every large step's proposal is one more independent
//! uniform sample of f*, so b is refined by them as the run goes (Kelemen et al. sec. 4).
//!
//! Everything a BDPT sample can render, this renders: media, every light (environment and
//! directional lights too: their vertices are BDPT's), emitting media (light subpaths from a
//! volume vertex x0), every BSDF.
//!
//! Determinism: bootstrap state i is stream (seed, i), chain c draws its seed and its steps from
//! streams of (seed, c); chains run in parallel and are merged in chain order, so an image
//! depends on the seed and the chain count, never on the thread count.
//! Book: "Primary-sample-space and multiplexed MLT".

pub mod kernel;
pub mod sample;

use glam::Vec2;
use rand_pcg::Pcg32;
use rayon::prelude::*;

use crate::bidir::{Bdpt, Scratch, Strategies};
use crate::film::Film;
use crate::math::sampler::mix64;
use crate::math::{PrimarySamples, Sampler};
use crate::path::LocalSampling;
use crate::scene::Scene;
use crate::spectrum::Rgb;

use super::mixing::Recorder;
use kernel::{KelemenChain, Target};
use sample::BdptTarget;

/// Default bootstrap size (the path-space MLT's).
pub const DEFAULT_BOOTSTRAP: u64 = 16384;
/// Default chain count (the path-space MLT's).
pub const DEFAULT_CHAINS: u32 = 16;
/// pbrt-v3's default large-step probability for its MLT (Kelemen et al. leave it open).
pub const DEFAULT_LARGE_STEP: f64 = 0.3;
/// pbrt-v3's default small-step deviation.
pub const DEFAULT_SIGMA: f64 = 0.01;

const BOOTSTRAP_SALT: u64 = 0x7073_626f_6f74_0000;
const CHAIN_SALT: u64 = 0x7073_6368_6169_6e00;
/// States evaluated per parallel work item of the bootstrap.
const BOOTSTRAP_CHUNK: u64 = 1024;

/// PSSMLT settings (the scene's `[render.pssmlt]` table and the `--pssmlt-*` flags).
#[derive(Clone, Debug, PartialEq)]
pub struct PssmltSettings {
    /// Bootstrap states n that estimate b and seed the chains.
    pub bootstrap: u64,
    /// Independent chains.
    pub chains: u32,
    /// Probability of a large step.
    pub large_step: f64,
    /// Standard deviation of the small step in primary sample space.
    pub sigma: f64,
}

impl Default for PssmltSettings {
    fn default() -> Self {
        PssmltSettings {
            bootstrap: DEFAULT_BOOTSTRAP,
            chains: DEFAULT_CHAINS,
            large_step: DEFAULT_LARGE_STEP,
            sigma: DEFAULT_SIGMA,
        }
    }
}

/// Why PSSMLT refuses its settings or a scene.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PssmltError {
    #[error("pssmlt bootstrap must be at least 1 sample")]
    NoBootstrap,
    #[error("pssmlt chains must be at least 1")]
    NoChains,
    #[error("pssmlt large_step = {0} must be a probability in [0, 1]")]
    BadLargeStep(f64),
    #[error("pssmlt sigma = {0} must be in (0, 1)")]
    BadSigma(f64),
    #[error("{0} renders images: the scene needs a camera")]
    NoCamera(&'static str),
}

impl From<PssmltError> for super::IntegratorError {
    fn from(e: PssmltError) -> Self {
        super::IntegratorError::Refused(e.to_string())
    }
}

impl From<PssmltError> for String {
    fn from(e: PssmltError) -> Self {
        e.to_string()
    }
}

impl PssmltSettings {
    /// Checks every value; the message names the setting.
    pub fn validate(&self) -> Result<(), PssmltError> {
        if self.bootstrap == 0 {
            return Err(PssmltError::NoBootstrap);
        }
        if self.chains == 0 {
            return Err(PssmltError::NoChains);
        }
        if !(0.0..=1.0).contains(&self.large_step) {
            return Err(PssmltError::BadLargeStep(self.large_step));
        }
        if !(self.sigma > 0.0 && self.sigma < 1.0) {
            return Err(PssmltError::BadSigma(self.sigma));
        }
        Ok(())
    }
}

/// The PSSMLT options, declared once: the `[render.pssmlt]` keys and the `--pssmlt-*` flags.
#[derive(clap::Args, serde::Deserialize, serde::Serialize, Debug, Clone, Default, PartialEq)]
#[serde(deny_unknown_fields)]
#[command(
    next_help_heading = "PSSMLT: primary-sample-space MLT (--integrator pssmlt; [render.pssmlt])"
)]
pub struct PssmltOptions {
    /// PSSMLT: bootstrap samples n that estimate b and seed the chains (default 16384).
    #[arg(id = "pssmlt_bootstrap", long = "pssmlt-bootstrap")]
    pub bootstrap: Option<u64>,
    /// PSSMLT: independent chains (default 16).
    #[arg(id = "pssmlt_chains", long = "pssmlt-chains")]
    pub chains: Option<u32>,
    /// PSSMLT: probability of a large step, all numbers afresh (default 0.3).
    #[arg(id = "pssmlt_large_step", long = "pssmlt-large-step")]
    pub large_step: Option<f64>,
    /// PSSMLT: standard deviation of the small step in primary sample space (default 0.01).
    #[arg(id = "pssmlt_sigma", long = "pssmlt-sigma")]
    pub sigma: Option<f64>,
}

impl PssmltOptions {
    /// `base` with every given option replacing its setting (unchecked: see
    /// [`PssmltSettings::validate`]).
    pub fn apply(&self, base: &mut PssmltSettings) {
        base.bootstrap = self.bootstrap.unwrap_or(base.bootstrap);
        base.chains = self.chains.unwrap_or(base.chains);
        base.large_step = self.large_step.unwrap_or(base.large_step);
        base.sigma = self.sigma.unwrap_or(base.sigma);
    }
}

/// Checks that integrator `name` (PSSMLT or MMLT) can render `scene`: it needs a camera (its
/// chains render the image).
pub fn check_scene(scene: &Scene, name: &'static str) -> Result<(), PssmltError> {
    if scene.camera.is_none() {
        return Err(PssmltError::NoCamera(name));
    }
    Ok(())
}

/// The counts of the steps of one kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StepCounts {
    pub attempted: u64,
    pub accepted: u64,
}

impl StepCounts {
    pub fn acceptance_rate(&self) -> f64 {
        self.accepted as f64 / self.attempted.max(1) as f64
    }
}

/// A chain with the storage it keeps from pass to pass (so that a pass allocates nothing per
/// step once the storage has grown): its walks and its deposits of the pass.
struct Slot {
    chain: KelemenChain,
    walks: Scratch,
    splats: Vec<(Vec2, Rgb)>,
}

/// What one chain did in a pass: its large and small steps, and the sum of its large steps'
/// f*(y) (independent samples of b).
struct ChainPass {
    large: StepCounts,
    small: StepCounts,
    large_sum: f64,
}

/// The target a chain follows, made for a scene and a BDPT engine: the BDPT sample
/// ([`BdptTarget`], PSSMLT) or one strategy of it (MMLT, `integrator::mmlt`).
/// The walks' storage is handed in and back ([`Target::storage`]) to be reused.
pub type MakeTarget = for<'a> fn(&'a Scene, &'a Bdpt<'a>, Scratch) -> Box<dyn Target + 'a>;

/// PSSMLT's target: the whole BDPT sample.
pub fn bdpt_target<'a>(
    scene: &'a Scene,
    bdpt: &'a Bdpt<'a>,
    walks: Scratch,
) -> Box<dyn Target + 'a> {
    Box::new(BdptTarget {
        walks,
        ..BdptTarget::new(scene, bdpt)
    })
}

/// The PSSMLT integrator (and, with another target, MMLT's).
pub struct Pssmlt<'t> {
    /// The integrator's name (`pssmlt`, `mmlt`).
    pub name: &'static str,
    /// The target of the chains.
    pub make_target: MakeTarget,
    pub settings: PssmltSettings,
    pub bdpt: Bdpt<'t>,
    pub seed: u64,
    /// The estimate of b: the bootstrap's and the large steps' mean f*.
    pub b: f64,
    b_sum: f64,
    b_samples: u64,
    chains: Vec<Slot>,
    initialized: bool,
    pub large: StepCounts,
    pub small: StepCounts,
    /// The chains' deposits per image block, for the mixing diagnostics.
    pub mixing: Recorder,
}

/// The stream of bootstrap state `i` or chain `c` (one per index, derived from the seed).
pub fn stream(seed: u64, salt: u64, index: u64) -> Pcg32 {
    Pcg32::new(mix64(seed ^ salt ^ mix64(index)), mix64(index ^ salt))
}

impl<'t> Pssmlt<'t> {
    pub fn new(
        scene: &Scene,
        tech: &'t dyn LocalSampling,
        settings: PssmltSettings,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, PssmltError> {
        Self::with_target(
            scene,
            tech,
            settings,
            seed,
            max_depth,
            ("pssmlt", bdpt_target),
        )
    }

    /// The chains of integrator `name` following the targets `make_target` makes.
    pub fn with_target(
        scene: &Scene,
        tech: &'t dyn LocalSampling,
        settings: PssmltSettings,
        seed: u64,
        max_depth: Option<u32>,
        (name, make_target): (&'static str, MakeTarget),
    ) -> Result<Self, PssmltError> {
        settings.validate()?;
        check_scene(scene, name)?;
        Ok(Pssmlt {
            name,
            make_target,
            settings,
            bdpt: Bdpt::new(tech, max_depth, Strategies::All),
            seed,
            b: 0.0,
            b_sum: 0.0,
            b_samples: 0,
            chains: Vec::new(),
            initialized: false,
            large: StepCounts::default(),
            small: StepCounts::default(),
            mixing: Recorder::new(scene),
        })
    }

    /// f* of every bootstrap state, in order (state i is the large step of stream i).
    // ANCHOR: bootstrap
    pub fn bootstrap(&self, scene: &Scene) -> Vec<f64> {
        let (n, seed, sigma) = (self.settings.bootstrap, self.seed, self.settings.sigma);
        (0..n.div_ceil(BOOTSTRAP_CHUNK))
            .into_par_iter()
            .flat_map_iter(|c| {
                let mut target = (self.make_target)(scene, &self.bdpt, Scratch::default());
                let mut out = Vec::new();
                let first = stream(seed, BOOTSTRAP_SALT, c * BOOTSTRAP_CHUNK);
                let mut sampler = Sampler::primary(PrimarySamples::new(first, sigma));
                (c * BOOTSTRAP_CHUNK..((c + 1) * BOOTSTRAP_CHUNK).min(n))
                    .map(|i| {
                        let chain = sampler.chain().expect("a primary sampler");
                        chain.restart(stream(seed, BOOTSTRAP_SALT, i));
                        chain.start_iteration(true);
                        target.evaluate(&mut sampler, &mut out)
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    }
    // ANCHOR_END: bootstrap

    /// The bootstrap, b, and the chains' seeds: chain c draws a bootstrap state in proportion
    /// to f* and re-creates it from its stream.
    pub fn initialize(&mut self, scene: &Scene) {
        self.initialized = true;
        let f = self.bootstrap(scene);
        self.b_sum = f.iter().sum();
        self.b_samples = f.len() as u64;
        self.b = self.b_sum / self.b_samples as f64;
        let cdf: Vec<f64> = f
            .iter()
            .scan(0.0, |acc, &x| {
                *acc += x;
                Some(*acc)
            })
            .collect();
        let total = self.b_sum;
        if !(total > 0.0 && total.is_finite()) {
            return; // no sample reaches the camera: the image is black
        }
        let seed = self.seed;
        let chains: Vec<Option<Slot>> = (0..self.settings.chains as u64)
            .into_par_iter()
            .map(|c| {
                let u = Sampler::new(seed, CHAIN_SALT ^ c, 0).next_f64() * total;
                let i = cdf.partition_point(|&x| x <= u).min(cdf.len() - 1);
                let mut target = (self.make_target)(scene, &self.bdpt, Scratch::default());
                let chain = self.replay(i as u64, c, target.as_mut())?;
                Some(Slot {
                    chain,
                    walks: target.storage(),
                    splats: Vec::new(),
                })
            })
            .collect();
        self.chains = chains.into_iter().flatten().collect();
    }

    /// Bootstrap state `i` re-created from its stream as chain `c`'s start (None where its f*
    /// is 0). The replay must reach the bootstrap's f* bit for bit: a chain that started from
    /// another value would not be seeded in proportion to f*, and in a medium, where a path
    /// reads a varying count of numbers, that is the easy thing to get wrong.
    pub fn replay(&self, i: u64, c: u64, target: &mut dyn Target) -> Option<KelemenChain> {
        let state = stream(self.seed, BOOTSTRAP_SALT, i);
        let own = stream(self.seed, CHAIN_SALT, c);
        kernel::start_chain(state, own, self.settings.sigma, target)
    }

    /// Runs `mutations` steps in total over the chains and splats them into `film` (whose
    /// splat count grows by `mutations`); b is then refined by the large steps.
    pub fn run(&mut self, scene: &Scene, film: &mut Film, mutations: u64) {
        if !self.initialized {
            self.initialize(scene);
        }
        film.splat_count += mutations;
        let n = self.chains.len() as u64;
        if n == 0 {
            return;
        }
        let mut chains = std::mem::take(&mut self.chains);
        let mut traces = self.mixing.take(chains.len());
        let (bdpt, large_step, make) = (&self.bdpt, self.settings.large_step, self.make_target);
        let grid = &self.mixing.grid;
        let results: Vec<ChainPass> = chains
            .par_iter_mut()
            .zip(traces.par_iter_mut())
            .enumerate()
            .map(|(c, (slot, trace))| {
                let quota = mutations / n + u64::from((c as u64) < mutations % n);
                let mut target = make(scene, bdpt, std::mem::take(&mut slot.walks));
                let mut pass = ChainPass {
                    large: StepCounts::default(),
                    small: StepCounts::default(),
                    large_sum: 0.0,
                };
                slot.splats.clear();
                for _ in 0..quota {
                    let from = slot.splats.len();
                    let splats = &mut slot.splats;
                    let step = &mut |p, v| splats.push((p, v));
                    let o = slot.chain.step(large_step, target.as_mut(), step);
                    trace.step(grid, &slot.splats[from..]);
                    let counts = if o.large {
                        pass.large_sum += o.fy;
                        &mut pass.large
                    } else {
                        &mut pass.small
                    };
                    counts.attempted += 1;
                    counts.accepted += u64::from(o.accepted);
                }
                slot.walks = target.storage();
                pass
            })
            .collect();
        for (slot, pass) in chains.iter().zip(results) {
            for &(r, l) in &slot.splats {
                if l.is_finite() {
                    film.add_splat(r, l);
                }
            }
            self.b_sum += pass.large_sum;
            self.b_samples += pass.large.attempted;
            for (total, add) in [(&mut self.large, pass.large), (&mut self.small, pass.small)] {
                total.attempted += add.attempted;
                total.accepted += add.accepted;
            }
        }
        self.chains = chains;
        self.mixing.put(traces);
        self.b = self.b_sum / self.b_samples.max(1) as f64;
        film.splat_scale = self.b;
    }
}

/// Deposits a step makes on average (a BDPT sample's own and light-tracing splats, twice: the
/// current state's and the proposal's), for the memory estimate.
const DEPOSITS_PER_STEP: u64 = 8;

/// PSSMLT's facts: film-wide passes that splat, its chains, light start points (BDPT's walks),
/// a camera checked before the work, shards as independent runs.
pub struct PssmltFacts;

impl super::Facts for PssmltFacts {
    fn prepare<'t>(
        &self,
        setup: &super::Setup<'_, 't>,
    ) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
        let mut p = Pssmlt::new(
            setup.scene,
            setup.technique,
            setup.settings.pssmlt.clone(),
            setup.seed,
            setup.max_depth,
        )?;
        p.bdpt.heuristic = setup.settings.mis_heuristic;
        Ok(Box::new(p))
    }

    /// Its target is BDPT's sample, the strategies weighted against each other.
    fn takes(&self, option: super::OwnOption) -> bool {
        option == super::OwnOption::MisHeuristic
    }

    fn samples_light_starts(&self) -> bool {
        true
    }

    /// A BDPT sample: its light subpath starts at a volume vertex x0 from the same primary
    /// samples as BDPT's (`bidir::walk`), its strategies collect L_e,V0 with BDPT's weights.
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        None
    }

    fn check(&self, case: &super::Case) -> Result<(), super::IntegratorError> {
        check_scene(case.scene, "pssmlt").map_err(super::IntegratorError::from)
    }

    fn pass_footprint(&self, _: &super::Case) -> super::PassFootprint {
        super::PassFootprint {
            tiles: false,
            bytes_per_sample: DEPOSITS_PER_STEP * super::SPLAT_BYTES,
        }
    }

    fn memory_parts(&self, case: &super::Case) -> Vec<(&'static str, u64)> {
        let s = &case.settings.pssmlt;
        // a chain's primary samples (two subpaths' worth of numbers, each about 48 bytes) and
        // walks; the bootstrap's f* values
        let per_chain = 2 * crate::bidir::MAX_SUBPATH_VERTICES as u64 * 8 * 48;
        vec![(
            "pssmlt chains",
            s.chains as u64 * per_chain + s.bootstrap * 8,
        )]
    }

    fn shard_split(&self) -> super::ShardSplit {
        super::ShardSplit::IndependentChains
    }

    fn chains(&self) -> Option<super::ChainCount> {
        Some(super::ChainCount {
            flag: "--pssmlt-chains",
            get: |s| s.pssmlt.chains,
            set: |s, c| s.pssmlt.chains = c,
        })
    }

    fn statistics_key(&self) -> Option<&'static str> {
        Some("pssmlt")
    }

    /// Its chains splat over the whole film.
    fn pixel_variance(&self) -> bool {
        false
    }
}

impl super::Integrator for Pssmlt<'_> {
    fn label(&self) -> String {
        self.name.into()
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
                "{} bootstrap ({} BDPT samples, seeds of {} chains)",
                self.name, self.settings.bootstrap, self.settings.chains
            )
        })
    }

    fn run_stage(&mut self, scene: &Scene) {
        if !self.initialized {
            self.initialize(scene);
        }
    }

    /// b, the large and small steps' counts and the chains' mixing.
    fn statistics(&self) -> super::Statistics {
        let line = |name: &str, c: &StepCounts| {
            format!(
                "  {name:<11} attempted {:>10} accepted {:>10} acceptance {:.4}",
                c.attempted,
                c.accepted,
                c.acceptance_rate()
            )
        };
        let json = |c: &StepCounts| {
            serde_json::json!({"attempted": c.attempted, "accepted": c.accepted,
                "acceptance_rate": c.acceptance_rate()})
        };
        let mut stats = super::Statistics {
            json: Some(serde_json::json!({"b": self.b, "b_samples": self.b_samples,
                "large_steps": json(&self.large), "small_steps": json(&self.small)})),
            lines: vec![
                format!(
                    "  {}: b = {:.5} ({} samples)",
                    self.name, self.b, self.b_samples
                ),
                line("large steps", &self.large),
                line("small steps", &self.small),
            ],
            ..Default::default()
        };
        self.mixing.statistics(self.name, &mut stats);
        stats
    }

    /// The chains are not saved in a checkpoint: a resumed run is an independent run merged by
    /// sample count, as the path-space MLT's.
    fn resumes_exactly(&self) -> bool {
        false
    }
}
