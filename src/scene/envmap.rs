//! The image-based environment light: radiance arriving from infinitely far, looked up in a
//! latitude-longitude map, and sampled in proportion to its luminance.
//!
//! The mapping is Mitsuba 3's (`src/emitters/envmap.cpp`), so a Mitsuba `envmap` emitter with
//! its `to_world` is this light: the map point (u, v) in [0, 1)^2 is the local direction
//!
//!   d(u, v) = (sin phi sin theta, cos theta, -cos phi sin theta),  phi = 2 pi u, theta = pi v,
//!
//! (+y up: the top row is the zenith), and the world direction towards the light is
//! `to_world * d`. Column x of a W-wide image is centred on u = (x + 1/2) / W; row y of an
//! H-high image is centred on theta = pi y / (H - 1), poles included, as Mitsuba places its
//! texels. pathspace takes the nearest texel (Mitsuba interpolates bilinearly), so the radiance
//! is exactly piecewise constant: on the W x 2 (H - 1) grid of half rows in v, half row k shows
//! texel row (k + 1) / 2 (rows 0 and H - 1 cover half a row each, at the poles).
//!
//! Sampling: the half-row grid carries a [`Distribution2D`] with the weight of each cell its
//! luminance times its solid angle, so a cell is drawn with the probability of its share of the
//! luminance, and the point uniformly in (u, v) within it. With d omega = 2 pi^2 sin theta du dv,
//! the solid-angle density is p(u, v) / (2 pi^2 sin theta) (Pharr, Jakob and Humphreys,
//! Physically Based Rendering, 3rd ed., eq. 14.18). Book: "Environment maps".

use glam::{Mat3, Vec2, Vec3};
use std::f32::consts::PI;

use crate::math::{warp, Distribution2D};
use crate::spectrum::{luminance, Rgb};

/// A latitude-longitude environment map (texels already multiplied by the light's `scale`).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    width: usize,
    height: usize,
    /// Row-major, top row (theta = 0) first.
    texels: Vec<Rgb>,
    /// Local (map) frame to world: an orthogonal matrix.
    to_world: Mat3,
    /// Its inverse, the transpose.
    to_local: Mat3,
    /// Over the W x 2 (H - 1) half-row cells (also the lookup grid).
    distr: Distribution2D,
    /// Sample directions uniformly on the sphere instead (for the variance comparison).
    uniform: bool,
    /// The mean radiance over the sphere (exact for the piecewise-constant map).
    mean: Rgb,
}

/// The smallest and largest side of a map (a 16384 x 8192 map holds 1.6 GB of texels).
pub const MIN_SIDE: usize = 2;
pub const MAX_SIDE: usize = 16384;
/// The most texels a map may hold.
pub const MAX_TEXELS: usize = 1 << 24;

impl EnvMap {
    /// A map of `width` x `height` texels (row-major, top first, finite and non-negative;
    /// each side at least [`MIN_SIDE`]), turned by the orthogonal `to_world`, sampled by
    /// luminance or, with `uniform`, uniformly over the sphere.
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        to_world: Mat3,
        uniform: bool,
    ) -> Self {
        assert!(width >= MIN_SIDE && height >= MIN_SIDE && texels.len() == width * height);
        let rows = 2 * (height - 1);
        let mut weights = Vec::with_capacity(width * rows);
        let mut mean = glam::DVec3::ZERO;
        for k in 0..rows {
            // the cell's solid angle over 2 pi / W: cos theta_0 - cos theta_1
            let band = |k: usize| (PI as f64 * k as f64 / rows as f64).cos();
            let omega = band(k) - band(k + 1);
            for i in 0..width {
                let l = texels[texel_row(k) * width + i];
                weights.push((luminance(l) as f64 * omega) as f32);
                mean += l.as_dvec3() * omega;
            }
        }
        // sum of L omega_cell over 4 pi, with omega_cell = (2 pi / W) (cos theta_0 - cos theta_1)
        let mean = (mean * (2.0 * std::f64::consts::PI / width as f64)
            / (4.0 * std::f64::consts::PI))
            .as_vec3();
        EnvMap {
            width,
            height,
            texels,
            to_world,
            to_local: to_world.transpose(),
            distr: Distribution2D::new(&weights, width, rows),
            uniform,
            mean,
        }
    }

    /// The map's size in texels (width, height).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The local-to-world matrix.
    pub fn to_world(&self) -> Mat3 {
        self.to_world
    }

    /// True when directions are sampled uniformly instead of by luminance.
    pub fn is_uniform(&self) -> bool {
        self.uniform
    }

    /// The bytes the map holds: its texels (12 each) and its distribution (a probability and a
    /// cumulative sum per half-row cell, 8 bytes).
    pub fn memory_bytes(&self) -> u64 {
        let cells = self.width * 2 * (self.height - 1);
        (self.texels.len() * 12 + cells * 8) as u64
    }

    /// The mean radiance over the sphere.
    pub fn mean_radiance(&self) -> Rgb {
        self.mean
    }

    /// The texel shown by half-row cell (i, k).
    #[inline]
    fn texel(&self, (i, k): (usize, usize)) -> Rgb {
        self.texels[texel_row(k) * self.width + i]
    }

    /// Radiance arriving from world direction `w` (pointing away from the scene).
    #[inline]
    pub fn radiance(&self, w: Vec3) -> Rgb {
        self.texel(self.distr.cell(uv_of(self.to_local * w)))
    }

    /// The solid-angle density with which [`EnvMap::sample`] draws world direction `w`.
    #[inline]
    pub fn pdf(&self, w: Vec3) -> f32 {
        if self.uniform {
            return warp::INV_FOUR_PI;
        }
        let d = self.to_local * w;
        let sin_theta = (d.x * d.x + d.z * d.z).sqrt();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        self.distr.pdf(uv_of(d)) / (2.0 * PI * PI * sin_theta)
    }

    /// A world direction towards the light from `u`, with its radiance and solid-angle density;
    /// `None` for the (measure-zero) poles.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        if self.uniform {
            let w = warp::uniform_sphere(u);
            return Some((w, self.radiance(w), warp::INV_FOUR_PI));
        }
        let (uv, cell, p) = self.distr.sample(u);
        let (d, sin_theta) = direction_of(uv);
        if sin_theta <= 0.0 || p <= 0.0 {
            return None;
        }
        Some((
            self.to_world * d,
            self.texel(cell),
            p / (2.0 * PI * PI * sin_theta),
        ))
    }
}

/// The texel row half row `k` shows: (k + 1) / 2 (rows 0 and H - 1 show in one half row each,
/// the others in two).
#[inline]
fn texel_row(k: usize) -> usize {
    k.div_ceil(2)
}

/// Mitsuba 3's `uv_to_direction`: the local direction of map point `uv`, with sin theta.
#[inline]
pub fn direction_of(uv: Vec2) -> (Vec3, f32) {
    let (sin_theta, cos_theta) = (PI * uv.y).sin_cos();
    let (sin_phi, cos_phi) = (2.0 * PI * uv.x).sin_cos();
    (
        Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta),
        sin_theta,
    )
}

/// Mitsuba 3's `direction_to_uv`: the map point of unit local direction `d`, u wrapped into
/// [0, 1).
#[inline]
pub fn uv_of(d: Vec3) -> Vec2 {
    let u = d.x.atan2(-d.z) * (0.5 / PI);
    let u = if u < 0.0 { u + 1.0 } else { u };
    // u + 1 rounds to 1 for tiny negative u
    let u = if u >= 1.0 { 0.0 } else { u };
    Vec2::new(u, d.y.clamp(-1.0, 1.0).acos() / PI)
}
