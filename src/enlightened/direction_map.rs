//! Equal-solid-angle direction maps (Kristensen 2010, sec. 5.2.4): the directional part of the
//! piecewise-constant estimates of incident radiance L_i and incident importance W_i kept per
//! region.
//!
//! A map has `rows` x `cols` texels; rows are uniform in cos(theta) (theta measured from the
//! world +z axis), columns uniform in phi, so every texel subtends the same solid angle
//! 4 pi / n (the cylindrical equal-area projection, by Archimedes' hat-box theorem). Particle
//! weights are added to the texel of their incident direction; sampling picks a row from the
//! marginal cumulative sums, a column from the row's conditional sums, then a uniform point of
//! the texel in (cos theta, phi). The density is
//!   p(w) = p_row p_col n / (4 pi)                  [Kristensen 2010, sec. 5.2.4]
//! and is computed from the same cumulative sums the sampler inverts, so sampled and evaluated
//! densities agree to the last bit of the table.
//! Book: "Enlightened local path sampling: guiding".

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::warp::INV_FOUR_PI;

/// The thesis's resolution: 32 columns (phi) by 16 rows (cos theta).
pub const DEFAULT_COLS: u32 = 32;
/// See [`DEFAULT_COLS`].
pub const DEFAULT_ROWS: u32 = 16;

/// An accumulated equal-area map with its sampling tables.
// ANCHOR: direction_map
#[derive(Clone, Debug)]
pub struct DirectionMap {
    cols: u32,
    rows: u32,
    /// Accumulated weight per texel, row-major (row = cos theta band, column = phi sector).
    weight: Vec<f32>,
    /// Marginal cumulative sums over rows, `rows + 1` entries from 0 to 1 (empty until built).
    row_cdf: Vec<f32>,
    /// Conditional cumulative sums of each row, `cols + 1` entries per row.
    col_cdf: Vec<f32>,
    /// Sum of all weights.
    total: f64,
}
// ANCHOR_END: direction_map

impl DirectionMap {
    /// An empty map of `cols` x `rows` texels (each at least 1).
    pub fn new(cols: u32, rows: u32) -> Self {
        let (cols, rows) = (cols.max(1), rows.max(1));
        DirectionMap {
            cols,
            rows,
            weight: vec![0.0; (cols * rows) as usize],
            row_cdf: Vec::new(),
            col_cdf: Vec::new(),
            total: 0.0,
        }
    }

    /// Number of texels n.
    pub fn len(&self) -> usize {
        self.weight.len()
    }

    /// True when no texel has weight (the map cannot be sampled).
    pub fn is_empty(&self) -> bool {
        self.total <= 0.0 || self.row_cdf.is_empty()
    }

    pub fn cols(&self) -> u32 {
        self.cols
    }

    pub fn rows(&self) -> u32 {
        self.rows
    }

    /// Sum of the accumulated weights.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Bytes held by the map (weights and tables).
    pub fn bytes(&self) -> usize {
        (self.weight.len() + self.row_cdf.len() + self.col_cdf.len()) * std::mem::size_of::<f32>()
            + std::mem::size_of::<Self>()
    }

