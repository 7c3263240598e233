//! The path characteristic (Pauly, Kollig, Keller 2000, sec. 3.1): bit b_i(l) is 1 when vertex
//! x_i lies on a surface and 0 when it lies in the volume. Paths of the same length k and
//! characteristic l form the set Omega_k^l, whose measure mu_k^l is the product of dA for the
//! surface vertices and dV for the medium vertices. Light and sensor vertices count as surface
//! vertices (point lights and the pinhole are Dirac positions on no surface; they carry no volume
//! measure either, so they take the surface bit).

use super::Vertex;

/// The characteristic l = sum_i b_i 2^i of a path x_0 ... x_k (x_0 is bit 0). Paths longer
/// than 63 edges keep their first 64 bits.
// ANCHOR: characteristic
pub fn characteristic(vertices: &[Vertex]) -> u64 {
    // ASSIGNMENT: characteristic
    vertices
        .iter()
        .take(64)
        .enumerate()
        .filter(|(_, v)| !v.is_medium())
        .fold(0u64, |l, (i, _)| l | (1u64 << i))
    // END ASSIGNMENT
}
// ANCHOR_END: characteristic

/// The measure of vertex i under characteristic l: "dA" for surface vertices, "dV" for medium
/// vertices (the product over i is mu_k^l).
pub fn measure_of(l: u64, i: usize) -> &'static str {
    if (l >> i) & 1 == 1 {
        "dA"
    } else {
        "dV"
    }
}
