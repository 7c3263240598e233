//! Sequential Monte Carlo adaptation in low-anisotropy participating media (Pegoraro, Wald,
//! Parker, EGSR 2008).
//!
//! Radiance estimates computed during rendering are cached in a 5-D structure, a spatial
//! octree whose leaves hold adaptive directional grids, which defines at every moment a control
//! variate g and an importance-sampling pdf p for the in-scattering integral at medium vertices
//! (eq. 5). Each estimate uses a fixed snapshot of both predicates, so the estimator stays
//! unbiased while they keep improving (eq. 1-3).
//!
//! | paper | module |
//! |---|---|
//! | eq. (1)-(3), the variants of Fig. 3 | [`estimator`] |
//! | sec. 4.1 the (s, t) grid | [`grid`] |
//! | sec. 4.1 B-spline control variates | [`bspline`] |
//! | sec. 4.2 the tree of partial sums | [`partial_sums`] |
//! | sec. 4.1-4.3 one leaf's cache, inheritance | [`cache`] |
//! | sec. 4.3-4.4 the octree, refinement criterion | [`octree`] |
//! | eq. (7), Fig. 2 distance sampling | [`distance`] |
//! | eq. (8), (9) ray marching on Omega_t U Omega_s | [`march`] |
//!
//! Parallelism and determinism: during a pass every thread reads the same snapshot of the
//! octree; the records of the pass are collected per tile and merged between passes in tile
//! order (then meter-chunk order), refinements happening during that serial merge. The result
//! is bit-identical for a seed whatever the thread count.
//! Book: "Sequential Monte Carlo adaptation", "SMC: the radiance cache", "SMC: the estimators",
//! "SMC: experiments".

pub mod bspline;
pub mod cache;
pub mod distance;
pub mod estimator;
pub mod grid;
pub mod march;
pub mod octree;
pub mod partial_sums;
pub mod walk;

pub use estimator::{ControlVariate, ImportanceSampling, Variant};
pub use octree::{Octree, OctreeStats, Record};
pub use walk::Scratch;

use glam::Vec3;

use crate::conventions::OptionValue as _;
use crate::geometry::Ray;
use crate::math::{warp, Frame, Sampler};
use crate::medium::Phase;
use crate::scene::{IrradianceMeter, Scene};
use crate::spectrum::Rgb;
use cache::RadianceCache;

/// The default refinement threshold on the average record count (the method's single
/// parameter, [PWP08 sec. 4.4]); Table 1 uses 256 and 512 for 512x512 renders. This default
/// was chosen by the threshold sweep of the experiments chapter on the 32x32 test bed.
pub const DEFAULT_REFINEMENT_THRESHOLD: f64 = 64.0;
/// The default memory budget of the structure: 1 GiB (Table 1's largest structure is 0.98 GB).
pub const DEFAULT_CACHE_BUDGET: usize = 1 << 30;
/// The default ray-marching step, in mean free paths of the medium (1 / mean sigma_t).
pub const DEFAULT_MARCH_STEP_MFP: f32 = 1.0;

/// Which form of the radiative transfer the in-scattering estimates enter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EstimatorForm {
    /// eq. (7): free-flight distance sampling, the pseudo-code of Fig. 2.
    Distance,
    /// eq. (8) with the joint domain Omega_t U Omega_s of eq. (9); `step` in mean free paths.
    RayMarching { step: f32 },
}

/// The estimator forms as `[render.smc] estimator` and `--smc-estimator` name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EstimatorKind {
    /// eq. (7), [`EstimatorForm::Distance`].
    Distance,
    /// eq. (8)-(9), [`EstimatorForm::RayMarching`].
    March,
}

crate::option_value!(EstimatorKind, "SMC estimator");

