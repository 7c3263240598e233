//! A discrete distribution over indices, sampled by inversion of its cumulative sum.
//! Executable spec: `tests/warp.rs` (sample frequencies against the pmf, uniformity of the
//! remapped number).

/// Piecewise-constant discrete distribution (light selection, triangle selection on meshes).
#[derive(Clone, Debug, Default)]
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
