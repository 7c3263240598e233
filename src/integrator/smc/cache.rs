//! A radiance cache: one leaf's directional grid holding both predicates of the combined
//! estimator (Pegoraro, Wald, Parker 2008, sec. 4.1-4.3):
//!
//! - g: the B-spline coefficients of the incoming radiance ([`Coefficients`]), times the
//!   isotropic phase function 1 / (4 pi), and its integral G;
//! - p: an order-0 pdf whose cell coefficient is the running mean of |f - g| (averaged over the
//!   colour channels), sampled through a [`PartialSums`] tree, then uniformly inside the cell;
//! - C: a record counter per cell. A record is merged with weights 1 / (C + 1) (new) and
//!   C / (C + 1) (old), then C increments. The sum of the counters is kept so that the
//!   refinement criterion (their average) is O(1).
//!
//! Refinement doubles the grid in both coordinates (every cell copied into its four sub-cells)
//! and divides the counters by 32, the dimensionality of the split (2^3 spatial children times
//! 2^2 directional sub-cells), never rounding a non-zero counter down to zero: a record then
//! merges with the inherited value instead of overwriting it, which keeps every pdf coefficient
//! that was positive positive [PWP08 sec. 4.3, "inheritance"].
//! Book: "SMC: the radiance cache", sections "Importance sampling" and "The octree".

use glam::{Vec2, Vec3};

use super::bspline::Coefficients;
use super::estimator::ControlVariate;
use super::grid::Grid;
use super::partial_sums::PartialSums;
use crate::math::warp;
use crate::spectrum::{self, Rgb};

/// The dimensionality of a split: 3 spatial and 2 directional coordinates are halved, so a
/// cell's records are spread over 2^5 = 32 cells [PWP08 sec. 4.3].
pub const SPLIT_DIMENSIONALITY: u32 = 32;

/// One leaf's radiance cache.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RadianceCache {
    /// The radiance coefficients (predicate g).
    pub coefficients: Coefficients,
    /// The order-0 pdf coefficients (predicate p), as a tree of partial sums.
    pdf: PartialSums,
    /// C per cell.
    counts: Vec<u32>,
    /// sum of C over the cells.
    count_sum: u64,
    /// Cells whose pdf coefficient is zero.
    zero_pdf_cells: usize,
}

impl RadianceCache {
    /// The root's cache: two cells in s, coefficients, pdf values and counters zero.
    pub fn root() -> Self {
        let grid = Grid::ROOT;
        RadianceCache {
            coefficients: Coefficients::zero(grid),
            pdf: PartialSums::new(&vec![0.0; grid.cells()])
                .expect("the root grid has a power-of-two number of cells"),
            counts: vec![0; grid.cells()],
            count_sum: 0,
            zero_pdf_cells: grid.cells(),
        }
    }

    /// Whether the arrays agree with the grid and hold finite numbers (a cache read back from
    /// a checkpoint).
    pub fn is_consistent(&self) -> bool {
        let cells = self.coefficients.grid.cells();
        self.counts.len() == cells
            && self.pdf.len() == cells
            && self.coefficients.len() == cells
            && self.coefficients.is_finite()
            && self.pdf.is_finite()
    }

    pub fn grid(&self) -> Grid {
        self.coefficients.grid
    }

    /// L~(wi): the cached radiance reconstruction of the given order (zero for `cv0`).
    #[inline]
    pub fn radiance(&self, wi: Vec3, cv: ControlVariate) -> Rgb {
        match cv {
            ControlVariate::None => Rgb::ZERO,
            ControlVariate::Order0 => self.coefficients.eval_order0(Grid::st(wi)),
            ControlVariate::Order1 => self.coefficients.eval_order1(Grid::st(wi)),
        }
    }

    /// g(wi) = L~(wi) f_iso: the control variate "weighted by an isotropic phase function"
    /// [PWP08 sec. 4.5, Fig. 2 lines 7-8].
    #[inline]
    pub fn g(&self, wi: Vec3, cv: ControlVariate) -> Rgb {
        self.radiance(wi, cv) * warp::INV_FOUR_PI
    }

    /// G = int g d omega = mean of the coefficients [PWP08 Fig. 2 line 6].
    #[inline]
    pub fn integral(&self, cv: ControlVariate) -> Rgb {
        match cv {
            ControlVariate::None => Rgb::ZERO,
            _ => self.coefficients.integral_isotropic(),
        }
    }

    /// True when every cell's pdf coefficient is positive: only then is the cache's pdf used
    /// (before, "the PDF is not relevant at this stage, a uniform directional sampling strategy
    /// is used" [PWP08 sec. 4.3]).
    #[inline]
    pub fn pdf_is_positive(&self) -> bool {
        self.zero_pdf_cells == 0
    }

    /// The pdf coefficient of a cell (the running mean of |f - g|).
    #[inline]
    pub fn pdf_coefficient(&self, cell: usize) -> f64 {
        self.pdf.value(cell)
    }

    /// The mean pdf coefficient, root / N: the integral of the coefficients over the sphere
    /// in the normalized measure ds dt [PWP08 sec. 4.5].
    #[inline]
    pub fn pdf_coefficient_mean(&self) -> f64 {
        self.pdf.total() / self.grid().cells() as f64
    }

