//! The Metropolis-Hastings acceptance probability (Pauly, Kollig, Keller 2000, eq. 8):
//! alpha(x -> y) = min(1, f(y) T(y -> x) / (f(x) T(x -> y))).
//!
//! With K(x -> y) = T(x -> y) alpha(x -> y), detailed balance f(x) K(x -> y) = f(y) K(y -> x)
//! holds because both sides equal min(f(x) T(x -> y), f(y) T(y -> x)); the chain then keeps
//! f / b stationary (Veach 1997 sec. 11.2; Kristensen 2010 sec. 3.8).

/// alpha(x -> y) from the scalar contributions and the transition densities both ways. A
/// proposal the mutation could not take back (T(y -> x) = 0) or with f(y) = 0 is rejected.
// ANCHOR: acceptance
pub fn acceptance(f_x: f64, f_y: f64, t_xy: f64, t_yx: f64) -> f64 {
    // ASSIGNMENT: acceptance
    let possible = f_y > 0.0 && t_xy > 0.0 && t_yx > 0.0 && (f_y * t_yx).is_finite();
    if !possible {
        return 0.0;
    }
    if f_x.is_nan() || f_x <= 0.0 {
        return 1.0;
    }
    ((f_y * t_yx) / (f_x * t_xy)).min(1.0)
    // END ASSIGNMENT
}
// ANCHOR_END: acceptance
