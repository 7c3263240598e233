//! The directional cell grid of a radiance cache (Pegoraro, Wald, Parker 2008, sec. 4.1):
//! the sphere is partitioned regularly in the normalized spherical coordinates
//!
//!   s = phi / (2 pi),   t = (1 - cos theta) / 2,
//!
//! whose Jacobian is constant (d omega = d phi d(cos theta) = 4 pi ds dt), so every cell of an
//! n_s x n_t grid subtends the same solid angle 4 pi / (n_s n_t).
//!
//! The polar axis is world +y, the axis of the scene format's gradient environments
//! (`zenith` at +y), so rows of constant t are rows of constant environment radiance.
//! Book: "SMC: the radiance cache", section "The directional grid".

use glam::{Vec2, Vec3};
use std::f32::consts::{PI, TAU};

/// Cells in s of the root cache: "a radiance cache with only two cells (in s)" [PWP08 sec. 4.3].
pub const ROOT_CELLS_S: u32 = 2;
/// Cells in t of the root cache.
pub const ROOT_CELLS_T: u32 = 1;

/// A regular n_s x n_t partition of the (s, t) unit square; cell (i, j) has index j n_s + i.
// ANCHOR: grid
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    /// Cells along s (azimuth), periodic.
    pub n_s: u32,
    /// Cells along t (polar).
    pub n_t: u32,
}

impl Grid {
    /// The root cache's grid: two cells in s, one in t.
    pub const ROOT: Grid = Grid {
        n_s: ROOT_CELLS_S,
        n_t: ROOT_CELLS_T,
    };

    /// The grid after one refinement: the resolution doubles in both coordinates
    /// [PWP08 sec. 4.3].
    pub fn refined(self) -> Grid {
        Grid {
            n_s: 2 * self.n_s,
            n_t: 2 * self.n_t,
        }
    }

    /// N = n_s n_t.
    pub fn cells(self) -> usize {
        self.n_s as usize * self.n_t as usize
    }

    /// The solid angle of every cell, 4 pi / N.
    pub fn cell_solid_angle(self) -> f32 {
        4.0 * PI / self.cells() as f32
    }

    /// (s, t) in [0, 1)^2 of a unit direction (pole +y).
    #[inline]
    pub fn st(w: Vec3) -> Vec2 {
        let mut phi = w.z.atan2(w.x);
        if phi < 0.0 {
            phi += TAU;
        }
        let s = (phi / TAU).clamp(0.0, 1.0);
        let t = (0.5 * (1.0 - w.y)).clamp(0.0, 1.0);
        Vec2::new(if s >= 1.0 { 0.0 } else { s }, t)
    }

    /// The unit direction of (s, t); the inverse of [`Grid::st`].
    #[inline]
    pub fn direction(st: Vec2) -> Vec3 {
        let cos_theta = (1.0 - 2.0 * st.y).clamp(-1.0, 1.0);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = TAU * st.x;
        Vec3::new(sin_theta * phi.cos(), cos_theta, sin_theta * phi.sin())
    }

    /// The index of the cell containing (s, t).
    #[inline]
    pub fn cell_of(self, st: Vec2) -> usize {
        let i = ((st.x * self.n_s as f32) as u32).min(self.n_s - 1);
        let j = ((st.y * self.n_t as f32) as u32).min(self.n_t - 1);
        (j * self.n_s + i) as usize
    }

    /// The cell containing direction `w`.
    #[inline]
    pub fn cell_of_direction(self, w: Vec3) -> usize {
        self.cell_of(Grid::st(w))
    }

    /// A direction uniform in solid angle inside `cell`: (s, t) uniform in the cell's
    /// rectangle, which the constant Jacobian maps to uniform solid angle (the "linear CDF"
    /// inside a cell of an order-0 pdf).
    #[inline]
    pub fn sample_in_cell(self, cell: usize, u: Vec2) -> Vec3 {
        let i = (cell % self.n_s as usize) as f32;
        let j = (cell / self.n_s as usize) as f32;
        let s = (i + u.x) / self.n_s as f32;
        let t = (j + u.y) / self.n_t as f32;
        Grid::direction(Vec2::new(s, t))
    }
}
// ANCHOR_END: grid
