//! The control-variate predicate g: B-spline coefficients over the directional grid
//! (Pegoraro, Wald, Parker 2008, sec. 4.1).
//!
//! Every cell holds one RGB coefficient c_ij, a running average of the radiance records that
//! fell in it. Two reconstructions are offered:
//!
//! - order 0 (piecewise constant, `cv1`): L~(s, t) = c_ij of the cell containing (s, t);
//! - order 1 (piecewise linear, `cv2`): the coefficients sit at the cell centres
//!   ((i + 1/2) / n_s, (j + 1/2) / n_t) and L~ interpolates them bilinearly, periodic in s;
//!   between the first (last) row of centres and the pole t = 0 (t = 1) it interpolates towards
//!   a polar value P_0 (P_1), the average of the boundary row's coefficients. The polar values
//!   make L~ single-valued at the poles (no discontinuity) and regularize the integral.
//!
//! Integral. With d omega = 4 pi ds dt, a periodic hat in s integrates to 1 / n_s, so
//! integrating over s leaves, in t, the piecewise-linear function through (0, P_0),
//! (h/2, r_0), (3h/2, r_1), ..., (1 - h/2, r_{n_t - 1}), (1, P_1) with h = 1 / n_t and r_j the
//! row means. Because P_0 = r_0 and P_1 = r_{n_t - 1}, the two half-intervals at the poles add
//! h r_0 / 2 and h r_{n_t - 1} / 2, and with the interior trapezoids the total is h sum_j r_j.
//! Both orders therefore have the same spherical integral,
//!
//!   int L~ d omega = 4 pi mean(c),   so   G = int L~(w) f_iso d omega = mean(c)
//!
//! for the isotropic phase function f_iso = 1 / (4 pi) [PWP08 sec. 4.1: "G evaluates to a simple
//! average"]. The sum of all coefficients and the sums of the two boundary rows are maintained
//! on every write, so g, the polar values and G cost O(1).
//! Book: "SMC: the radiance cache", section "Control variates".

use glam::Vec2;

use super::grid::Grid;
use crate::spectrum::Rgb;

/// RGB coefficients of a cache with the sums that make G and the polar values O(1).
// ANCHOR: coefficients
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Coefficients {
    pub grid: Grid,
    /// c_ij, index j n_s + i.
    c: Vec<Rgb>,
    /// sum of all c_ij (f64 so that O(1) updates do not drift).
    sum: [f64; 3],
    /// sum of row j = 0 (for P_0) and of row j = n_t - 1 (for P_1).
    sum_row_first: [f64; 3],
    sum_row_last: [f64; 3],
}
// ANCHOR_END: coefficients

/// Adds `sign * v` to an f64 RGB accumulator.
#[inline]
fn acc(a: &mut [f64; 3], v: Rgb, sign: f64) {
    for k in 0..3 {
        a[k] += sign * v[k] as f64;
    }
}

#[inline]
fn to_rgb(a: [f64; 3], scale: f64) -> Rgb {
    Rgb::new(
        (a[0] * scale) as f32,
        (a[1] * scale) as f32,
        (a[2] * scale) as f32,
    )
}

impl Coefficients {
    /// The number of coefficients stored.
    pub fn len(&self) -> usize {
        self.c.len()
    }

    /// Whether every coefficient and sum is a finite number (a cache read back from a
    /// checkpoint that passed its checksum may still have been forged).
    pub fn is_finite(&self) -> bool {
        self.c.iter().all(|c| c.is_finite())
            && [self.sum, self.sum_row_first, self.sum_row_last]
                .iter()
                .flatten()
                .all(|x| x.is_finite())
    }

    /// Whether no coefficient is stored.
    pub fn is_empty(&self) -> bool {
        self.c.is_empty()
    }

    /// All coefficients zero.
    pub fn zero(grid: Grid) -> Self {
        Coefficients {
            grid,
            c: vec![Rgb::ZERO; grid.cells()],
            sum: [0.0; 3],
            sum_row_first: [0.0; 3],
            sum_row_last: [0.0; 3],
        }
    }

    /// Coefficients from a list (index j n_s + i); `None` when the length is not N.
    pub fn from_values(grid: Grid, values: Vec<Rgb>) -> Option<Self> {
        if values.len() != grid.cells() {
            return None;
        }
        let mut out = Coefficients::zero(grid);
        for (k, v) in values.into_iter().enumerate() {
            out.set(k, v);
        }
        Some(out)
    }

