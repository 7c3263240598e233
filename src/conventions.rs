//! Conventions used everywhere in pathspace, written once (book: "Notation and conventions").
//!
//! - **Directions at a vertex** both point away from it: `wo` towards where the light goes (the
//!   previous vertex of an eye path, the next of a light path), `wi` towards where it comes from.
//!   A phase function's deflection cosine is therefore `-dot(wo, wi)`; Henyey-Greenstein with
//!   g > 0 scatters forwards (its mean deflection cosine is g, checked by `tests/phase.rs`).
//! - **Paths** run x_0 (on a light) to x_k (on the sensor), as in Pauly et al. sec. 3.
//! - **Normals** are geometric and never flipped by the geometry code: a quad's is
//!   normalize(u x v), a box's and a sphere's point outwards. A shape with an `interior` medium
//!   holds it behind its normal.
//! - **Units**: lengths in scene units, sigma in 1/length, radiance in W/(m^2 sr) per channel.
//! - **Depth** counts scattering vertices (surface or medium) between sensor and light:
//!   `max_depth = 0` is emission seen directly, 1 is single scattering.

// ANCHOR: deflection
/// The deflection cosine of a phase function for directions in pathspace's convention.
#[inline]
pub fn deflection_cosine(wo: glam::Vec3, wi: glam::Vec3) -> f32 {
    // ASSIGNMENT: deflection_cosine
    -wo.dot(wi)
    // END ASSIGNMENT
}
// ANCHOR_END: deflection
