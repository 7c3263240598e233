//! Metropolis particle sampling (Kristensen 2010, sec. 5.2.2, eq. (5.15)): the bidirectional
//! particle sampler run as a Kelemen-style Markov chain in primary sample space, so that the
//! particles crowd where paths carry light to the sensor.
//!
//! The bidirectional particle sampler is a deterministic function of the uniform numbers u it
//! draws. Its particles' expected weight sum is the quantity they represent:
//! E_u[sum alpha(u)] = int sum alpha(u) du. A Markov chain with stationary density
//! T(u) / b over the unit hypercube (b = int T du) estimates the same integral with the weights
//! alpha(u) b / T(u), averaged over its N states: unbiased wherever T(u) > 0 where
//! alpha(u) != 0.
//!
//! The target. Eq. (5.15) asks for pi* proportional to f(x)/p(x), the full path's contribution
//! I(u) (returned by the bidirectional sampler: (k + 2)/p_k w_s f/p_s). With T = I alone, the
//! particles of samples whose full path carries no light (a walk that ended early, a blocked or
//! back-facing connection) are lost: the representation is then biased, harmlessly for the
//! image (the guided pdfs stay exact) but visibly for the maps (Kristensen 2010 sec. 5.2.2 on what eq. (5.15) misses; measured here: the photons on a
//! floor that only reach a meter through its back are gone, and so are all importons on a black
//! emitter). This module therefore targets a defensive mixture (a choice of this crate;
//! delta = 0 is eq. (5.15) exactly):
//!
//! T(u) = I(u) / b_I + delta/2 (P_photon(u) / b_photon + P_importon(u) / b_importon),
//!
//! where P sums the luminance of u's photon (importon) weights and the b are bootstrap means.
//! About delta / (1 + delta) of the states then follow the particle weights themselves, every
//! particle is represented without bias, and no weight can exceed 2 b_T b_photon / (delta N)
//! (b_importon for importons): a constant floor instead would leave the states it attracts with
//! weights 1/delta times their share, the heavy tail this avoids.
//!
//! The chain: a pilot run (a quarter of the bootstrap's size) fixes the b's in T; then bootstrap
//! samples estimate b_T = E[T] and seed the chains in proportion to T (Veach's start-up bias
//! elimination: a chain started from a bootstrap sample drawn in proportion to a fixed T,
//! weighted by the bootstrap mean, is unbiased; a T normalized by the same bootstrap would be
//! only consistent); each chain proposes a large step (all numbers
//! afresh) with probability `p_large` (the thesis's 0.5) or a small step, and accepts with
//! min(1, T(y)/T(x)). A state deposits its particles once per step it is held, as one particle
//! with the multiplicity in its weight.
//!
//! Determinism: bootstrap samples and chains are each one stream derived from (seed, index);
//! chains run in parallel and are concatenated in chain order.
//!
//! Book: "Enlightened local path sampling: the adjoint image and particles", section
//! "Metropolis particles".

use rand_pcg::Pcg32;
use rayon::prelude::*;

use crate::bidir::Bdpt;
use crate::enlightened::particles::{bidirectional_sample, ImportonSource, ParticleSets};
use crate::math::sampler::mix64;
use crate::math::{PrimarySamples, Sampler};
use crate::path::LocalSampling;
use crate::scene::Scene;
use crate::spectrum::luminance;

/// The Metropolis particle sampler's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetropolisParticleSettings {
    /// Bootstrap samples (the thesis: 65536); a pilot run of a quarter as many (at least 256)
    /// precedes them.
    pub bootstrap: u64,
    /// Independent chains (the thesis: 1024).
    pub chains: u32,
    /// Probability of a large step (the thesis: 0.5, Kelemen's PSSMLT default for its scenes).
    pub large_step: f64,
    /// Small-step deviation in primary sample space.
    pub sigma: f64,
    /// delta: the weight of the defensive part of the target, which follows the particle
    /// weights (0: eq. (5.15) exactly; see the module documentation).
    pub defensive: f64,
}

impl Default for MetropolisParticleSettings {
    fn default() -> Self {
        MetropolisParticleSettings {
            bootstrap: 65_536,
            chains: 1024,
            large_step: 0.5,
            sigma: crate::math::primary_sample::DEFAULT_SIGMA,
            defensive: 0.1,
        }
    }
}