    /// c of cell `k`.
    #[inline]
    pub fn get(&self, k: usize) -> Rgb {
        self.c[k]
    }

    /// Sets c of cell `k`, keeping the sums (G and the polar values) current: O(1).
    // ANCHOR: set
    #[inline]
    pub fn set(&mut self, k: usize, v: Rgb) {
        let old = self.c[k];
        self.c[k] = v;
        acc(&mut self.sum, old, -1.0);
        acc(&mut self.sum, v, 1.0);
        let row = k / self.grid.n_s as usize;
        if row == 0 {
            acc(&mut self.sum_row_first, old, -1.0);
            acc(&mut self.sum_row_first, v, 1.0);
        }
        if row == self.grid.n_t as usize - 1 {
            acc(&mut self.sum_row_last, old, -1.0);
            acc(&mut self.sum_row_last, v, 1.0);
        }
    }
    // ANCHOR_END: set

    /// The polar value P_0 at t = 0: the mean of row j = 0.
    pub fn polar_first(&self) -> Rgb {
        to_rgb(self.sum_row_first, 1.0 / self.grid.n_s as f64)
    }

    /// The polar value P_1 at t = 1: the mean of row j = n_t - 1.
    pub fn polar_last(&self) -> Rgb {
        to_rgb(self.sum_row_last, 1.0 / self.grid.n_s as f64)
    }

    /// G = int L~(w) / (4 pi) d omega = mean(c), for either order (see the module header).
    // ANCHOR: integral
    #[inline]
    pub fn integral_isotropic(&self) -> Rgb {
        to_rgb(self.sum, 1.0 / self.grid.cells() as f64)
    }
    // ANCHOR_END: integral

    /// Order 0 (piecewise constant) reconstruction L~ at (s, t).
    #[inline]
    pub fn eval_order0(&self, st: Vec2) -> Rgb {
        self.c[self.grid.cell_of(st)]
    }

    /// Order 1 (piecewise linear) reconstruction L~ at (s, t): bilinear between cell centres,
    /// periodic in s, towards the polar values beyond the first and last rows of centres.
    // ANCHOR: eval_order1
    #[inline]
    pub fn eval_order1(&self, st: Vec2) -> Rgb {
        // ASSIGNMENT: bspline_control_variate
        let (n_s, n_t) = (self.grid.n_s as usize, self.grid.n_t as usize);
        // s: centres at (i + 1/2) / n_s, periodic
        let x = st.x * n_s as f32 - 0.5;
        let xf = x.floor();
        let fx = x - xf;
        let i0 = (xf as isize).rem_euclid(n_s as isize) as usize;
        let i1 = (i0 + 1) % n_s;
        let row = |j: usize| self.c[j * n_s + i0] * (1.0 - fx) + self.c[j * n_s + i1] * fx;
        // t: centres at (j + 1/2) / n_t, polar values at t = 0 and t = 1
        let y = st.y * n_t as f32 - 0.5;
        if y <= 0.0 {
            // between P_0 (y = -1/2) and row 0 (y = 0)
            let w = ((y + 0.5) * 2.0).clamp(0.0, 1.0);
            return self.polar_first() * (1.0 - w) + row(0) * w;
        }
        if y >= (n_t - 1) as f32 {
            // between the last row (y = n_t - 1) and P_1 (y = n_t - 1/2)
            let w = ((y - (n_t - 1) as f32) * 2.0).clamp(0.0, 1.0);
            return row(n_t - 1) * (1.0 - w) + self.polar_last() * w;
        }
        let j0 = (y.floor() as usize).min(n_t - 2);
        let fy = y - j0 as f32;
        row(j0) * (1.0 - fy) + row(j0 + 1) * fy
        // END ASSIGNMENT
    }
    // ANCHOR_END: eval_order1

    /// The coefficients after the resolution doubles in both coordinates: every cell's value
    /// is duplicated into its four sub-cells, preserving the data repartition [PWP08 sec. 4.3].
    pub fn refined(&self) -> Self {
        let g2 = self.grid.refined();
        let mut out = Coefficients::zero(g2);
        let n_s = self.grid.n_s as usize;
        for k in 0..g2.cells() {
            let (i, j) = (k % g2.n_s as usize, k / g2.n_s as usize);
            out.set(k, self.c[(j / 2) * n_s + i / 2]);
        }
        out
    }

    /// Bytes of heap storage.
    pub fn heap_bytes(&self) -> usize {
        self.c.capacity() * std::mem::size_of::<Rgb>()
    }
}