impl EstimatorForm {
    /// The form of `kind`, marching by `step` mean free paths (default 1), checked.
    pub fn new(kind: EstimatorKind, step: Option<f32>) -> Result<Self, SmcError> {
        match kind {
            EstimatorKind::Distance => Ok(EstimatorForm::Distance),
            EstimatorKind::March => {
                let step = step.unwrap_or(DEFAULT_MARCH_STEP_MFP);
                if !(step.is_finite() && step > 0.0) {
                    return Err(SmcError::BadMarchStep(step));
                }
                Ok(EstimatorForm::RayMarching { step })
            }
        }
    }

    /// The form named `s` with the default step.
    pub fn parse(s: &str) -> Result<Self, String> {
        Ok(Self::new(EstimatorKind::parse(s)?, None)?)
    }

    /// Its kind, without the step.
    pub fn kind(self) -> EstimatorKind {
        match self {
            EstimatorForm::Distance => EstimatorKind::Distance,
            EstimatorForm::RayMarching { .. } => EstimatorKind::March,
        }
    }

    pub fn name(self) -> String {
        self.kind().name()
    }
}

/// Parses a byte count: `1073741824`, `512MiB`, `1GiB`, `64KiB` (the `--cache-budget` option
/// and the `[render.smc] cache_budget` key).
pub fn parse_bytes(s: &str) -> Result<usize, SmcError> {
    let t = s.trim();
    let (digits, unit) = match t.find(|c: char| !c.is_ascii_digit()) {
        Some(i) => t.split_at(i),
        None => (t, ""),
    };
    let scale: usize = match unit.trim() {
        "" | "B" => 1,
        "KiB" => 1 << 10,
        "MiB" => 1 << 20,
        "GiB" => 1 << 30,
        u => return Err(SmcError::UnknownUnit(s.into(), u.into())),
    };
    digits
        .parse::<usize>()
        .ok()
        .and_then(|n| n.checked_mul(scale))
        .ok_or_else(|| SmcError::NotBytes(s.into()))
}

/// Why SMC refuses a value or its settings (Pegoraro et al. 2008: the variant, the estimator
/// form of eq. (7) or (8), the cache's refinement threshold and memory budget); the messages
/// are what the command line and the scene-file errors print.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SmcError {
    /// The ray-marching step of eq. (8) is not a positive number of mean free paths.
    #[error("the ray-marching step {0} must be a positive number of mean free paths")]
    BadMarchStep(f32),
    /// A byte count with a unit that is none (the count, the unit).
    #[error("`{0}`: unknown unit `{1}` (use B, KiB, MiB or GiB)")]
    UnknownUnit(String, String),
    /// A byte count that does not parse or overflows.
    #[error("`{0}` is not a byte count such as 1073741824 or 512MiB")]
    NotBytes(String),
    /// A file's byte count that is negative (the key as the caller spells it, the value).
    #[error("{0} = {1} is not a byte count")]
    NegativeBytes(String, i64),
    /// A budget below the root cache (the key, the budget, the root's bytes).
    #[error("{0} = {1} bytes cannot hold even the root cache ({2} bytes)")]
    BudgetBelowRoot(String, usize, usize),
    /// The settings' threshold is not a positive number of records.
    #[error("the refinement threshold {0} must be a positive number of records")]
    BadThreshold(f64),
    /// The settings' budget is below the root cache (the budget, the root's bytes).
    #[error("the cache budget of {0} bytes cannot hold even the root cache ({1} bytes)")]
    TooSmallBudget(usize, usize),
    /// A march across a medium would take more steps than the limit (see
    /// [`march::max_steps`]).
    #[error("[render.smc] step = {step} (--smc-step): a march through medium `{medium}` may take {steps:.3e} steps (mean majorant sigma_t {sigma:e} x longest segment {length:e} / step), more than the limit {limit}: raise step, or use estimator = \"distance\"")]
    MarchSteps {
        medium: String,
        step: f32,
        steps: f64,
        sigma: f32,
        length: f32,
        limit: usize,
    },
}

impl From<SmcError> for String {
    fn from(e: SmcError) -> Self {
        e.to_string()
    }
}

