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

/// A piecewise-bilinear density on the unit square: the bilinear interpolation of values on the
/// `(nu + 1) x (nv + 1)` vertices of an `nu` x `nv` grid of equal cells, normalized, sampled
/// exactly as the marginal density in v (piecewise linear) times the conditional density in u
/// at that v (piecewise linear too), each inverted in closed form (Mitsuba 3's `Marginal2D`
/// without parameters does the same; Heitz, *Can't invert the CDF? The triangle-cut parameterization*,
/// and Pharr, Jakob and Humphreys, *Physically Based Rendering*, 4th ed., sec. A.4.2, for the
/// linear inversion). Environment maps interpolated bilinearly.
#[derive(Clone, Debug, PartialEq)]
pub struct Bilinear2D {
    nu: usize,
    nv: usize,
    /// Vertex values divided by their integral over the square, row-major (`(nu + 1)` a row).
    values: Vec<f32>,
    /// Per vertex row: the integral of the row's piecewise-linear function over the cells left
    /// of each vertex, times `nu` (`nu + 1` a row, the first 0).
    row_cdf: Vec<f64>,
    /// The marginal's cumulative integral over the vertex-row cells below each vertex row,
    /// times `nu nv` (`nv + 1` entries, the first 0).
    marginal_cdf: Vec<f64>,
}

impl Bilinear2D {
    /// Builds from `(nu + 1) * (nv + 1)` finite non-negative vertex values, row-major; all-zero
    /// values give the uniform density.
    ///
    /// # Panics
    /// If the count is wrong or either side is zero.
    pub fn new(values: &[f32], nu: usize, nv: usize) -> Self {
        assert!(nu > 0 && nv > 0 && values.len() == (nu + 1) * (nv + 1));
        let total: f64 = Self::cells(values, nu, nv).sum::<f64>() / (nu * nv) as f64;
        let values: Vec<f32> = if total > 0.0 {
            values
                .iter()
                .map(|&v| (v.max(0.0) as f64 / total) as f32)
                .collect()
        } else {
            vec![1.0; values.len()]
        };
        let mut row_cdf = Vec::with_capacity(values.len());
        for row in values.chunks(nu + 1) {
            let mut acc = 0.0f64;
            row_cdf.push(0.0);
            for i in 0..nu {
                acc += 0.5 * (row[i] as f64 + row[i + 1] as f64);
                row_cdf.push(acc);
            }
        }
        let mut marginal_cdf = vec![0.0f64];
        for j in 0..nv {
            let sum = row_cdf[j * (nu + 1) + nu] + row_cdf[(j + 1) * (nu + 1) + nu];
            marginal_cdf.push(marginal_cdf[j] + 0.5 * sum);
        }
        Bilinear2D {
            nu,
            nv,
            values,
            row_cdf,
            marginal_cdf,
        }
    }

    /// The cells' sums of their four vertex values over 4 (their integrals times `nu nv`).
    fn cells(values: &[f32], nu: usize, nv: usize) -> impl Iterator<Item = f64> + '_ {
        let at = move |i: usize, j: usize| values[j * (nu + 1) + i].max(0.0) as f64;
        (0..nv).flat_map(move |j| {
            (0..nu).map(move |i| 0.25 * (at(i, j) + at(i + 1, j) + at(i, j + 1) + at(i + 1, j + 1)))
        })
    }

    /// The grid's size in cells (`nu`, `nv`).
    pub fn size(&self) -> (usize, usize) {
        (self.nu, self.nv)
    }

    /// The normalized value at vertex (i, j).
    #[inline]
    fn value(&self, i: usize, j: usize) -> f32 {
        self.values[j * (self.nu + 1) + i]
    }

    /// The density at `p` with respect to area on the unit square (coordinates clamped into it,
    /// NaN to 0).
    #[inline]
    pub fn pdf(&self, p: Vec2) -> f32 {
        let (i, fu) = split(p.x, self.nu);
        let (j, fv) = split(p.y, self.nv);
        let lerp = |a: f32, b: f32, t: f32| (1.0 - t) * a + t * b;
        let low = lerp(self.value(i, j), self.value(i + 1, j), fu);
        let high = lerp(self.value(i, j + 1), self.value(i + 1, j + 1), fu);
        lerp(low, high, fv)
    }

    /// Samples a point: v by the marginal from `u.y`, u by the conditional at that v from
    /// `u.x`. Returns the point and its density ([`Bilinear2D::pdf`] at the point).
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let nu1 = self.nu + 1;
        // the marginal: a vertex-row cell by its integral, then v within it
        let m = &self.marginal_cdf;
        let target = u.y as f64 * m[self.nv];
        let j = (m[1..].partition_point(|&c| c <= target)).min(self.nv - 1);
        let (a, b) = (
            self.row_cdf[j * nu1 + self.nu],
            self.row_cdf[(j + 1) * nu1 + self.nu],
        );
        let r = remap(target - m[j], m[j + 1] - m[j]);
        let tv = sample_linear(a as f32, b as f32, r);
        // the conditional at v: the rows' cumulative integrals interpolated
        let t = tv as f64;
        let cdf =
            |i: usize| (1.0 - t) * self.row_cdf[j * nu1 + i] + t * self.row_cdf[(j + 1) * nu1 + i];
        let target = u.x as f64 * cdf(self.nu);
        let (mut lo, mut hi) = (0, self.nu - 1);
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if cdf(mid) <= target {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        let i = lo;
        let at = |i: usize| (1.0 - tv) * self.value(i, j) + tv * self.value(i, j + 1);
        let r = remap(target - cdf(i), cdf(i + 1) - cdf(i));
        let tu = sample_linear(at(i), at(i + 1), r);
        let p = Vec2::new(
            ((i as f32 + tu) / self.nu as f32).min(1.0),
            ((j as f32 + tv) / self.nv as f32).min(1.0),
        );
        (p, self.pdf(p))
    }
}

/// The cell of coordinate `x` on a grid of `n` cells over [0, 1] and the fraction within it
/// (`x` clamped, NaN to 0; 1 lies at the end of the last cell).
#[inline]
fn split(x: f32, n: usize) -> (usize, f32) {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } * n as f32;
    let i = (x as usize).min(n - 1);
    (i, (x - i as f32).clamp(0.0, 1.0))
}

/// `part / whole` in [0, 1) (0 for an empty whole).
#[inline]
fn remap(part: f64, whole: f64) -> f32 {
    if whole > 0.0 {
        ((part / whole) as f32).clamp(0.0, ONE_MINUS_EPSILON)
    } else {
        0.0
    }
}

/// The t in [0, 1] where the density proportional to (1 - t) a + t b on [0, 1] has cumulative
/// probability `r`: the root of (b - a) t^2 / 2 + a t = r (a + b) / 2, in the form without
/// cancellation, t = r (a + b) / (a + sqrt((1 - r) a^2 + r b^2)).
#[inline]
pub fn sample_linear(a: f32, b: f32, r: f32) -> f32 {
    if a + b <= 0.0 {
        return r;
    }
    let t = r * (a + b) / (a + ((1.0 - r) * a * a + r * b * b).sqrt());
    if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        r
    }
}
