//! A discrete distribution over indices, sampled by inversion of its cumulative sum, and the
//! piecewise-constant density on the unit square built from it (environment maps).
//! Executable spec: `tests/spec/math/warp.rs` (sample frequencies against the pmf, uniformity of the
//! remapped number), `tests/spec/scene/envmap.rs` (the 2-D density against its samples).

use glam::Vec2;

/// Piecewise-constant discrete distribution (light selection, triangle selection on meshes).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Distribution1D {
    /// Normalized cumulative sums, `cdf[0] = 0`, `cdf[n] = 1`.
    cdf: Vec<f32>,
    /// Normalized probabilities.
    pmf: Vec<f32>,
    total: f32,
}

impl Distribution1D {
    /// Builds from non-negative weights; all-zero weights fall back to uniform.
    pub fn new(weights: &[f32]) -> Self {
        let n = weights.len();
        let total: f64 = weights.iter().map(|&w| w.max(0.0) as f64).sum();
        let pmf: Vec<f32> = if total > 0.0 {
            weights
                .iter()
                .map(|&w| (w.max(0.0) as f64 / total) as f32)
                .collect()
        } else {
            vec![1.0 / n.max(1) as f32; n]
        };
        let mut cdf = Vec::with_capacity(n + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0);
        for &p in &pmf {
            acc += p as f64;
            cdf.push(acc as f32);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Distribution1D {
            cdf,
            pmf,
            total: total as f32,
        }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    /// True when there are no entries.
    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// Sum of the weights it was built from.
    pub fn total(&self) -> f32 {
        self.total
    }

    /// Probability of index `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf[i]
    }

    /// Cumulative probability of the indices below `i` (`cdf(len()) = 1`).
    #[inline]
    pub fn cdf(&self, i: usize) -> f32 {
        self.cdf[i]
    }

    /// Samples an index; returns it with its probability and `u` remapped to [0, 1) inside the
    /// chosen bin, so one random number can serve two decisions. Indices of weight zero are
    /// never returned (unless all weights are zero, see [`Distribution1D::new`]).
    ///
    /// # Panics
    /// If the distribution is empty.
    pub fn sample(&self, u: f32) -> (usize, f32, f32) {
        let n = self.pmf.len();
        // first i with cdf[i + 1] > u
        let i = self.cdf[1..].partition_point(|&c| c <= u).min(n - 1);
        let p = self.pmf[i];
        let rem = if p > 0.0 {
            ((u - self.cdf[i]) / p).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        };
        (i, p, rem)
    }
}

/// The largest f32 below 1, so remapped numbers stay in [0, 1).
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// A piecewise-constant density on the unit square over an `nu` x `nv` grid of equal cells:
/// the marginal density of the row times the conditional density within the row (Pharr, Jakob
/// and Humphreys, Physically Based Rendering, 3rd ed., sec. 13.6.7). Cell (i, j) covers
/// [i / nu, (i + 1) / nu) x [j / nv, (j + 1) / nv) and has density
/// p(u, v) = nu nv w_ij / sum w.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    nu: usize,
    nv: usize,
    /// The conditional distribution over the cells of each row.
    rows: Vec<Distribution1D>,
    /// The marginal distribution over rows (weights: the rows' sums).
    marginal: Distribution1D,
}

impl Distribution2D {
    /// Builds from `nu * nv` non-negative weights, row-major (`weights[j * nu + i]`); all-zero
    /// weights give the uniform density.
    ///
    /// # Panics
    /// If `weights.len() != nu * nv` or either side is zero.
    pub fn new(weights: &[f32], nu: usize, nv: usize) -> Self {
        assert!(nu > 0 && nv > 0 && weights.len() == nu * nv);
        let rows: Vec<Distribution1D> = weights.chunks(nu).map(Distribution1D::new).collect();
        let sums: Vec<f32> = rows.iter().map(Distribution1D::total).collect();
        Distribution2D {
            nu,
            nv,
            rows,
            marginal: Distribution1D::new(&sums),
        }
    }

    /// The grid's size (`nu`, `nv`).
    pub fn size(&self) -> (usize, usize) {
        (self.nu, self.nv)
    }

    /// The cell containing `p` (coordinates clamped into the square).
    #[inline]
    pub fn cell(&self, p: Vec2) -> (usize, usize) {
        let index = |x: f32, n: usize| ((x.max(0.0) * n as f32) as usize).min(n - 1);
        (index(p.x, self.nu), index(p.y, self.nv))
    }

    /// The density of cell (i, j) with respect to area on the unit square.
    #[inline]
    pub fn cell_pdf(&self, i: usize, j: usize) -> f32 {
        self.marginal.pmf(j) * self.rows[j].pmf(i) * (self.nu * self.nv) as f32
    }

    /// The density at `p` with respect to area on the unit square.
    #[inline]
    pub fn pdf(&self, p: Vec2) -> f32 {
        let (i, j) = self.cell(p);
        self.cell_pdf(i, j)
    }

    /// Samples a point: the row by the marginal from `u.y`, the cell within it from `u.x`, the
    /// point uniform in the cell from the remapped numbers. Returns the point, its cell and its
    /// density; the point always lies in the returned cell ([`Distribution2D::cell`]).
    pub fn sample(&self, u: Vec2) -> (Vec2, (usize, usize), f32) {
        let (j, _, rv) = self.marginal.sample(u.y);
        let (i, _, ru) = self.rows[j].sample(u.x);
        let p = Vec2::new(inside_cell(i, ru, self.nu), inside_cell(j, rv, self.nv));
        (p, (i, j), self.cell_pdf(i, j))
    }
}

/// (i + r) / n, moved by ulps where rounding carried it out of cell i (for large i, i + r
/// rounds up to i + 1 in f32 when r is close to 1).
fn inside_cell(i: usize, r: f32, n: usize) -> f32 {
    let mut x = (i as f32 + r) / n as f32;
    while x > 0.0 && (x * n as f32) as usize > i {
        x = x.next_down();
    }
    while ((x * n as f32) as usize) < i {
        x = x.next_up();
    }
    x
}