impl From<SmcError> for super::IntegratorError {
    fn from(e: SmcError) -> Self {
        super::IntegratorError::Refused(e.to_string())
    }
}

/// The weight of the phase function in SMC's adaptive direction density: a direction is drawn
/// from the cache's pdf with probability 1 - DEFENSIVE and from the phase function otherwise,
/// and weighted by the mixture's density.
///
/// DEVIATION: Pegoraro et al. sample the cache's pdf alone. Its coefficients are running means
/// of |f - g| over few records, so a cell can hold a coefficient orders of magnitude below what
/// arrives through it, and (f - g) / p then has a practically infinite variance. Measured before
/// the change on the heterogeneous cloud at 64 spp (distance form, seeds 1-3): is1_cv2 image
/// means of 0.307, 0.220, 0.223 against the path tracer's 0.234. With the mixture every
/// direction weight is at most 1 / DEFENSIVE times the phase-sampling one (defensive importance
/// sampling, Hesterberg 1995), at the cost of at most 1 / (1 - DEFENSIVE) in variance where the
/// cache is good.
pub const DEFENSIVE: f64 = 0.25;

/// The deepest scattering vertex of a path whose direction comes from the cache's pdf; deeper
/// vertices sample the phase function (their control variates stay).
///
/// DEVIATION: Pegoraro et al. sample the cache at every vertex. Each vertex multiplies the path
/// by f_p / p, a weight of mean one whose logarithm has a negative mean, so over many vertices
/// the product of weights is typically small and occasionally huge: in a bright hazy room
/// (albedo 0.9 walls, 0.97 haze, paths of some 30 vertices) is1_cv0 came out 24% dark at 24 spp
/// and is1_cv1's error bars were 120% of the image, with the defensive mixture. The first
/// vertices carry the image's directional structure, which is where the cache helps; beyond them
/// the light is diffuse and the phase function samples it as well. The cache's pdf before it is
/// complete is replaced by the phase function too (the paper's uniform directions, the same
/// thing for isotropic media; for a forward phase function they made weights up to
/// (1 + g) / (1 - g)^2).
///
/// The slab oracle (`tests/oracles/slab.rs`) shows the same on forward-scattering slabs
/// (Henyey-Greenstein g = 0.8, a beam at 60 degrees, paths of tens of vertices): with the pdf at
/// every vertex, uniform directions before it was complete and the adaptive march choice,
/// is1_cv2 transmitted 0.0020 +- 0.0007 of a tau 10, albedo 0.9 slab against the oracle's
/// 0.0229 (8 runs of 2 passes of 1024 samples); with the pdf at every vertex alone (the rest as
/// now) is1_cv0 transmitted 0.0148 +- 0.0008 (32 runs); with this limit 0.0244 +- 0.0008 (32
/// runs of 2 passes of 4096 samples; is1_cv2 0.0209 +- 0.0019). None of these
/// densities is wrong (eq. 1 stays unbiased [PWP08]); the product of weights is heavy-tailed,
/// and a few runs see its typical, small value. Book: "SMC: the estimators", section
/// "Forward scattering".
pub const ADAPTIVE_DEPTH: u32 = 2;

/// The mean cosine of a medium's phase function from which SMC's control variates are warned
/// against. The control variate is the cached radiance times the *isotropic* phase function
/// while the integrand is f_p L, so the residual grows with f_p's departure from 1 / 4 pi; on
/// the albedo-0.8 test bed at 256 spp is1_cv2 is 3.7x as efficient as Monte Carlo at g = 0.1,
/// 0.85x at g = 0.3, 0.07x at 0.6 and 30x Monte Carlo's error at 0.9 (book: "SMC:
/// experiments", section "Anisotropy"). The estimate stays unbiased, so this is a warning.
pub const CONTROL_VARIATE_ANISOTROPY: f32 = 0.3;

