//! The mutations of Metropolis light transport, one interface (Veach 1997 sec. 11.3; Pauly,
//! Kollig, Keller 2000 sec. 5.2): `sample(x) -> y` proposes a path and
//! `transition_density(x, y)` is Veach's T(x -> y), the density of proposing y from x in the
//! measure of the vertices the mutation changes, with the Dirac factors of specular vertices
//! removed as in `contribution`. Eq. (8) needs T both ways; no mutation assumes symmetry.

pub mod bidirectional;
pub mod light;
pub mod multichain;
pub mod propagation;
pub mod sensor;

use crate::math::Sampler;
use crate::path::pdf::Densities;
use crate::path::{LocalSampling, Vertex};
use crate::scene::Scene;

pub use bidirectional::Bidirectional;
pub use light::LightPerturbation;
pub use multichain::MultiChainPerturbation;
pub use propagation::PropagationPerturbation;
pub use sensor::SensorPerturbation;

// ANCHOR: mutation
/// A proposal distribution over paths (Mitsuba 0.6's `Mutator::{sampleMutation, Q}`).
///
/// Both methods write into buffers the caller keeps (`y`, `work`): a chain proposes once per
/// mutation, and a fresh vector per proposal made MLT allocate two to three times per step.
pub trait Mutation: Sync {
    /// Writes a proposal y from x into `y` (its old content is dropped); `None` when the
    /// mutation does not apply to x or the proposal left path space (escaped, changed the
    /// characteristic): the chain then stays at x, and `y` holds nothing of use.
    fn sample(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        x: &[Vertex],
        sampler: &mut Sampler,
        work: &mut Workspace,
        y: &mut Vec<Vertex>,
    ) -> Option<()>;
    /// T(x -> y); zero when `sample` cannot produce y from x.
    fn transition_density(
        &self,
        scene: &Scene,
        tech: &dyn LocalSampling,
        x: &[Vertex],
        y: &[Vertex],
        work: &mut Workspace,
    ) -> f64;
}

/// The intermediate buffers of the mutations, reused from one proposal to the next (each
/// chain owns one): their content means nothing between calls.
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    /// The eye side the bidirectional mutation grows, or a retraced chain of vertices.
    pub(crate) vertices: Vec<Vertex>,
    /// The densities of a proposal's new vertices (the bidirectional mutation's T).
    pub(crate) densities: Densities,
}
// ANCHOR_END: mutation

/// The closed set of mutation types, in the order of the configuration keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MutationKind {
    Bidirectional,
    Sensor,
    Light,
    Propagation,
    MultiChain,
}

/// One value per mutation type, indexed by [`MutationKind::index`] (weights, statistics).
pub type PerMutation<T> = [T; MutationKind::COUNT];

impl MutationKind {
    /// How many mutation types there are: the length of every per-mutation array.
    pub const COUNT: usize = 5;

    pub const ALL: PerMutation<MutationKind> = [
        MutationKind::Bidirectional,
        MutationKind::Sensor,
        MutationKind::Light,
        MutationKind::Propagation,
        MutationKind::MultiChain,
    ];

    /// The configuration key and report name.
    pub fn name(self) -> &'static str {
        match self {
            MutationKind::Bidirectional => "bidirectional",
            MutationKind::Sensor => "sensor",
            MutationKind::Light => "light",
            MutationKind::Propagation => "propagation",
            MutationKind::MultiChain => "multichain",
        }
    }

    pub fn index(self) -> usize {
        self as usize
    }
}

/// p(D) proportional to 1/D on [min, max] (Pauly et al. sec. 5.2.1), sampled as Veach's eq.
/// (11.11), D = max exp(-ln(max/min) u): the same law written from the other end.
// ANCHOR: inverse_distance
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseDistance {
    pub min: f32,
    pub max: f32,
}

impl InverseDistance {
    /// Requires 0 < min < max, finite.
    pub fn new(min: f32, max: f32) -> Result<Self, super::MltError> {
        if min > 0.0 && max > min && max.is_finite() {
            Ok(InverseDistance { min, max })
        } else {
            Err(super::MltError::BadRange(min, max))
        }
    }

    /// D for a uniform u in [0, 1) [Veach eq. 11.11].
    pub fn sample(&self, u: f32) -> f32 {
        // ASSIGNMENT: inverse_distance
        self.max * (-(self.max / self.min).ln() * u).exp()
        // END ASSIGNMENT
    }

    /// p(D) = 1 / (D ln(max/min)) on [min, max].
    pub fn pdf(&self, d: f32) -> f64 {
        // ASSIGNMENT: inverse_distance
        // a sampled D can round a hair outside the range
        let slack = 1e-5;
        if d < self.min * (1.0 - slack) || d > self.max * (1.0 + slack) {
            return 0.0;
        }
        1.0 / (d as f64 * ((self.max / self.min) as f64).ln())
        // END ASSIGNMENT
    }
}
// ANCHOR_END: inverse_distance

/// The prefix x[..n] of both paths is the same vertices.
pub(crate) fn same_prefix(x: &[Vertex], y: &[Vertex], n: usize) -> bool {
    x.len() >= n
        && y.len() >= n
        && x[..n]
            .iter()
            .zip(&y[..n])
            .all(|(a, b)| super::contribution::same_vertex(a, b))
}

/// Relative tolerance on a kept distance (medium vertices placed at their old distance).
pub(crate) const DISTANCE_TOLERANCE: f32 = 1e-4;

/// True when `a` and `b` agree within `DISTANCE_TOLERANCE`.
pub(crate) fn same_distance(a: f32, b: f32) -> bool {
    (a - b).abs() <= DISTANCE_TOLERANCE * a.abs().max(b.abs())
}
