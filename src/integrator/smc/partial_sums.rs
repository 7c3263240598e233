//! The tree of partial sums that samples the order-0 pdf of a radiance cache in O(log N)
//! (Pegoraro, Wald, Parker 2008, sec. 4.2, after Veach 1997).
//!
//! A complete binary tree over the N cells (N a power of two), stored in a flat array of size
//! 2N - 1: node k has children 2k + 1 and 2k + 2, the leaves N - 1 .. 2N - 2 hold the cells'
//! pdf coefficients and every inner node the sum of its two children, so the root holds the
//! sum of all coefficients. A write updates the log2(2N) nodes of one branch; sampling scales
//! a random number by the root and walks down: "if the random quantity is greater than the
//! value of the first child, its value is subtracted and the second child becomes the current
//! node, the first child otherwise".
//! Book: "SMC: the radiance cache", section "Importance sampling".

/// Why a tree of partial sums could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PartialSumsError {
    #[error("a tree of partial sums needs a power-of-two number of cells, got {0}")]
    NotPowerOfTwo(usize),
    #[error("cell {index} has value {value}: pdf coefficients must be finite and >= 0")]
    BadValue { index: usize, value: f64 },
}

/// A complete binary tree of partial sums in a flat array of 2N - 1 nodes.
// ANCHOR: tree
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct PartialSums {
    /// Number of leaves (cells).
    n: usize,
    nodes: Vec<f64>,
}

impl PartialSums {
    /// The tree over `values` (one per cell).
    pub fn new(values: &[f64]) -> Result<Self, PartialSumsError> {
        let n = values.len();
        if n == 0 || !n.is_power_of_two() {
            return Err(PartialSumsError::NotPowerOfTwo(n));
        }
        if let Some((index, &value)) = values
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
        {
            return Err(PartialSumsError::BadValue { index, value });
        }
        let mut nodes = vec![0.0; 2 * n - 1];
        nodes[n - 1..].copy_from_slice(values);
        for k in (0..n - 1).rev() {
            nodes[k] = nodes[2 * k + 1] + nodes[2 * k + 2];
        }
        Ok(PartialSums { n, nodes })
    }

    /// Sets cell `i` and updates its branch up to the root: O(log N).
    #[inline]
    pub fn set(&mut self, i: usize, value: f64) {
        // ASSIGNMENT: partial_sums
        let mut k = self.n - 1 + i;
        self.nodes[k] = value;
        while k > 0 {
            k = (k - 1) / 2;
            self.nodes[k] = self.nodes[2 * k + 1] + self.nodes[2 * k + 2];
        }
        // END ASSIGNMENT
    }

    /// Samples a cell with probability value / total from `u` in [0, 1): O(log N).
    /// Returns the cell and its probability. The total must be positive.
    #[inline]
    pub fn sample(&self, u: f64) -> (usize, f64) {
        // ASSIGNMENT: partial_sums
        let mut x = u * self.nodes[0];
        let mut k = 0;
        while k < self.n - 1 {
            let (left, right) = (2 * k + 1, 2 * k + 2);
            // the guards keep rounding from ever selecting a zero-valued branch
            if (x >= self.nodes[left] && self.nodes[right] > 0.0) || self.nodes[left] <= 0.0 {
                x -= self.nodes[left];
                k = right;
            } else {
                k = left;
            }
        }
        let i = k - (self.n - 1);
        (i, self.nodes[k] / self.nodes[0])
        // END ASSIGNMENT
    }
}
// ANCHOR_END: tree

impl PartialSums {
    /// The sum of all values (the root).
    #[inline]
    pub fn total(&self) -> f64 {
        self.nodes[0]
    }

    /// The value of cell `i`.
    #[inline]
    pub fn value(&self, i: usize) -> f64 {
        self.nodes[self.n - 1 + i]
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether every partial sum is finite and non-negative, as sums of pdf values are.
    pub fn is_finite(&self) -> bool {
        self.nodes.iter().all(|x| x.is_finite() && *x >= 0.0)
    }

    /// Always false: a tree has at least one cell.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The whole flat array (root first), for tests of the invariant.
    pub fn nodes(&self) -> &[f64] {
        &self.nodes
    }

    /// Bytes of heap storage.
    pub fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<f64>()
    }
}