impl MetropolisParticleSettings {
    /// Every value in its range, or the reason it is not.
    pub fn check(&self) -> Result<(), MetropolisParticleError> {
        if self.bootstrap == 0 {
            return Err(MetropolisParticleError::NoBootstrap);
        }
        if self.chains == 0 {
            return Err(MetropolisParticleError::NoChains);
        }
        if !(0.0..=1.0).contains(&self.large_step) {
            return Err(MetropolisParticleError::BadLargeStep(self.large_step));
        }
        if !(self.sigma > 0.0 && self.sigma < 1.0) {
            return Err(MetropolisParticleError::BadSigma(self.sigma));
        }
        if !(self.defensive >= 0.0 && self.defensive.is_finite()) {
            return Err(MetropolisParticleError::BadDefensive(self.defensive));
        }
        Ok(())
    }
}

/// Why the Metropolis particle sampler refuses its settings (the value out of its range); the
/// messages name the setting as the `[render.guide]` keys do.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetropolisParticleError {
    /// No bootstrap sample: nothing to estimate b_T or seed the chains with.
    #[error("bootstrap must be at least 1")]
    NoBootstrap,
    /// No chain to run.
    #[error("chains must be at least 1")]
    NoChains,
    /// A large-step probability outside [0, 1].
    #[error("large_step = {0} must be a probability in [0, 1]")]
    BadLargeStep(f64),
    /// A small-step deviation outside (0, 1).
    #[error("sigma = {0} must be in (0, 1)")]
    BadSigma(f64),
    /// A defensive weight delta that is negative or not finite.
    #[error("defensive = {0} must be finite and >= 0")]
    BadDefensive(f64),
}

/// What a run of the sampler did (for the preprocessing statistics and the book).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MetropolisParticleStats {
    /// b_I: the bootstrap mean of the full-path contribution I(u).
    pub mean_contribution: f64,
    /// b_T: the bootstrap mean of the target T(u) (about 1 + delta).
    pub mean_target: f64,
    /// Fraction of bootstrap samples with I(u) > 0.
    pub connected: f64,
    /// Fraction of bootstrap samples carrying particles.
    pub with_particles: f64,
    /// Chain steps taken (N) and accepted.
    pub steps: u64,
    pub accepted: u64,
}

const BOOTSTRAP_SALT: u64 = 0x6d70_626f_6f74_0000;
const PILOT_SALT: u64 = 0x6d70_7069_6c6f_7400;
const CHAIN_SALT: u64 = 0x6d70_6368_6169_6e00;

/// The bidirectional particle sampler, evaluated at a chain's proposals.
struct Evaluator<'a> {
    scene: &'a Scene,
    bdpt: &'a Bdpt<'a>,
    source: ImportonSource,
    walks: crate::bidir::Scratch,
}

impl Evaluator<'_> {
    /// I(u) and the luminance sums of the photon and importon weights of u.
    fn eval(&mut self, sampler: &mut Sampler, out: &mut ParticleSets) -> [f64; 3] {
        out.clear();
        let i = bidirectional_sample(
            self.scene,
            self.bdpt,
            self.source,
            1.0,
            sampler,
            &mut self.walks,
            out,
        );
        let sum = |ps: &[crate::enlightened::Particle]| {
            ps.iter()
                .map(|p| luminance(p.weight).max(0.0) as f64)
                .sum::<f64>()
        };
        [i, sum(&out.photons), sum(&out.importons)]
    }

    /// The light vertex x_0 of the full path the last evaluation built (valid when its I > 0):
    /// the light walk's first vertex, or, for s = 0, the emitter the eye walk ended on.
    fn light_vertex(&self) -> Option<LightStart> {
        let v = self.walks.light.first().or(self.walks.eye.last())?;
        let (light, prim) = v.area_light_point(self.scene)?;
        Some(LightStart {
            light,
            prim,
            p: v.p,
            weight: 0.0,
        })
    }
}

/// A light start point of a chain state's full path, with the state's weight for the adjoint
/// image: I(u) b_T / (T(u) N) per step the state was held (Kristensen 2010, sec. 5.2.1: each
/// Markov state deposits its weight at F^-1(x_0)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightStart {
    pub light: u32,
    pub prim: u32,
    pub p: glam::Vec3,
    pub weight: f64,
}

// ANCHOR: target
/// The target T(u) = I(u)/b_I + delta/2 (P_photon(u)/b_photon + P_importon(u)/b_importon)
/// from the pilot run's means `b` of the three parts (a part whose mean is zero is left out).
#[derive(Clone, Copy)]
struct Target {
    inv: [f64; 3],
}

impl Target {
    fn new(b: [f64; 3], defensive: f64) -> Self {
        let inv = |m: f64, c: f64| if m > 0.0 && c > 0.0 { c / m } else { 0.0 };
        Target {
            inv: [
                inv(b[0], 1.0),
                inv(b[1], 0.5 * defensive),
                inv(b[2], 0.5 * defensive),
            ],
        }
    }

