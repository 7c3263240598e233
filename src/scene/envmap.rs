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
//! H-high image is centred on theta = pi y / (H - 1), poles included, and the radiance between
//! the centres is their bilinear interpolation, wrapping around in u (column W - 1 meets column 0
//! at u = 0) and clamped in v, as Mitsuba 3's texture lookup does.
//!
//! Sampling, Mitsuba's too: on the (W + 1) x H grid of texel centres in (s, v), s = u - 1/(2W)
//! (the last column repeating the first), the value Y(L) sin theta_y at each centre, interpolated
//! bilinearly, is a [`Bilinear2D`] density, drawn exactly. With d omega = 2 pi^2 sin theta du dv,
//! the solid-angle density is p(s, v) / (2 pi^2 sin theta) (Pharr, Jakob and Humphreys,
//! Physically Based Rendering, 3rd ed., eq. 14.18). Book: "Environment maps".

use glam::{Mat3, Vec2, Vec3};
use std::f32::consts::PI;

use crate::math::{warp, Bilinear2D};
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
    /// Over the W x (H - 1) cells between texel centres, in (s, v).
    distr: Bilinear2D,
    /// Sample directions uniformly on the sphere instead (for the variance comparison).
    uniform: bool,
    /// The mean radiance over the sphere (exact for the bilinear lookup).
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
        let row_theta = |y: usize| std::f64::consts::PI * y as f64 / (height - 1) as f64;
        let mut values = Vec::with_capacity((width + 1) * height);
        for y in 0..height {
            // (exactly 0 at both poles: sin pi rounds to 1e-16)
            let sin_theta = if y == 0 || y == height - 1 {
                0.0
            } else {
                row_theta(y).sin() as f32
            };
            let row = &texels[y * width..(y + 1) * width];
            values.extend(
                row.iter()
                    .chain(&row[..1])
                    .map(|&l| luminance(l) * sin_theta),
            );
        }
        let mean = mean_of(width, height, &texels);
        EnvMap {
            width,
            height,
            texels,
            to_world,
            to_local: to_world.transpose(),
            distr: Bilinear2D::new(&values, width, height - 1),
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

    /// The bytes the map holds: its texels (12 each) and its distribution (a value and a
    /// cumulative sum per vertex of the (W + 1) x H grid, 12 bytes).
    pub fn memory_bytes(&self) -> u64 {
        let vertices = (self.width + 1) * self.height;
        (self.texels.len() * 12 + vertices * 12) as u64
    }

    /// The mean radiance over the sphere.
    pub fn mean_radiance(&self) -> Rgb {
        self.mean
    }

    /// Texel (x, y).
    #[inline]
    fn texel(&self, x: usize, y: usize) -> Rgb {
        self.texels[y * self.width + x]
    }

    /// The radiance at map point `uv`: Mitsuba 3's bilinear lookup between the texel centres,
    /// wrapped in u, clamped in v (a NaN coordinate reads as 0).
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        let (w, h) = (self.width, self.height);
        let u = uv.x - uv.x.floor();
        let x = if u.is_nan() { 0.0 } else { u } * w as f32 - 0.5;
        let x0 = x.floor();
        let fx = x - x0;
        // x0 is in [-1, W - 1] (W - 1 + 1/2 rounds to at most W - 1/2)
        let i0 = (x0 as i64).rem_euclid(w as i64) as usize;
        let i1 = if i0 + 1 == w { 0 } else { i0 + 1 };
        let y = if uv.y.is_nan() {
            0.0
        } else {
            uv.y.clamp(0.0, 1.0)
        } * (h - 1) as f32;
        let j0 = (y as usize).min(h - 2);
        let fy = y - j0 as f32;
        let row = |j: usize| self.texel(i0, j) * (1.0 - fx) + self.texel(i1, j) * fx;
        row(j0) * (1.0 - fy) + row(j0 + 1) * fy
    }

    /// Radiance arriving from world direction `w` (pointing away from the scene).
    #[inline]
    pub fn radiance(&self, w: Vec3) -> Rgb {
        self.lookup(uv_of(self.to_local * w))
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
        let uv = uv_of(d);
        let s = uv.x - 0.5 / self.width as f32;
        let s = if s < 0.0 { s + 1.0 } else { s };
        self.distr.pdf(Vec2::new(s, uv.y)) / (2.0 * PI * PI * sin_theta)
    }

    /// A world direction towards the light from `u`, with its radiance and solid-angle density
    /// (both those of [`EnvMap::radiance`] and [`EnvMap::pdf`] at it); `None` for the
    /// (measure-zero) poles.
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        if self.uniform {
            let w = warp::uniform_sphere(u);
            return Some((w, self.radiance(w), warp::INV_FOUR_PI));
        }
        let (p, density) = self.distr.sample(u);
        let u = p.x + 0.5 / self.width as f32;
        let u = if u >= 1.0 { u - 1.0 } else { u };
        let (d, sin_theta) = direction_of(Vec2::new(u, p.y));
        if sin_theta <= 0.0 || density <= 0.0 {
            return None;
        }
        let w = self.to_world * d;
        let pdf = self.pdf(w);
        (pdf > 0.0).then(|| (w, self.radiance(w), pdf))
    }
}

/// The mean over the sphere of the bilinear lookup of a `width` x `height` map: per band between
/// row centres, the row means (the mean over u of a periodic piecewise-linear function is the
/// mean of its nodes) linear in theta, against sin theta d theta.
fn mean_of(width: usize, height: usize, texels: &[Rgb]) -> Rgb {
    let row_theta = |y: usize| std::f64::consts::PI * y as f64 / (height - 1) as f64;
    let row_mean = |y: usize| {
        let row = &texels[y * width..(y + 1) * width];
        row.iter().map(|l| l.as_dvec3()).sum::<glam::DVec3>() / width as f64
    };
    // the row means, linear in theta between the centres, against sin theta d theta:
    // int (1 - s) sin = c0 - c1 - i1, int s sin = i1 with s = (theta - theta0) / delta
    let mut mean = glam::DVec3::ZERO;
    for y in 0..height - 1 {
        let (t0, t1) = (row_theta(y), row_theta(y + 1));
        let i1 = (t1.sin() - t0.sin()) / (t1 - t0) - t1.cos();
        mean += row_mean(y) * (t0.cos() - t1.cos() - i1) + row_mean(y + 1) * i1;
    }
    // over 4 pi, with d omega = sin theta d theta d phi and the row mean over 2 pi in phi
    (mean / 2.0).as_vec3()
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
