//! Path space with participating media (Pauly, Kollig, Keller 2000, section 3).
//!
//! A path x_0 ... x_k runs from a light (x_0) to a sensor (x_k); each vertex lies on a surface or
//! in the medium, which the path's characteristic records bit by bit (sec. 3.1). The measure of
//! a path is the product of area (dA) and volume (dV) measures of its vertices; the generalized
//! geometry term G converts solid angle to these measures (sec. 3.2), and the measurement
//! contribution f_j of eq. (6) is a product of emission, G, transmittance, f-hat and W_e. The
//! densities of locally sampled paths are in the same product measure, so f_j / p is an
//! estimator of the path integral (7) whichever technique sampled the path.
//! Book: "Path space (eqs. 5-7)".

pub mod characteristic;
pub mod contribution;
pub mod distance;
pub mod geometry_term;
pub mod pdf;
pub mod subpath;
pub mod technique;
pub mod verify;
pub mod vertex;

pub use characteristic::characteristic;
pub use contribution::measurement_contribution;
pub use geometry_term::geometry_term;
pub use technique::{LocalSampling, Plain, PLAIN};
pub use vertex::{Vertex, VertexKind};

/// A path in the index arena style: vertices in order from the light (x_0) to the sensor (x_k).
#[derive(Clone, Debug, Default)]
pub struct Path {
    pub vertices: Vec<Vertex>,
}

impl Path {
    /// The number of edges k (a path of length k has k + 1 vertices).
    pub fn length(&self) -> usize {
        self.vertices.len().saturating_sub(1)
    }

    /// The characteristic l of the path (sec. 3.1).
    pub fn characteristic(&self) -> u64 {
        characteristic(&self.vertices)
    }
}