    fn of(&self, x: [f64; 3]) -> f64 {
        x[0] * self.inv[0] + x[1] * self.inv[1] + x[2] * self.inv[2]
    }
}
// ANCHOR_END: target

fn stream(seed: u64, salt: u64, index: u64) -> Pcg32 {
    Pcg32::new(mix64(seed ^ salt ^ mix64(index)), mix64(index ^ salt))
}

/// The Metropolis particle sampler (Kristensen 2010, eq. (5.15)): `steps` chain steps in total
/// over `settings.chains` chains, after `settings.bootstrap` bootstrap samples. Particle weights
/// are estimates of the same sums as [`crate::enlightened::particles::trace_bidirectional`]'s
/// (divided by the number of steps).
// ANCHOR: trace_metropolis
pub fn trace_metropolis(
    scene: &Scene,
    tech: &dyn LocalSampling,
    source: ImportonSource,
    steps: u64,
    seed: u64,
    settings: &MetropolisParticleSettings,
) -> (ParticleSets, MetropolisParticleStats) {
    let (sets, stats, _) =
        trace_metropolis_with_starts(scene, tech, source, steps, seed, settings, false);
    (sets, stats)
}
// ANCHOR_END: trace_metropolis

/// [`trace_metropolis`], and, if `starts` is set, the light start point of every chain state
/// with I(u) > 0, weighted so that their sum per region of the lights estimates the part of
/// the measurement whose paths start there (the adjoint image's I*, eq. (5.7)).
pub fn trace_metropolis_with_starts(
    scene: &Scene,
    tech: &dyn LocalSampling,
    source: ImportonSource,
    steps: u64,
    seed: u64,
    settings: &MetropolisParticleSettings,
    starts: bool,
) -> (ParticleSets, MetropolisParticleStats, Vec<LightStart>) {
    let mut stats = MetropolisParticleStats::default();
    if steps == 0 || settings.check().is_err() || !super::particles::can_trace(scene, source) {
        return (ParticleSets::default(), stats, Vec::new());
    }
    let run = Run {
        scene,
        base: super::particles::particle_bdpt(tech),
        source,
        seed,
        settings,
    };
    // 1. a pilot run fixes the target's normalization, then the bootstrap (independent of
    // it) estimates b_T and seeds the chains: with T fixed before the bootstrap, Veach's
    // start-up argument makes the weights exactly unbiased
    let mean = |v: &[[f64; 3]], j: usize| v.iter().map(|b| b[j]).sum::<f64>() / v.len() as f64;
    let pilot = run.evaluate(PILOT_SALT, (settings.bootstrap / 4).max(256));
    let target = Target::new(
        [mean(&pilot, 0), mean(&pilot, 1), mean(&pilot, 2)],
        settings.defensive,
    );
    let boot = run.evaluate(BOOTSTRAP_SALT, settings.bootstrap);
    let n_boot = boot.len() as f64;
    let b_t = boot.iter().map(|&b| target.of(b)).sum::<f64>() / n_boot;
    stats.mean_contribution = mean(&boot, 0);
    stats.mean_target = b_t;
    stats.connected = boot.iter().filter(|b| b[0] > 0.0).count() as f64 / n_boot;
    stats.with_particles = boot.iter().filter(|b| b[1] + b[2] > 0.0).count() as f64 / n_boot;
    if !(b_t > 0.0 && b_t.is_finite()) {
        return (ParticleSets::default(), stats, Vec::new());
    }
    // 2. chain starts: bootstrap samples drawn in proportion to T
    let cdf: Vec<f64> = boot
        .iter()
        .scan(0.0, |acc, &b| {
            *acc += target.of(b);
            Some(*acc)
        })
        .collect();
    let chains = Chains {
        total: *cdf.last().unwrap(),
        cdf,
        target,
        b_t,
        steps,
        count: settings.chains as u64,
        starts,
    };
    // 3. the chains
    let parts: Vec<(ParticleSets, u64, Vec<LightStart>)> = (0..chains.count)
        .into_par_iter()
        .map(|c| run.chain(&chains, c))
        .collect();
    let mut all = ParticleSets::default();
    let mut all_starts = Vec::new();
    for (mut p, a, st) in parts {
        all.append(&mut p);
        stats.accepted += a;
        all_starts.extend(st);
    }
    stats.steps = steps;
    (all, stats, all_starts)
}

/// One run of the Metropolis particle sampler: the scene, the particle walks and where the
/// importons come from, with the seed and settings every stream derives from.
struct Run<'a> {
    scene: &'a Scene,
    base: Bdpt<'a>,
    source: ImportonSource,
    seed: u64,
    settings: &'a MetropolisParticleSettings,
}