/// A warning when a medium of `scene` scatters too anisotropically for the control variate of
/// `variant` ([`CONTROL_VARIATE_ANISOTROPY`]), or `None`.
pub fn anisotropy_warning(scene: &Scene, variant: Variant) -> Option<String> {
    if variant.cv == ControlVariate::None {
        return None;
    }
    let g = scene
        .media
        .iter()
        .map(|m| m.phase().mean_cosine())
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))?;
    (g.abs() >= CONTROL_VARIATE_ANISOTROPY).then(|| {
        format!(
            "smc {}: a medium has a phase function of mean cosine {g}; SMC's control variate \
             assumes isotropic scattering and from |g| = {CONTROL_VARIATE_ANISOTROPY} on costs more \
             than it saves (at g = 0.9 thirty times Monte Carlo's error): the image is unbiased \
             but noisy; --smc-variant is0_cv0 or --integrator path converge faster",
            variant.name()
        )
    })
}

/// Samples `wi` at a medium vertex from the defensive mixture (1 - DEFENSIVE) p_cache +
/// DEFENSIVE f_p(wo, .); returns wi and the mixture's solid-angle density.
pub fn defensive_direction(
    cache: &RadianceCache,
    phase: &Phase,
    wo: Vec3,
    sampler: &mut Sampler,
) -> (Vec3, f32) {
    let (wi, p_cache) = if sampler.next_f64() >= DEFENSIVE {
        cache.sample(sampler.next_f64(), sampler.next_2d())
    } else {
        let wi = phase.sample(wo, sampler.next_2d()).wi;
        (wi, cache.pdf(wi))
    };
    let pdf = (1.0 - DEFENSIVE) * p_cache as f64 + DEFENSIVE * phase.pdf(wo, wi) as f64;
    (wi, pdf as f32)
}

/// The SMC integrator's options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmcSettings {
    pub variant: Variant,
    /// Refinement threshold on the average record count of a cache.
    pub threshold: f64,
    /// Memory budget of the structure in bytes.
    pub budget: usize,
    pub form: EstimatorForm,
}

impl Default for SmcSettings {
    fn default() -> Self {
        SmcSettings {
            variant: Variant::SMC,
            threshold: DEFAULT_REFINEMENT_THRESHOLD,
            budget: DEFAULT_CACHE_BUDGET,
            // the joint domain of eq. (9) controls the transmitted radiance too, which the
            // distance form leaves to plain sampling (see the experiments chapter)
            form: EstimatorForm::RayMarching {
                step: DEFAULT_MARCH_STEP_MFP,
            },
        }
    }
}

/// A byte count written as an integer or as a string with a unit (`"512MiB"`).
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize, PartialEq)]
#[serde(untagged)]
pub enum ByteCount {
    Bytes(i64),
    Text(String),
}

impl ByteCount {
    /// The command line's form: a string with an optional unit.
    pub fn parse_arg(s: &str) -> Result<ByteCount, std::convert::Infallible> {
        Ok(ByteCount::Text(s.to_string()))
    }
}

/// An invalid option: its key (as in `[render.smc]`) and what is wrong, the message naming
/// the option as the caller spells it (a file key or a flag).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct OptionError {
    pub key: &'static str,
    pub message: String,
}