    /// The solid-angle density of `wi` under the order-0 pdf: coefficient / (total * cell
    /// solid angle). Only meaningful when [`RadianceCache::pdf_is_positive`].
    #[inline]
    pub fn pdf(&self, wi: Vec3) -> f32 {
        let grid = self.grid();
        let cell = grid.cell_of_direction(wi);
        (self.pdf.value(cell) / self.pdf.total()) as f32 / grid.cell_solid_angle()
    }

    /// Samples a direction from the order-0 pdf: a cell through the partial sums (O(log N)),
    /// then uniformly inside it. Returns (wi, solid-angle density).
    // ANCHOR: sample
    #[inline]
    pub fn sample(&self, u_cell: f64, u_dir: Vec2) -> (Vec3, f32) {
        let grid = self.grid();
        let (cell, probability) = self.pdf.sample(u_cell);
        let wi = grid.sample_in_cell(cell, u_dir);
        (wi, probability as f32 / grid.cell_solid_angle())
    }
    // ANCHOR_END: sample

    /// The average record count, compared against the refinement threshold [PWP08 sec. 4.4].
    #[inline]
    pub fn average_count(&self) -> f64 {
        self.count_sum as f64 / self.grid().cells() as f64
    }

    /// C of a cell.
    pub fn count(&self, cell: usize) -> u32 {
        self.counts[cell]
    }

    /// Merges one record: the radiance L arriving from `wi`, with the phase value f_p that
    /// turned it into f = f_p L. The radiance coefficient and the pdf coefficient (the mean of
    /// |f - g| over channels, g from this cache before the write) become running averages with
    /// weights C / (C + 1) and 1 / (C + 1) [PWP08 sec. 4.1, 4.2].
    // ANCHOR: write
    pub fn write(&mut self, wi: Vec3, radiance: Rgb, phase_value: f32, cv: ControlVariate) {
        // radiance is never negative; a negative record is an excursion of the combined
        // estimator (G + (f - g) / p dips below zero where g exceeds f), and writing it would
        // feed the next estimates a negative g (see `RadianceCache` on why the cache may be
        // any function: it shapes the estimator's variance, never its mean)
        let radiance = radiance.max(Rgb::ZERO);
        let cell = self.grid().cell_of_direction(wi);
        let g = self.g(wi, cv);
        let pdf_sample = spectrum::average((radiance * phase_value - g).abs()) as f64;
        let c = self.counts[cell];
        let (w_old, w_new) = (c as f64 / (c as f64 + 1.0), 1.0 / (c as f64 + 1.0));
        let old = self.coefficients.get(cell);
        let blended = old * w_old as f32 + radiance * w_new as f32;
        self.coefficients.set(cell, blended);
        let old_pdf = self.pdf.value(cell);
        let new_pdf = old_pdf * w_old + pdf_sample * w_new;
        self.pdf.set(cell, new_pdf);
        if old_pdf <= 0.0 && new_pdf > 0.0 {
            self.zero_pdf_cells -= 1;
        } else if old_pdf > 0.0 && new_pdf <= 0.0 {
            self.zero_pdf_cells += 1;
        }
        self.counts[cell] = c.saturating_add(1);
        self.count_sum += 1;
    }
    // ANCHOR_END: write

    /// The cache a child receives when its node splits: the grid doubled in both coordinates,
    /// every cell's coefficient, pdf value and counter copied into its four sub-cells, the
    /// counters divided by [`SPLIT_DIMENSIONALITY`] but never rounded down to zero.
    // ANCHOR: refined
    pub fn refined(&self) -> Self {
        let grid = self.grid();
        let fine = grid.refined();
        let coefficients = self.coefficients.refined();
        let parent = |k: usize| {
            let (i, j) = (k % fine.n_s as usize, k / fine.n_s as usize);
            (j / 2) * grid.n_s as usize + i / 2
        };
        let values: Vec<f64> = (0..fine.cells())
            .map(|k| self.pdf.value(parent(k)))
            .collect();
        let counts: Vec<u32> = (0..fine.cells())
            .map(|k| match self.counts[parent(k)] {
                0 => 0,
                c => (c / SPLIT_DIMENSIONALITY).max(1),
            })
            .collect();
        RadianceCache {
            coefficients,
            zero_pdf_cells: values.iter().filter(|v| **v <= 0.0).count(),
            pdf: PartialSums::new(&values)
                .expect("a refined grid has a power-of-two number of cells"),
            count_sum: counts.iter().map(|&c| c as u64).sum(),
            counts,
        }
    }
    // ANCHOR_END: refined

    /// Bytes of heap storage plus the struct itself.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.coefficients.heap_bytes()
            + self.pdf.heap_bytes()
            + self.counts.capacity() * std::mem::size_of::<u32>()
    }

    /// Bytes a cache with `cells` cells occupies (for the memory budget, before building it).
    pub fn bytes_for(cells: usize) -> usize {
        std::mem::size_of::<Self>()
            + cells * std::mem::size_of::<Rgb>()
            + (2 * cells - 1) * std::mem::size_of::<f64>()
            + cells * std::mem::size_of::<u32>()
    }
}
