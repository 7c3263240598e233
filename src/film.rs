//! The film: per-pixel accumulation of radiance samples with a box filter (the filter h_j of
//! Pauly et al. sec. 5 is the indicator of pixel j), with the running sums of squares that give
//! each pixel's standard error, and a splat buffer for light tracing and MLT.

use crate::image_io::Image;
use crate::spectrum::Rgb;

/// Sums of samples and of their squares per pixel, in f64 so billions of samples add up exactly
/// enough.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub sum: Vec<[f64; 3]>,
    pub sum_sq: Vec<[f64; 3]>,
    /// Samples per pixel accumulated so far.
    pub spp: u64,
    /// Splatted contributions (light paths, MLT), already divided by their own sample counts.
    pub splat: Vec<[f64; 3]>,
    /// How many light paths (or mutations) the splat buffer stands for; it is divided by this.
    pub splat_count: u64,
    /// Factor on the splat buffer (1 except for MLT, whose deposits are in units of b: the
    /// buffer is scaled by the current estimate of b, which keeps improving during a run).
    pub splat_scale: f64,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        let n = (width * height) as usize;
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            spp: 0,
            splat: vec![[0.0; 3]; n],
            splat_count: 0,
            splat_scale: 1.0,
        }
    }

    /// Adds one pixel's batch of samples (sums computed by the caller).
    #[inline]
    pub fn add_pixel(&mut self, index: usize, sum: [f64; 3], sum_sq: [f64; 3]) {
        for c in 0..3 {
            self.sum[index][c] += sum[c];
            self.sum_sq[index][c] += sum_sq[c];
        }
    }

    /// Adds a splat at continuous raster position `raster` (box filter: the pixel it falls in).
    #[inline]
    pub fn add_splat(&mut self, raster: glam::Vec2, l: Rgb) {
        let x = (raster.x.max(0.0) as u32).min(self.width - 1);
        let y = (raster.y.max(0.0) as u32).min(self.height - 1);
        let i = (y * self.width + x) as usize;
        for c in 0..3 {
            self.splat[i][c] += l[c] as f64;
        }
    }

    /// The estimate: mean of the samples plus the splats.
    pub fn image(&self) -> Image {
        let inv_n = if self.spp > 0 {
            1.0 / self.spp as f64
        } else {
            0.0
        };
        let inv_s = if self.splat_count > 0 {
            self.splat_scale / self.splat_count as f64
        } else {
            0.0
        };
        let pixels = self
            .sum
            .iter()
            .zip(&self.splat)
            .map(|(s, sp)| {
                Rgb::new(
                    (s[0] * inv_n + sp[0] * inv_s) as f32,
                    (s[1] * inv_n + sp[1] * inv_s) as f32,
                    (s[2] * inv_n + sp[2] * inv_s) as f32,
                )
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Per-pixel variance of the mean (sample variance / n) of the accumulated samples: the
    /// noise level of a render without a reference.
    pub fn variance_of_mean(&self) -> Image {
        let n = self.spp as f64;
        let pixels = self
            .sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(s, q)| {
                let mut v = [0.0f32; 3];
                if n > 1.0 {
                    for c in 0..3 {
                        let mean = s[c] / n;
                        let var = ((q[c] / n - mean * mean) * n / (n - 1.0)).max(0.0);
                        v[c] = (var / n) as f32;
                    }
                }
                Rgb::from_array(v)
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}