/// The SMC options, declared once: the `[render.smc]` keys (serde) and the `--smc-*` flags
/// (clap) are the same fields with the same docs; [`SmcOptions::apply`] puts them over the
/// settings and checks every value (the file's over the defaults at load, the flags over the
/// file's on the command line). `--cache-budget` of earlier releases is a hidden alias.
#[derive(clap::Args, serde::Deserialize, serde::Serialize, Debug, Clone, Default, PartialEq)]
#[serde(deny_unknown_fields)]
#[command(next_help_heading = "SMC: sequential Monte Carlo (--integrator smc; [render.smc])")]
pub struct SmcOptions {
    /// SMC: the variant, is0|is1 x cv0|cv1|cv2 (default is1_cv2, the proposed method).
    #[arg(long = "smc-variant")]
    pub variant: Option<Variant>,
    /// SMC: the refinement threshold on the average record count of a cache (default 64).
    #[arg(long = "smc-threshold")]
    pub threshold: Option<f64>,
    /// SMC: memory budget of the structure, bytes or with a KiB/MiB/GiB suffix (default 1GiB).
    #[arg(long = "smc-cache-budget", alias = "cache-budget", value_parser = ByteCount::parse_arg)]
    pub cache_budget: Option<ByteCount>,
    /// SMC: `march` (eq. 8-9, the default) or `distance` (eq. 7, Fig. 2).
    #[arg(long = "smc-estimator")]
    pub estimator: Option<EstimatorKind>,
    /// SMC: the ray-marching step in mean free paths (default 1; march only).
    #[arg(long = "smc-step")]
    pub step: Option<f32>,
}

impl SmcOptions {
    /// True when no option is given.
    pub fn is_empty(&self) -> bool {
        *self == SmcOptions::default()
    }

    /// `base` with every given option replacing its setting, each checked; `name` spells a
    /// key for the messages (`step` in a file, `--smc-step` on the command line). The step of
    /// `base`'s march form carries over unless `step` replaces it.
    pub fn apply(
        &self,
        base: SmcSettings,
        name: &dyn Fn(&str) -> String,
    ) -> Result<SmcSettings, OptionError> {
        let err = |key: &'static str, message: String| OptionError { key, message };
        let mut s = base;
        if let Some(v) = self.variant {
            s.variant = v;
        }
        if let Some(t) = self.threshold {
            if !(t.is_finite() && t > 0.0) {
                let m = format!(
                    "{} = {t} must be a positive number of records",
                    name("threshold")
                );
                return Err(err("threshold", m));
            }
            s.threshold = t;
        }
        if let Some(b) = &self.cache_budget {
            s.budget = self
                .budget(b, name)
                .map_err(|e| err("cache_budget", e.to_string()))?;
        }
        let base_step = match base.form {
            EstimatorForm::RayMarching { step } => Some(step),
            EstimatorForm::Distance => None,
        };
        let estimator = self.estimator.unwrap_or(base.form.kind());
        if self.step.is_some() && estimator != EstimatorKind::March {
            let m = format!(
                "{} applies to the march estimator, not `{}`",
                name("step"),
                estimator.name()
            );
            return Err(err("step", m));
        }
        s.form = EstimatorForm::new(estimator, self.step.or(base_step))
            .map_err(|e| err("step", e.to_string()))?;
        Ok(s)
    }

    /// The budget in bytes, at least the root cache's.
    fn budget(&self, b: &ByteCount, name: &dyn Fn(&str) -> String) -> Result<usize, SmcError> {
        let bytes = match b {
            ByteCount::Bytes(n) => usize::try_from(*n)
                .map_err(|_| SmcError::NegativeBytes(name("cache_budget"), *n))?,
            ByteCount::Text(t) => parse_bytes(t)?,
        };
        let root = RadianceCache::root().bytes();
        if bytes < root {
            return Err(SmcError::BudgetBelowRoot(name("cache_budget"), bytes, root));
        }
        Ok(bytes)
    }
}

/// The SMC integrator: settings, the structure (read-only during a pass) and path limits.
#[derive(Clone, Debug)]
pub struct Smc {
    pub settings: SmcSettings,
    pub octree: Octree,
    pub max_depth: u32,
}

/// A sampled direction of the in-scattering integral with everything eq. (1) needs.
#[derive(Clone, Copy, Debug)]
#[allow(non_snake_case)]
pub struct InScatter {
    pub wi: Vec3,
    /// Solid-angle density of `wi`.
    pub pdf: f32,
    /// f_p(wo, wi).
    pub phase_value: f32,
    /// The control variate at `wi` (zero for cv0).
    pub g: Rgb,
    /// Its integral over the sphere.
    #[allow(non_snake_case)]
    pub G: Rgb,
}