/// What every chain shares after the bootstrap: the cumulative target of the bootstrap samples
/// (where chains start), the target and its mean b_T, the steps in total and per chain count,
/// and whether light starts are kept.
struct Chains {
    cdf: Vec<f64>,
    total: f64,
    target: Target,
    b_t: f64,
    steps: u64,
    count: u64,
    starts: bool,
}

impl Run<'_> {
    fn evaluator(&self) -> Evaluator<'_> {
        Evaluator {
            scene: self.scene,
            bdpt: &self.base,
            source: self.source,
            walks: Default::default(),
        }
    }

    /// `n` independent samples of stream `salt` (the pilot run, the bootstrap), evaluated.
    fn evaluate(&self, salt: u64, n: u64) -> Vec<[f64; 3]> {
        let (seed, settings) = (self.seed, self.settings);
        let chunk = 1024u64;
        (0..n.div_ceil(chunk))
            .into_par_iter()
            .flat_map_iter(|c| {
                let mut ev = self.evaluator();
                let mut out = ParticleSets::default();
                // one chain object per chunk, restarted for every sample (no allocation per
                // sample once its storage has grown)
                let mut sampler = Sampler::primary(PrimarySamples::new(
                    stream(seed, salt, c * chunk),
                    settings.sigma,
                ));
                (c * chunk..((c + 1) * chunk).min(n))
                    .map(|b| {
                        let chain = sampler.chain().unwrap();
                        chain.restart(stream(seed, salt, b));
                        chain.start_iteration(true);
                        ev.eval(&mut sampler, &mut out)
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// Chain `c`: its start drawn from the bootstrap, its steps, and what it deposits (the
    /// particles, the accepted count, the light starts).
    fn chain(&self, chains: &Chains, c: u64) -> (ParticleSets, u64, Vec<LightStart>) {
        let (seed, settings) = (self.seed, self.settings);
        let Chains {
            ref cdf,
            total,
            target,
            b_t,
            steps,
            count,
            starts,
        } = *chains;
        let target = |b: [f64; 3]| target.of(b);
        let per_chain = steps / count + u64::from(c < steps % count);
        let mut rng = Sampler::new(seed, c ^ CHAIN_SALT, 1);
        let pick = rng.next_f64() * total;
        let start = cdf.partition_point(|&x| x <= pick).min(cdf.len() - 1) as u64;
        let mut ev = self.evaluator();
        let mut out = ParticleSets::default();
        // re-create the start state, then give the chain its own mutation stream
        let mut sampler = Sampler::primary(PrimarySamples::new(
            stream(seed, BOOTSTRAP_SALT, start),
            settings.sigma,
        ));
        sampler.chain().unwrap().start_iteration(true);
        let mut current = ParticleSets::default();
        let e = ev.eval(&mut sampler, &mut current);
        let mut t_x = target(e);
        // the current state's light start and I(u) (for the adjoint image)
        let mut start_x = (e[0] > 0.0).then(|| ev.light_vertex()).flatten();
        let mut i_x = e[0];
        let mut light_starts = Vec::new();
        let chain = sampler.chain().unwrap();
        chain.accept();
        chain.reseed(stream(seed, CHAIN_SALT, c));
        let mut held = 0u64;
        let mut accepted = 0u64;
        let mut deposit = ParticleSets::default();
        // the state's particles, once per step it was held, as one particle of that weight
        let mut flush =
            |state: &mut ParticleSets, t: f64, held: u64, start: Option<LightStart>, i: f64| {
                if held > 0 && t > 0.0 {
                    let w = held as f64 * b_t / (t * steps as f64);
                    state.scale(w as f32);
                    deposit.append(state);
                    if let Some(s) = start.filter(|_| starts) {
                        light_starts.push(LightStart { weight: w * i, ..s });
                    }
                }
                state.clear();
            };
        for _ in 0..per_chain {
            let chain = sampler.chain().unwrap();
            let large = chain.uniform() < settings.large_step;
            chain.start_iteration(large);
            let e = ev.eval(&mut sampler, &mut out);
            let t_y = target(e);
            let chain = sampler.chain().unwrap();
            let a = if t_x > 0.0 { (t_y / t_x).min(1.0) } else { 1.0 };
            if chain.uniform() < a {
                chain.accept();
                flush(&mut current, t_x, held, start_x, i_x);
                std::mem::swap(&mut current, &mut out);
                t_x = t_y;
                i_x = e[0];
                start_x = (i_x > 0.0 && starts).then(|| ev.light_vertex()).flatten();
                held = 1;
                accepted += 1;
            } else {
                chain.reject();
                held += 1;
            }
        }
        flush(&mut current, t_x, held, start_x, i_x);
        (deposit, accepted, light_starts)
    }
}
