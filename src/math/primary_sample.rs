//! Primary sample space (Kelemen, Szirmay-Kalos, Antal, Csonka 2002): a path sampler is a
//! deterministic function of the uniform numbers it draws, so a Markov chain over those numbers
//! (the unit hypercube) is a Markov chain over paths that needs no path-space mutations.
//!
//! [`PrimarySamples`] is the state of such a chain: the numbers of the current state, drawn
//! lazily (a sampler that draws more numbers than before extends the vector), and the two
//! proposals of the chain:
//! - the *large step*: every number afresh, uniform. Its transition density is 1 in both
//!   directions;
//! - the *small step*: every number moved by a wrapped normal offset of standard deviation
//!   `sigma`. The offset's density depends only on the wrapped difference, and the difference
//!   from y back to x is the negated one, whose density is the same: the step is symmetric.
//!
//! Both are symmetric, so a mixture with a fixed large-step probability is too, and the
//! acceptance of a target I(u) is min(1, I(y) / I(x)) (Metropolis et al. 1953).
//!
//! Numbers are mutated lazily: a coordinate the current state did not read keeps its last value
//! and receives, when next read, all the small steps it missed at once (n steps of deviation
//! sigma are one step of deviation sigma sqrt(n)), or a fresh value when a large step was
//! accepted since. That is the same chain as mutating every coordinate every step.
//! The value a number has in the current state is fixed when a proposal first reads it, and a
//! rejection keeps it: drawing it afresh after a rejection would forget what the rejection said
//! of it and favour the proposals that read more numbers.
//!
//! Streams keep a small step small when a sampler's parts consume a varying count of numbers:
//! coordinate j of stream s is number `s + STREAMS * j`, so the eye walk's numbers do not shift
//! when the light walk took one more bounce.
//!
//! Book: "Enlightened local path sampling: the adjoint image and particles", section
//! "Metropolis particles".

use rand::RngCore;
use rand_pcg::Pcg32;

/// Independent coordinate streams (see the module documentation).
pub const STREAMS: usize = 4;

/// Kelemen et al.'s default small-step deviation is of this order: small enough that most
/// small steps stay on the same path type, large enough to move across a pixel's worth of
/// primary samples in a few steps.
pub const DEFAULT_SIGMA: f64 = 1.0 / 64.0;

#[derive(Clone, Copy, Debug, Default)]
struct Coordinate {
    value: f64,
    /// The iteration whose mutation `value` reflects.
    modified: u64,
    /// Whether the chain has read this number (storage is allocated in rounds of all the
    /// streams, so other streams' slots can exist unread).
    read: bool,
    /// The iteration that last read the number, and the three fields before it did (restored
    /// if that iteration is rejected).
    touched: u64,
    backup: (f64, u64, bool),
}

/// `n` small steps of deviation `sigma` at once, from number `value` with the standard normal
/// number `z`: the offset sigma sqrt(n) z, wrapped into [0, 1). The wrap keeps the step
/// symmetric (the density of going from u to v is that of the wrapped difference, the same as
/// from v to u), and n steps of a normal offset are one of deviation sigma sqrt(n).
// ANCHOR: small_step
pub fn small_step(value: f64, sigma: f64, n: f64, z: f64) -> f64 {
    // ASSIGNMENT: small_step
    let v = value + sigma * n.sqrt() * z;
    let v = v - v.floor();
    // v - floor(v) rounds to 1.0 for tiny negative v
    if v >= 1.0 {
        0.0
    } else {
        v
    }
    // END ASSIGNMENT
}
// ANCHOR_END: small_step

/// The state of a primary-sample-space Markov chain (Kelemen et al. 2002).
// ANCHOR: primary_samples
#[derive(Clone, Debug)]
pub struct PrimarySamples {
    coords: Vec<Coordinate>,
    /// The chain's own random numbers: mutations and acceptance decisions.
    rng: Pcg32,
    /// Deviation of the small step.
    sigma: f64,
    /// Current iteration (incremented by [`PrimarySamples::start_iteration`]).
    iteration: u64,
    /// Whether the current iteration is a large step.
    large_step: bool,
    /// The last accepted large step: coordinates older than it are redrawn when read.
    last_large_step: u64,
    /// Per stream, the next coordinate to read.
    next: [usize; STREAMS],
    stream: usize,
}
// ANCHOR_END: primary_samples