    /// The texel (column, row) of unit direction `w`.
    // ANCHOR: texel_of
    #[inline]
    pub fn texel_of(&self, w: Vec3) -> (u32, u32) {
        // ASSIGNMENT: equal_area_texel
        let u = ((w.z.clamp(-1.0, 1.0) + 1.0) * 0.5).min(ONE_MINUS_EPSILON);
        let mut phi = w.y.atan2(w.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let v = (phi * (0.5 / PI)).clamp(0.0, ONE_MINUS_EPSILON);
        let col = ((v * self.cols as f32) as u32).min(self.cols - 1);
        let row = ((u * self.rows as f32) as u32).min(self.rows - 1);
        (col, row)
        // END ASSIGNMENT
    }
    // ANCHOR_END: texel_of

    /// The direction at map coordinates `uv` in [0, 1)^2 (u along phi, v along cos theta).
    #[inline]
    pub fn direction_at(uv: Vec2) -> Vec3 {
        let z = 2.0 * uv.y - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * uv.x;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Adds `weight` to the texel of direction `w` (tables must be rebuilt by [`Self::build`]).
    pub fn splat(&mut self, w: Vec3, weight: f32) {
        if !(weight > 0.0 && weight.is_finite() && w.is_finite()) {
            return;
        }
        let (c, r) = self.texel_of(w);
        self.weight[(r * self.cols + c) as usize] += weight;
    }

    /// The accumulated weight of texel (col, row).
    pub fn weight(&self, col: u32, row: u32) -> f32 {
        self.weight[(row * self.cols + col) as usize]
    }

    /// Builds the marginal and conditional cumulative sums from the accumulated weights.
    // ANCHOR: build_cdf
    pub fn build(&mut self) {
        let (cols, rows) = (self.cols as usize, self.rows as usize);
        let mut row_sum = vec![0.0f64; rows];
        self.col_cdf = vec![0.0; rows * (cols + 1)];
        for (r, rs) in row_sum.iter_mut().enumerate() {
            let texels = &self.weight[r * cols..(r + 1) * cols];
            let s: f64 = texels.iter().map(|&w| w as f64).sum();
            *rs = s;
            let cdf = &mut self.col_cdf[r * (cols + 1)..(r + 1) * (cols + 1)];
            let mut acc = 0.0f64;
            for (c, &w) in texels.iter().enumerate() {
                acc += w as f64;
                cdf[c + 1] = if s > 0.0 { (acc / s) as f32 } else { 0.0 };
            }
            if s > 0.0 {
                cdf[cols] = 1.0;
            }
        }
        self.total = row_sum.iter().sum();
        if self.total <= 0.0 {
            self.row_cdf.clear();
            return;
        }
        self.row_cdf = vec![0.0; rows + 1];
        let mut acc = 0.0f64;
        for (r, &s) in row_sum.iter().enumerate() {
            acc += s;
            self.row_cdf[r + 1] = (acc / self.total) as f32;
        }
        self.row_cdf[rows] = 1.0;
    }
    // ANCHOR_END: build_cdf

    /// Picks the bin i of `cdf` with cdf[i] <= u < cdf[i + 1] (zero-width bins never), and
    /// returns it with u remapped to [0, 1) inside it.
    #[inline]
    fn invert(cdf: &[f32], u: f32) -> (usize, f32) {
        let n = cdf.len() - 1;
        let i = cdf[1..].partition_point(|&c| c <= u).min(n - 1);
        let width = cdf[i + 1] - cdf[i];
        let rem = if width > 0.0 {
            ((u - cdf[i]) / width).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        };
        (i, rem)
    }

    /// Samples a direction; `None` for an empty map. Returns the direction and its density.
    // ANCHOR: map_sample
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        if self.is_empty() {
            return None;
        }
        let cols = self.cols as usize;
        let (r, v_in) = Self::invert(&self.row_cdf, u.y);
        let (c, u_in) = Self::invert(&self.col_cdf[r * (cols + 1)..(r + 1) * (cols + 1)], u.x);
        let uv = Vec2::new(
            (c as f32 + u_in) / self.cols as f32,
            (r as f32 + v_in) / self.rows as f32,
        );
        let w = Self::direction_at(uv);
        // the density of the texel chosen (not of texel_of(w): they agree except on texel
        // borders, where rounding may put w into a neighbour)
        let pdf = self.texel_pdf(c, r);
        (pdf > 0.0).then_some((w, pdf))
    }
    // ANCHOR_END: map_sample

    /// p(w) = p_row p_col n / (4 pi) [Kristensen 2010, sec. 5.2.4]; zero for an empty map.
    // ANCHOR: map_pdf
    #[inline]
    pub fn pdf(&self, w: Vec3) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let (c, r) = self.texel_of(w);
        self.texel_pdf(c as usize, r as usize)
    }

    #[inline]
    fn texel_pdf(&self, c: usize, r: usize) -> f32 {
        let cols = self.cols as usize;
        let p_row = self.row_cdf[r + 1] - self.row_cdf[r];
        let cdf = &self.col_cdf[r * (cols + 1)..];
        let p_col = cdf[c + 1] - cdf[c];
        p_row * p_col * self.len() as f32 * INV_FOUR_PI
    }
    // ANCHOR_END: map_pdf

    /// The mean weight per steradian in direction w relative to the map's mean over the sphere,
    /// i.e. 4 pi p(w): 1 for a uniform map (the shape of L_i or W_i, without its scale).
    #[inline]
    pub fn relative(&self, w: Vec3) -> f32 {
        self.pdf(w) * 4.0 * PI
    }
}