impl Smc {
    /// Validates the settings and builds the root of the structure over the scene's bounds.
    pub fn new(
        scene: &Scene,
        settings: SmcSettings,
        max_depth: Option<u32>,
    ) -> Result<Self, SmcError> {
        if !(settings.threshold.is_finite() && settings.threshold > 0.0) {
            return Err(SmcError::BadThreshold(settings.threshold));
        }
        let root_bytes = RadianceCache::root().bytes();
        if settings.budget < root_bytes {
            return Err(SmcError::TooSmallBudget(settings.budget, root_bytes));
        }
        if let EstimatorForm::RayMarching { step } = settings.form {
            march::check_steps(scene, step)?;
        }
        let (min, max) = if scene.bounds.is_empty() {
            (Vec3::splat(-1.0), Vec3::splat(1.0))
        } else {
            (scene.bounds.min, scene.bounds.max)
        };
        Ok(Smc {
            settings,
            octree: Octree::new(
                min,
                max,
                settings.threshold,
                settings.budget,
                settings.variant.cv,
            ),
            max_depth: max_depth.unwrap_or(u32::MAX),
        })
    }

    /// [PWP08 Fig. 2 lines 4-8]: a direction for the in-scattering integral at the `vertex`-th
    /// scattering vertex of a path (1 = the first) from the snapshot's cache (or the phase
    /// function for is0, deeper than [`ADAPTIVE_DEPTH`], and before the cache's pdf is complete),
    /// with g and G.
    // ANCHOR: in_scatter
    #[inline]
    pub fn in_scatter(
        &self,
        cache: &RadianceCache,
        phase: &Phase,
        wo: Vec3,
        vertex: u32,
        sampler: &mut Sampler,
    ) -> InScatter {
        let cv = self.settings.variant.cv;
        let (wi, pdf) = if self.adaptive(cache, vertex) {
            defensive_direction(cache, phase, wo, sampler)
        } else {
            let ps = phase.sample(wo, sampler.next_2d());
            (ps.wi, ps.pdf)
        };
        InScatter {
            wi,
            pdf,
            phase_value: phase.eval(wo, wi),
            g: cache.g(wi, cv),
            G: cache.integral(cv),
        }
    }

    /// Whether the `vertex`-th scattering vertex samples from `cache`'s pdf (is1, a complete
    /// pdf, and no deeper than [`ADAPTIVE_DEPTH`]).
    #[inline]
    pub fn adaptive(&self, cache: &RadianceCache, vertex: u32) -> bool {
        self.settings.variant.is == ImportanceSampling::Order0
            && vertex <= ADAPTIVE_DEPTH
            && cache.pdf_is_positive()
    }
    // ANCHOR_END: in_scatter

    /// The radiance arriving at the camera along `ray` (which starts in `medium`); the path's
    /// records are appended to `records`.
    pub fn radiance(
        &self,
        scene: &Scene,
        ray: Ray,
        medium: Option<u32>,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
        records: &mut Vec<Record>,
    ) -> Rgb {
        scratch.links.clear();
        let state = walk::State::start(ray, medium, Rgb::ONE);
        self.walk(scene, state, sampler, scratch);
        walk::resolve(&scratch.links, records)
    }

    /// One sample of a meter's mean irradiance: a uniform point, delta lights by shadow rays,
    /// then a cosine-distributed direction (weight pi) continued by the SMC walk.
    pub fn meter_irradiance(
        &self,
        scene: &Scene,
        meter: &IrradianceMeter,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
        records: &mut Vec<Record>,
    ) -> Rgb {
        let n = meter.normal();
        let (p, _) = crate::geometry::Primitive::Quad(meter.quad).sample_area(sampler.next_2d());
        let direct = walk::delta_lights(scene, p, meter.medium, sampler, |wi| wi.dot(n).max(0.0));
        let local = warp::cosine_hemisphere(sampler.next_2d());
        if local.z <= 0.0 {
            return direct;
        }
        let wi = Frame::from_normal(n).to_world(local);
        scratch.links.clear();
        scratch
            .links
            .push(walk::Link::plain(direct, Rgb::splat(std::f32::consts::PI)));
        let state = walk::State::start(
            Ray::new(p, wi),
            meter.medium,
            Rgb::splat(std::f32::consts::PI),
        );
        self.walk(scene, state, sampler, scratch);
        walk::resolve(&scratch.links, records)
    }