impl PrimarySamples {
    /// A chain whose first state is the uniform numbers drawn from `rng` (its first iteration
    /// is a large step, so no coordinate exists yet).
    pub fn new(rng: Pcg32, sigma: f64) -> Self {
        PrimarySamples {
            coords: Vec::new(),
            rng,
            sigma,
            iteration: 0,
            large_step: true,
            last_large_step: 0,
            next: [0; STREAMS],
            stream: 0,
        }
    }

    /// Starts over as [`PrimarySamples::new`] with `rng`, keeping the storage (a bootstrap
    /// evaluates many independent first states with one chain object).
    pub fn restart(&mut self, rng: Pcg32) {
        self.coords.clear();
        self.rng = rng;
        self.iteration = 0;
        self.large_step = true;
        self.last_large_step = 0;
        self.next = [0; STREAMS];
        self.stream = 0;
    }

    /// Gives the chain a new stream for its mutations and decisions (a chain started from a
    /// bootstrap state re-created with that state's stream must not then repeat the
    /// bootstrap's numbers, or two chains started from one state would stay identical).
    pub fn reseed(&mut self, rng: Pcg32) {
        self.rng = rng;
    }

    /// Starts a proposal: a large step (every number fresh) or a small step.
    pub fn start_iteration(&mut self, large_step: bool) {
        self.iteration += 1;
        self.large_step = large_step;
        self.next = [0; STREAMS];
        self.stream = 0;
    }

    /// Reading from stream `s` (taken modulo [`STREAMS`]) from now on.
    pub fn set_stream(&mut self, s: usize) {
        self.stream = s % STREAMS;
    }

    /// Whether the current proposal is a large step.
    pub fn is_large_step(&self) -> bool {
        self.large_step
    }

    /// A uniform number in [0, 1) from the chain's own stream (not a coordinate).
    pub fn uniform(&mut self) -> f64 {
        (self.rng.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    /// A standard normal number (Box-Muller).
    fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // in (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// The next number of the current stream under the current proposal.
    // ANCHOR: next_coordinate
    pub fn next_number(&mut self) -> f64 {
        let i = self.stream + STREAMS * self.next[self.stream];
        self.next[self.stream] += 1;
        if i >= self.coords.len() {
            self.coords.resize(i + 1, Coordinate::default());
        }
        // the number as of the last accepted large step: one that was not read then (or
        // never) is uniform, as that step would have redrawn it
        let c = self.coords[i];
        let (value, modified) = if !c.read || c.modified < self.last_large_step {
            (self.uniform(), self.last_large_step)
        } else {
            (c.value, c.modified)
        };
        // the number in the current state: the small steps it missed in the accepted
        // iterations since, at once
        let before = self.iteration.saturating_sub(1);
        let current = if before > modified {
            let z = self.normal();
            small_step(value, self.sigma, (before - modified) as f64, z)
        } else {
            value
        };
        // each number is read at most once per iteration: back up the current state's number.
        // A rejected proposal keeps it: it was part of the state already, and drawing it
        // afresh after a rejection would forget what the rejection said of it (proposals that
        // read more numbers would be favoured)
        self.coords[i].touched = self.iteration;
        self.coords[i].backup = (current, before, true);
        let value = if self.large_step {
            self.uniform()
        } else {
            let z = self.normal();
            small_step(current, self.sigma, 1.0, z)
        };
        let c = &mut self.coords[i];
        c.value = value;
        c.modified = self.iteration;
        c.read = true;
        value
    }
    // ANCHOR_END: next_coordinate

    /// Keeps the proposal as the new state.
    pub fn accept(&mut self) {
        if self.large_step {
            self.last_large_step = self.iteration;
        }
    }

    /// Restores the previous state.
    pub fn reject(&mut self) {
        for c in &mut self.coords {
            if c.touched == self.iteration {
                (c.value, c.modified, c.read) = c.backup;
            }
        }
        self.iteration -= 1;
    }

    /// The stored number `j` of stream `s`: the current state's, if the state read it (a number
    /// the state did not read is refreshed lazily when next read); `None` if never read.
    pub fn value(&self, s: usize, j: usize) -> Option<f64> {
        self.coords
            .get(s % STREAMS + STREAMS * j)
            .filter(|c| c.read)
            .map(|c| c.value)
    }

    /// Every stored number in storage order (`None`: a slot never read).
    pub fn values(&self) -> Vec<Option<f64>> {
        self.coords
            .iter()
            .map(|c| c.read.then_some(c.value))
            .collect()
    }

    /// How many coordinates the chain holds (the longest state it has read).
    pub fn len(&self) -> usize {
        self.coords.len()
    }

    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }
}
