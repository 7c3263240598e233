//! The Kelemen kernel: one Metropolis step of a chain over primary samples (Kelemen et al.
//! 2002, sec. 3-4), with Veach's expected-value deposits.
//!
//! A state u is the vector of uniform numbers a sampler read; its image contribution is the
//! list of deposits (film point, value) the sampler makes from u, and the target f*(u) is their
//! summed luminance. A step proposes y from x by a *large step* (every number afresh, with
//! probability `large_step`) or a *small step* (every number moved by a wrapped normal offset),
//! both symmetric in the unit hypercube (`math::primary_sample`), so the acceptance is
//! a(x -> y) = min(1, f*(y) / f*(x)) for either. The step deposits x's contribution with weight
//! (1 - a) / f*(x) and y's with a / f*(y), whatever is then accepted: over N steps of chains
//! distributed by f* / b, the deposits times b / N estimate the image.

use glam::Vec2;

use crate::math::{PrimarySamples, Sampler};
use crate::spectrum::Rgb;

/// A deposit: film point and value.
pub type Deposit = (Vec2, Rgb);

/// A sampler as a function of primary samples: the deposits of one state and its target value
/// f*(u) (their summed luminance, or zero for a state that carries no light).
pub trait Target {
    /// Reads the state's numbers from `sampler` (a primary-sample sampler), writes its deposits
    /// into `out` (cleared first) and returns f*(u).
    fn evaluate(&mut self, sampler: &mut Sampler, out: &mut Vec<Deposit>) -> f64;

    /// The walks' storage, handed back to the next target of the chain (none by default).
    fn storage(&mut self) -> crate::bidir::Scratch {
        crate::bidir::Scratch::default()
    }
}

/// The acceptance of Kelemen's symmetric proposals: min(1, f*(y) / f*(x)) (1 from a state
/// with f*(x) = 0, which a chain seeded by f* never holds).
// ANCHOR: acceptance
pub fn acceptance(fx: f64, fy: f64) -> f64 {
    if fx > 0.0 {
        (fy / fx).min(1.0)
    } else {
        1.0
    }
}
// ANCHOR_END: acceptance

/// What a step did, for the statistics and for b's refinement by the large steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutcome {
    pub large: bool,
    pub accepted: bool,
    /// f*(y) of the proposal (for a large step, an independent uniform sample of f*).
    pub fy: f64,
}

/// One Markov chain over primary samples: its sampler (which holds the state u and the
/// chain's own random numbers), the current state's deposits and f*, and the proposal's.
pub struct KelemenChain {
    pub sampler: Sampler,
    pub current: Vec<Deposit>,
    pub f: f64,
    proposal: Vec<Deposit>,
}

impl KelemenChain {
    /// A chain in state `state` (whose current iteration has been read by `target` into
    /// `current` with value `f`, and accepted).
    pub fn new(sampler: Sampler, current: Vec<Deposit>, f: f64) -> Self {
        KelemenChain {
            sampler,
            current,
            f,
            proposal: Vec::new(),
        }
    }

    /// The primary samples of the chain.
    pub fn state(&mut self) -> &mut PrimarySamples {
        self.sampler
            .chain()
            .expect("a Kelemen chain reads primary samples")
    }

    /// One Metropolis step with a large step of probability `large_step`: the expected-value
    /// deposits go to `deposit(point, value)` (in units of b: the film multiplies by b / N).
    // ANCHOR: step
    pub fn step(
        &mut self,
        large_step: f64,
        target: &mut (impl Target + ?Sized),
        deposit: &mut impl FnMut(Vec2, Rgb),
    ) -> StepOutcome {
        let large = self.state().uniform() < large_step;
        self.state().start_iteration(large);
        let fy = target.evaluate(&mut self.sampler, &mut self.proposal);
        let a = acceptance(self.f, fy);
        if a < 1.0 && self.f > 0.0 {
            let w = ((1.0 - a) / self.f) as f32;
            for &(p, v) in &self.current {
                deposit(p, v * w);
            }
        }
        if a > 0.0 && fy > 0.0 {
            let w = (a / fy) as f32;
            for &(p, v) in &self.proposal {
                deposit(p, v * w);
            }
        }
        let accepted = self.state().uniform() < a;
        if accepted {
            self.state().accept();
            std::mem::swap(&mut self.current, &mut self.proposal);
            self.f = fy;
        } else {
            self.state().reject();
        }
        StepOutcome {
            large,
            accepted,
            fy,
        }
    }
    // ANCHOR_END: step
}

/// Starts a chain from the state that stream `rng` draws on a large step (a bootstrap sample,
/// re-created exactly from its stream), then gives the chain the stream `own` for its
/// mutations and decisions; `None` when that state carries no light.
pub fn start_chain(
    rng: rand_pcg::Pcg32,
    own: rand_pcg::Pcg32,
    sigma: f64,
    target: &mut (impl Target + ?Sized),
) -> Option<KelemenChain> {
    let mut sampler = Sampler::primary(PrimarySamples::new(rng, sigma));
    let mut current = Vec::new();
    let chain = sampler.chain()?;
    chain.start_iteration(true);
    let f = target.evaluate(&mut sampler, &mut current);
    let chain = sampler.chain()?;
    chain.accept();
    chain.reseed(own);
    (f > 0.0).then(|| KelemenChain::new(sampler, current, f))
}