    /// The walk of `state` by the estimator the settings choose.
    fn walk(
        &self,
        scene: &Scene,
        state: walk::State,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
    ) {
        match self.settings.form {
            EstimatorForm::Distance => distance::walk(self, scene, state, sampler, scratch),
            EstimatorForm::RayMarching { step } => {
                march::walk(self, scene, state, step, sampler, scratch)
            }
        }
    }

    /// Merges a pass's records in their order, refining as the criterion is met.
    pub fn merge(&mut self, records: &[Record]) {
        for r in records {
            self.octree.add_record(r);
        }
    }

    pub fn stats(&self) -> OctreeStats {
        self.octree.stats()
    }
}

/// SMC records a sample leaves for the structure (one per scattering or marching decision), at
/// least; a march leaves one per step, as many as a segment across the densest medium takes
/// (about 875 per sample measured where that is 1158 steps).
const RECORDS_PER_SAMPLE: u64 = 4;
/// One SMC record: position, direction, radiance, phase value.
const RECORD_BYTES: u64 = 40;

/// SMC's facts: tile results and records, its cache (bounded by its budget), the march's
/// step limit checked before the work, and no shards (a pass learns from every earlier one).
pub struct SmcFacts;

impl super::Facts for SmcFacts {
    fn prepare<'t>(
        &self,
        setup: &super::Setup<'_, 't>,
    ) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
        prepare(setup)
    }

    /// Both estimators collect the emission of eq. (3)'s source term along their flights
    /// (weight 1: no emitting medium is sampled as a light), and the records carry it.
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        None
    }

    /// A march that would exceed its step limit is refused before the memory it would need.
    fn check(&self, case: &super::Case) -> Result<(), super::IntegratorError> {
        if let EstimatorForm::RayMarching { step } = case.settings.smc.form {
            march::check_steps(case.scene, step).map_err(super::IntegratorError::from)?;
        }
        Ok(())
    }

    /// SMC shares the path tracer's surface vertices and next-event estimation.
    fn unreachable(&self) -> super::reach::Unreachable {
        super::reach::Unreachable::DiracLightsBehindSpecular
    }

    fn warnings(&self, case: &super::Case) -> Vec<String> {
        anisotropy_warning(case.scene, case.settings.smc.variant)
            .into_iter()
            .collect()
    }

    fn pass_footprint(&self, case: &super::Case) -> super::PassFootprint {
        let records = match case.settings.smc.form {
            // a longer march is refused (`march::check_steps`)
            EstimatorForm::RayMarching { step } => {
                march::scene_max_steps(case.scene, step).min(march::MAX_MARCH_STEPS as f64) as u64
            }
            EstimatorForm::Distance => 0,
        };
        super::PassFootprint {
            tiles: true,
            bytes_per_sample: records.max(RECORDS_PER_SAMPLE) * RECORD_BYTES,
        }
    }

    /// The octree grows until its budget, which bounds it.
    fn memory_parts(&self, case: &super::Case) -> Vec<(&'static str, u64)> {
        vec![("smc cache", case.settings.smc.budget as u64)]
    }

    fn shard_split(&self) -> super::ShardSplit {
        super::ShardSplit::Refused("smc")
    }

    fn statistics_key(&self) -> Option<&'static str> {
        Some("smc")
    }

    fn takes(&self, option: super::OwnOption) -> bool {
        matches!(
            option,
            super::OwnOption::Smc | super::OwnOption::PixelSamples
        )
    }

    /// Its control variates before they converge.
    fn negative_pixels_hint(&self) -> Option<&'static str> {
        Some("SMC's control variates: more samples per pixel, or --smc-variant is1_cv0")
    }
}

