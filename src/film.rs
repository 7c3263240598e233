//! The film: per-pixel accumulation of radiance samples with a reconstruction filter (the
//! filter h_j of Pauly et al. sec. 5: the indicator of pixel j by default, or a `tent` or
//! `gaussian` of [`filter`]), with the running sums of squares that give each pixel's standard
//! error, and a splat buffer for light tracing and MLT.

pub mod filter;

use crate::image_io::Image;
use crate::spectrum::Rgb;
pub use filter::{FilterBlock, PixelFilter};

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
    /// The reconstruction filter (the box keeps `sum` and `sum_sq` per sample; another filter
    /// keeps `sum` = sum(w f), `sum_sq` = the sum over passes of each pass's sum(w f) squared,
    /// and the rest in `filtered`).
    pub filter: PixelFilter,
    /// Per pixel, for a filter other than the box (empty for the box).
    pub filtered: Vec<FilteredPixel>,
    /// The filter's integral over the film for each column and each row (N_j = x[i] y[k]),
    /// computed when first needed.
    #[serde(skip)]
    norms: std::sync::OnceLock<(Vec<f64>, Vec<f64>)>,
}

/// A filtered pixel's sums besides sum(w f): the pass's batch (A_b, B_b) = (sum(w f), sum(w))
/// over the pass's samples, and over the passes so far sum(B_b), sum(A_b B_b), sum(B_b^2) and
/// their count (the ratio's variance comes from the batches, Measuring a renderer).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct FilteredPixel {
    pub weight: f64,
    pub pass: [f64; 4],
    pub cross: [f64; 3],
    pub weight_sq: f64,
    pub batches: u64,
}

impl Film {
    /// A film with the box filter.
    pub fn new(width: u32, height: u32) -> Self {
        Self::with_filter(width, height, PixelFilter::Box)
    }

    /// A film with reconstruction filter `filter`.
    pub fn with_filter(width: u32, height: u32, filter: PixelFilter) -> Self {
        let n = (width * height) as usize;
        let m = if filter.is_box() { 0 } else { n };
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            spp: 0,
            splat: vec![[0.0; 3]; n],
            splat_count: 0,
            splat_scale: 1.0,
            filter,
            filtered: vec![FilteredPixel::default(); m],
            norms: std::sync::OnceLock::new(),
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

    /// Adds one tile's filtered camera samples of the pass in flight.
    pub fn add_block(&mut self, block: &FilterBlock) {
        for y in 0..block.height {
            for x in 0..block.width {
                let i = ((block.y0 + y) * self.width as i64 + block.x0 + x) as usize;
                let b = &block.sums[(y * block.width + x) as usize];
                let p = &mut self.filtered[i].pass;
                for c in 0..4 {
                    p[c] += b[c];
                }
            }
        }
    }

    /// Closes the pass of a filtered film: each pixel's batch joins the sums.
    pub fn end_pass(&mut self) {
        for ((s, q), f) in self
            .sum
            .iter_mut()
            .zip(&mut self.sum_sq)
            .zip(&mut self.filtered)
        {
            let [a0, a1, a2, b] = std::mem::take(&mut f.pass);
            for (c, a) in [a0, a1, a2].into_iter().enumerate() {
                s[c] += a;
                q[c] += a * a;
                f.cross[c] += a * b;
            }
            f.weight += b;
            f.weight_sq += b * b;
            f.batches += 1;
        }
    }

    /// Adds a splat at continuous raster position `raster`: with the box, to the pixel it
    /// falls in; with another filter, w(x_j - raster) / N_j to each pixel j it reaches.
    #[inline]
    pub fn add_splat(&mut self, raster: glam::Vec2, l: Rgb) {
        if !self.filter.is_box() {
            return self.add_filtered_splat(raster, l);
        }
        let x = (raster.x.max(0.0) as u32).min(self.width - 1);
        let y = (raster.y.max(0.0) as u32).min(self.height - 1);
        let i = (y * self.width + x) as usize;
        for c in 0..3 {
            self.splat[i][c] += l[c] as f64;
        }
    }

    fn add_filtered_splat(&mut self, raster: glam::Vec2, l: Rgb) {
        let (w, h, f) = (self.width, self.height, self.filter);
        let (nx, ny) = self.norms.get_or_init(|| (f.norms(w), f.norms(h)));
        for y in f.reach(raster.y, 0, h as i64) {
            let wy = f.eval(y as f64 + 0.5 - raster.y as f64) / ny[y as usize];
            for x in f.reach(raster.x, 0, w as i64) {
                let wx = f.eval(x as f64 + 0.5 - raster.x as f64) / nx[x as usize];
                let s = &mut self.splat[(y * w as i64 + x) as usize];
                for c in 0..3 {
                    s[c] += wx * wy * l[c] as f64;
                }
            }
        }
    }

    /// The estimate: mean of the samples (sum(w f) / sum(w) with a filter) plus the splats.
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
            .enumerate()
            .map(|(i, (s, sp))| {
                let inv_n = match self.filtered.get(i) {
                    Some(f) if f.weight > 0.0 => 1.0 / f.weight,
                    Some(_) => 0.0,
                    None => inv_n,
                };
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
    /// noise level of a render without a reference. With a filter other than the box, the
    /// variance of the ratio sum(w f) / sum(w) from its independent passes instead.
    pub fn variance_of_mean(&self) -> Image {
        if !self.filter.is_box() {
            return self.batch_variance();
        }
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

    /// The delta-method variance of I = sum_b A_b / sum_b B_b over K independent passes b:
    /// K / (K - 1) sum_b (A_b - I B_b)^2 / (sum_b B_b)^2, zero below two passes (neighbouring
    /// samples share pixels, so the per-sample spread is not the pixel's).
    fn batch_variance(&self) -> Image {
        let pixels = self
            .sum
            .iter()
            .zip(&self.sum_sq)
            .zip(&self.filtered)
            .map(|((a, aa), f)| {
                let k = f.batches as f64;
                let mut v = [0.0f32; 3];
                if k > 1.0 && f.weight > 0.0 {
                    for c in 0..3 {
                        let i = a[c] / f.weight;
                        let ss = aa[c] - 2.0 * i * f.cross[c] + i * i * f.weight_sq;
                        v[c] = (ss.max(0.0) * k / (k - 1.0) / (f.weight * f.weight)) as f32;
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
