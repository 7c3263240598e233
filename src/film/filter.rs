//! Pixel reconstruction filters: Mitsuba 3's `box`, `tent` and `gaussian` (Mitsuba 3
//! documentation, plugins `box`, `tent`, `gaussian`; `ImageBlock::put`).
//!
//! A filter is separable, w(dx, dy) = w(dx) w(dy), with pixel j's centre at (j + 1/2) in
//! raster coordinates. A camera sample at p adds w(x_j - p) f and w(x_j - p) to every pixel j
//! within the radius, and the pixel is sum(w f) / sum(w) (Mitsuba's `hdrfilm`). A splat (light
//! tracing, BDPT's t = 1, MLT) adds f w(x_j - p) / N_j, with N_j the integral of the filter
//! over the film's rectangle: both estimate the same image, int_film w(x_j - p) f(p) dp / N_j.

use crate::spectrum::Rgb;

/// The largest filter radius in pixels a scene may ask for (a sample's cost grows with its
/// square).
pub const MAX_RADIUS: f64 = 16.0;

/// A reconstruction filter with Mitsuba 3's parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum PixelFilter {
    /// The pixel's indicator (radius 1/2): each sample counts in its own pixel only.
    #[default]
    Box,
    /// max(0, 1 - |x| / radius) (Mitsuba 3, plugin `tent`; default radius 1).
    Tent { radius: f32 },
    /// exp(-x^2 / (2 stddev^2)) - exp(-radius^2 / (2 stddev^2)), clamped at 0, with radius
    /// = 4 stddev (Mitsuba 3, plugin `gaussian`; default stddev 0.5, so radius 2). Mitsuba's
    /// CPU variants evaluate it through a degree-9 minimax polynomial within 5e-4 of this.
    Gaussian { stddev: f32 },
}

impl PixelFilter {
    /// Whether it is the box, whose samples stay in their own pixel.
    pub fn is_box(self) -> bool {
        self == PixelFilter::Box
    }

    /// The radius of its support, in pixels.
    pub fn radius(self) -> f64 {
        match self {
            PixelFilter::Box => 0.5,
            PixelFilter::Tent { radius } => radius as f64,
            PixelFilter::Gaussian { stddev } => 4.0 * stddev as f64,
        }
    }

    /// The one-dimensional filter w(x) (unnormalized, as Mitsuba evaluates it).
    pub fn eval(self, x: f64) -> f64 {
        let r = self.radius();
        match self {
            PixelFilter::Box => f64::from(u8::from(x.abs() <= 0.5)),
            PixelFilter::Tent { .. } => (1.0 - x.abs() / r).max(0.0),
            PixelFilter::Gaussian { stddev } => {
                let alpha = -0.5 / (stddev as f64 * stddev as f64);
                ((alpha * x * x).exp() - (alpha * r * r).exp()).max(0.0)
            }
        }
    }

    // ANCHOR: norms
    /// The integral of w from -radius to t (t clamped to the support), in closed form.
    pub fn primitive(self, t: f64) -> f64 {
        let r = self.radius();
        let t = t.clamp(-r, r);
        match self {
            PixelFilter::Box => t + r,
            PixelFilter::Tent { .. } if t <= 0.0 => 0.5 * (t + r) * (t + r) / r,
            PixelFilter::Tent { .. } => r - 0.5 * (r - t) * (r - t) / r,
            PixelFilter::Gaussian { stddev } => {
                let s = stddev as f64;
                let erf = |u: f64| statrs::function::erf::erf(u / (s * std::f64::consts::SQRT_2));
                let bias = (-0.5 * r * r / (s * s)).exp();
                s * (0.5 * std::f64::consts::PI).sqrt() * (erf(t) - erf(-r)) - bias * (t + r)
            }
        }
    }

    /// N for each pixel along an axis of `n` pixels: the integral of w(j + 1/2 - u) over the
    /// film's extent u in [0, n] (smaller near the edges, where the film cuts the support).
    pub fn norms(self, n: u32) -> Vec<f64> {
        (0..n)
            .map(|j| {
                let c = j as f64 + 0.5;
                self.primitive(c) - self.primitive(c - n as f64)
            })
            .collect()
    }
    // ANCHOR_END: norms

    /// The pixels along an axis of `n` pixels that a sample at coordinate `p` reaches, those of
    /// `|j + 1/2 - p| <= radius` (Mitsuba's `ImageBlock::put`), clipped to `lo..hi`.
    pub fn reach(self, p: f32, lo: i64, hi: i64) -> std::ops::Range<i64> {
        let (c, r) = (p as f64 - 0.5, self.radius());
        ((c - r).ceil() as i64).max(lo)..((c + r).floor() as i64 + 1).min(hi)
    }

    /// How many pixels beyond its own a camera sample reaches on each side.
    pub fn margin(self) -> u32 {
        ((self.radius() + 0.5).ceil() - 1.0).max(0.0) as u32
    }
}

/// One tile's camera samples spread by a filter: sum(w f) and sum(w) for the pixels of the
/// tile and of its margin inside the film, added to the film in tile order.
#[derive(Clone, Debug)]
pub struct FilterBlock {
    pub x0: i64,
    pub y0: i64,
    pub width: i64,
    pub height: i64,
    /// Per pixel of the block, row-major: sum(w f) (RGB) and sum(w).
    pub sums: Vec<[f64; 4]>,
}

impl FilterBlock {
    /// The block for the tile of pixels `xs` x `ys` of a `film_w` x `film_h` film.
    pub fn new(
        filter: PixelFilter,
        (film_w, film_h): (u32, u32),
        xs: std::ops::Range<u32>,
        ys: std::ops::Range<u32>,
    ) -> Self {
        let m = filter.margin() as i64;
        let x0 = (xs.start as i64 - m).max(0);
        let y0 = (ys.start as i64 - m).max(0);
        let x1 = (xs.end as i64 + m).min(film_w as i64);
        let y1 = (ys.end as i64 + m).min(film_h as i64);
        FilterBlock {
            x0,
            y0,
            width: x1 - x0,
            height: y1 - y0,
            sums: vec![[0.0; 4]; ((x1 - x0) * (y1 - y0)) as usize],
        }
    }

    /// Adds a camera sample of value `l` at raster point `p` to every pixel it reaches.
    pub fn put(&mut self, filter: PixelFilter, p: glam::Vec2, l: Rgb) {
        let xs = filter.reach(p.x, self.x0, self.x0 + self.width);
        for y in filter.reach(p.y, self.y0, self.y0 + self.height) {
            let wy = filter.eval(y as f64 + 0.5 - p.y as f64);
            let row = ((y - self.y0) * self.width - self.x0) as usize;
            for x in xs.clone() {
                let w = wy * filter.eval(x as f64 + 0.5 - p.x as f64);
                let s = &mut self.sums[row + x as usize];
                for c in 0..3 {
                    s[c] += w * l[c] as f64;
                }
                s[3] += w;
            }
        }
    }
}