/// SMC's storage in a tile or meter chunk: the walk's path links and the records its samples
/// leave for the end of the pass.
#[derive(Default)]
struct PassScratch {
    links: Scratch,
    records: Vec<Record>,
}

/// SMC from the scene file's `[render.smc]` (the `--smc-*` options already applied).
pub fn prepare(setup: &super::Setup) -> Result<Box<dyn super::Integrator>, super::IntegratorError> {
    Ok(Box::new(Smc::new(
        setup.scene,
        setup.settings.smc,
        setup.max_depth,
    )?))
}

impl super::Integrator for Smc {
    fn label(&self) -> String {
        format!(
            "smc ({}, {})",
            self.settings.variant.name(),
            self.settings.form.name()
        )
    }

    fn camera_sample(
        &self,
        scene: &Scene,
        cam: &crate::scene::Camera,
        raster: glam::Vec2,
        sampler: &mut Sampler,
        scratch: &mut super::Scratch,
    ) -> Rgb {
        let own = scratch.own.get::<PassScratch>();
        self.radiance(
            scene,
            cam.sample_ray(raster, sampler),
            scene.camera_medium,
            sampler,
            &mut own.links,
            &mut own.records,
        )
    }

    fn meter_sample(
        &self,
        scene: &Scene,
        meter: u32,
        sampler: &mut Sampler,
        scratch: &mut super::Scratch,
    ) -> Rgb {
        let own = scratch.own.get::<PassScratch>();
        self.meter_irradiance(
            scene,
            &scene.sensors[meter as usize],
            sampler,
            &mut own.links,
            &mut own.records,
        )
    }

    fn delta_light_view(&self, scene: &Scene, sampler: &mut Sampler) -> Vec<super::Splat> {
        super::path::delta_light_view(scene, sampler)
    }

    /// A tile's or chunk's records, kept for the end of the pass.
    fn deposit(&self, own: &mut super::Own) -> Option<super::Deposit> {
        Some(Box::new(std::mem::take(
            &mut own.get::<PassScratch>().records,
        )))
    }

    /// [PWP08 Fig. 2 lines 13-14]: the pass's records refine the structure for the next pass.
    fn end_pass(&mut self, deposits: &[super::Deposit]) {
        for d in deposits {
            if let Some(r) = d.downcast_ref::<Vec<Record>>() {
                self.merge(r);
            }
        }
    }

    /// The structure's statistics (Pegoraro et al. Table 1).
    fn statistics(&self) -> super::Statistics {
        let s = self.stats();
        super::Statistics {
            json: Some(serde_json::json!({
                "refinement_threshold": s.threshold,
                "max_depth": s.max_depth,
                "nodes": s.nodes,
                "leaves": s.leaves,
                "cells": s.cells,
                "bytes": s.bytes,
                "budget": s.budget,
                "budget_reached": s.budget_reached,
                "records": s.records,
            })),
            lines: Vec::new(),
            closing: vec![format!("  {s}")],
            ..Default::default()
        }
    }

    fn as_any(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }

    fn checkpoint_state(&self) -> super::IntegratorState {
        Some(postcard::to_stdvec(&self.octree).expect("the octree always serializes"))
    }

    /// The octree comes back only whole and with finite coefficients: a damaged or forged
    /// checkpoint must not become a NaN image.
    fn restore_state(&mut self, state: Option<&[u8]>) -> Result<(), &'static str> {
        let bytes = state.ok_or("it holds no SMC structure")?;
        let octree: octree::Octree =
            postcard::from_bytes(bytes).map_err(|_| "SMC's octree cannot be read")?;
        if !octree.is_consistent() {
            return Err("SMC's octree is inconsistent");
        }
        self.octree = octree;
        Ok(())
    }
}
