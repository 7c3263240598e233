//! The adjoint image: light start points sampled in proportion to how much they matter to the
//! image (Kristensen 2010, sec. 5.2.1 and 5.3.1).
//!
//! A light path usually starts at a point chosen in proportion to emitted power,
//! p(x_0) ~ int L_e |cos| dw (eq. (5.2)). The ideal start density is in proportion to the
//! adjoint measurement I*(x_0) = int L_e(x_0, w) W_i(x_0, w) |cos| dw (eq. (5.3), (5.6)): the
//! power the light sends to the sensor. I* is estimated once, on a coarse grid over the unit
//! square, and the light is sampled through an invertible map F from that square onto the lights:
//!
//! - F (the light-sampling map): light i = floor(m u_1) of the m area lights, the remainder
//!   m u_1 - i chooses a primitive of the light by area and is reused as its first coordinate,
//!   u_2 the second; the point is uniform by area, so F's density is p_F(x) = 1 / (m A_i).
//!   Lights occupy vertical strips of width 1/m; with a column count that is a multiple of m no
//!   cell spans two lights.
//! - The grid: cell j holds I*_j, the part of the image's total value carried by paths whose
//!   light vertex lies in F(cell j) (eq. (5.7) with the split by cells), estimated by BDPT: every
//!   MIS-weighted contribution of a pre-pass is deposited in the cell F^-1(y_0) of its light
//!   vertex. DEVIATION: the thesis estimates it with MLT (or a Markov chain pre-pass); any
//!   unbiased estimator of the image serves, and BDPT's is the project's simplest.
//! - Sampling: cell j with P_j = (I*_j + eps) / sum_k (I*_k + eps), u uniform in the cell, x_0 =
//!   F(u); its area density is p_A(x_0) = P_j N_cells p_F(x_0) (derived from the light-sampling map: P_j
//!   picks the cell, N_cells p_F(x_0) is the density within it). eps > 0
//!   keeps the density positive wherever L_e > 0 (footnote 1 of ch. 5; the value is not given:
//!   here a fraction `epsilon` of the mean cell value, DEVIATION/choice).
//!
//! Only area lights are covered; point, spot, directional and environment lights keep their
//! power-proportional sampling. A light start picks a light by power as before; when the pick is
//! an area light the start point comes from the adjoint image instead, so the total density of an
//! area-light point is P(area lights) p_A(x_0).
//!
//! Held by the enlightened technique ([`crate::enlightened::Enlightened`]), the image is used by every sampler
//! of light start points (BDPT's light subpaths and its s = 1 connections, light tracing, MLT's
//! initialization and its bidirectional mutation) and every density of one
//! ([`crate::path::Vertex::light_origin_pdf`]: BDPT's MIS weights, MLT's transition densities).

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::bidir::{Bdpt, Strategies};
use crate::math::distribution::ONE_MINUS_EPSILON;
use crate::math::{Distribution1D, Sampler};
pub use crate::path::technique::{LightStart, MapPoint};
use crate::path::{LocalSampling, Vertex};
use crate::scene::{Light, Scene};

/// Default grid: 64 x 64 cells (the thesis's "typically 64x64"); columns are rounded up to a
/// multiple of the number of area lights.
pub const DEFAULT_RESOLUTION: (u32, u32) = (64, 64);
/// Default pre-pass size: BDPT samples per grid cell. The thesis rendered its 72x72 maze image
/// with 50 samples per pixel, about one sample per pixel of its 512x512 image; 8 per cell of
/// 72x64 is about 2 per pixel of the 128x128 maze; with the floor below it gave the best of the
/// settings measured on the maze (book, "Measured: the maze").
pub const DEFAULT_SAMPLES_PER_CELL: u32 = 8;
/// Default floor eps as a fraction of the mean cell value (the thesis gives no value). With
/// eps = 0.5 the floor carries eps / (1 + eps) = 1/3 of all area-light starts, spread over the
/// lights like F: a defensive mixture. Measured on the maze (32 spp, 2 seeds): relMSE 0.078 at
/// eps = 0.01, 0.082 at 0.1, 0.066 at 0.5, against 0.069 without the image.
pub const DEFAULT_EPSILON: f32 = 0.5;
/// Camera samples per parallel work item of the pre-pass.
const CHUNK: u64 = 1024;
/// Keeps the pre-pass streams apart from the renderers'.
const ADJOINT_SALT: u64 = 0x6164_6a6f_696e_7400;

/// The adjoint image's parameters (`[render.adjoint]`, `--adjoint-*`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdjointSettings {
    /// Requested columns and rows; columns are rounded up to a multiple of the area lights.
    pub resolution: (u32, u32),
    /// BDPT camera samples of the pre-pass per grid cell.
    pub samples_per_cell: u32,
    /// The floor eps added to every cell, as a fraction of the mean cell value.
    pub epsilon: f32,
    /// How I* is estimated: a BDPT pre-pass, or the chains of the Metropolis particle sampler
    /// (the thesis's way).
    pub estimator: AdjointEstimator,
}

/// The pre-pass that estimates the adjoint image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum AdjointEstimator {
    /// `samples_per_cell` BDPT camera samples per cell; every MIS-weighted contribution goes to
    /// the cell of its light vertex.
    Bdpt,
    /// `samples_per_cell` steps per cell of Metropolis particle chains over full paths (eq.
    /// (5.15), without the defensive part): each state deposits its weight at F^-1(x_0)
    /// (Kristensen 2010, sec. 5.2.1).
    Metropolis,
}

crate::option_value!(AdjointEstimator, "adjoint estimator");

/// Why the adjoint image refuses its settings or its scene (Kristensen 2010, sec. 5.3.1); the
/// messages name the setting or the missing piece, as the command line and the scene-file
/// errors print them.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AdjointError {
    /// A command-line override refused (the flag as the message spells it, the reason).
    #[error("{0}: {1}")]
    Flag(&'static str, #[source] Box<AdjointError>),
    /// An option's value refused, the message naming the option as the caller spells it.
    #[error("{0}")]
    Option(String),
    /// A grid size outside 1..=4096 (columns, rows).
    #[error("adjoint resolution {0}x{1}: both sizes must be in 1..=4096")]
    BadResolution(u32, u32),
    /// No pre-pass sample per cell.
    #[error("adjoint samples per cell must be at least 1")]
    NoSamples,
    /// A floor eps that is not positive and finite.
    #[error(
        "adjoint epsilon = {0} must be positive (a zero floor gives cells of density 0 \
         where light is emitted, which biases the image)"
    )]
    BadEpsilon(f32),
    /// Estimates for a scene without area lights: there is no light map to put them on.
    #[error("the adjoint image needs at least one area light")]
    NoAreaLight,
    /// Estimates that do not fit the grid, or a column count that is no multiple of the area
    /// lights (columns, rows, estimates, area lights).
    #[error("adjoint grid {0}x{1} with {2} estimates for {3} area lights")]
    GridMismatch(u32, u32, usize, usize),
    /// `--adjoint-image` on a scene without area lights.
    #[error("--adjoint-image: the scene has no area light to sample")]
    NothingToSample,
    /// `--adjoint-image` on a scene without a camera: the pre-pass traces camera samples.
    #[error("--adjoint-image needs a scene with a camera")]
    NoCamera,
}

/// The command line and the tests report errors as text.
impl From<AdjointError> for String {
    fn from(e: AdjointError) -> Self {
        e.to_string()
    }
}

impl Default for AdjointSettings {
    fn default() -> Self {
        AdjointSettings {
            resolution: DEFAULT_RESOLUTION,
            samples_per_cell: DEFAULT_SAMPLES_PER_CELL,
            epsilon: DEFAULT_EPSILON,
            estimator: AdjointEstimator::Bdpt,
        }
    }
}

impl AdjointSettings {
    /// These settings with the command line's `--adjoint-*` overrides (resolution, samples per
    /// cell, epsilon, estimator), checked; the message names the option.
    pub fn overridden(
        mut self,
        resolution: Option<(u32, u32)>,
        samples_per_cell: Option<u32>,
        epsilon: Option<f32>,
        estimator: Option<AdjointEstimator>,
    ) -> Result<Self, AdjointError> {
        if let Some(r) = resolution {
            self.resolution = r;
        }
        if let Some(n) = samples_per_cell {
            self.samples_per_cell = n;
        }
        if let Some(e) = epsilon {
            self.epsilon = e;
        }
        if let Some(e) = estimator {
            self.estimator = e;
        }
        self.validate()
            .map_err(|e| AdjointError::Flag("--adjoint-*", Box::new(e)))?;
        Ok(self)
    }

    /// Checks the values; the message names the offending one.
    pub fn validate(&self) -> Result<(), AdjointError> {
        let (c, r) = self.resolution;
        if !(1..=4096).contains(&c) || !(1..=4096).contains(&r) {
            return Err(AdjointError::BadResolution(c, r));
        }
        if self.samples_per_cell == 0 {
            return Err(AdjointError::NoSamples);
        }
        if !(self.epsilon.is_finite() && self.epsilon > 0.0) {
            return Err(AdjointError::BadEpsilon(self.epsilon));
        }
        Ok(())
    }
}

/// The light-sampling map F: [0,1)^2 -> area lights (Kristensen 2010, sec. 5.2.1).
// ANCHOR: light_map
#[derive(Clone, Debug)]
pub struct LightMap {
    /// Scene indices of the area lights, in scene order: light `lights[i]` owns the strip
    /// i/m <= u_1 < (i+1)/m.
    lights: Vec<u32>,
    /// For every scene light, its strip (None for other light types).
    slot: Vec<Option<u32>>,
}

impl LightMap {
    pub fn new(scene: &Scene) -> Self {
        let mut lights = Vec::new();
        let mut slot = vec![None; scene.lights.len()];
        for (i, l) in scene.lights.iter().enumerate() {
            if matches!(l, Light::Area { .. }) {
                slot[i] = Some(lights.len() as u32);
                lights.push(i as u32);
            }
        }
        LightMap { lights, slot }
    }

    /// m, the number of area lights.
    pub fn len(&self) -> usize {
        self.lights.len()
    }

    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// The strip of scene light `light` (None if it is no area light).
    pub fn slot(&self, light: u32) -> Option<u32> {
        self.slot.get(light as usize).copied().flatten()
    }

    /// F(u): light i = floor(m u_1), the remainder picks a primitive by area and becomes its
    /// first coordinate, u_2 the second.
    pub fn forward(&self, scene: &Scene, u: Vec2) -> Option<MapPoint> {
        let m = self.lights.len();
        if m == 0 {
            return None;
        }
        let x = u.x.clamp(0.0, ONE_MINUS_EPSILON) * m as f32;
        let i = (x as usize).min(m - 1);
        let rem = (x - i as f32).clamp(0.0, ONE_MINUS_EPSILON);
        let light = self.lights[i];
        let Light::Area { prims, distr, .. } = &scene.lights[light as usize] else {
            return None;
        };
        let (k, _, rem2) = distr.sample(rem);
        let prim = prims[k];
        let (p, n) = scene.prims[prim as usize].sample_area(Vec2::new(rem2, u.y));
        Some(MapPoint { light, prim, p, n })
    }

    /// F^-1: the u with F(u) = p for point `p` on primitive `prim` of area light `light`.
    pub fn inverse(&self, scene: &Scene, light: u32, prim: u32, p: Vec3) -> Option<Vec2> {
        // ASSIGNMENT: light_map_inverse
        let i = self.slot(light)?;
        let Light::Area { prims, distr, .. } = &scene.lights[light as usize] else {
            return None;
        };
        let k = prims.iter().position(|&q| q == prim)?;
        let a = scene.prims[prim as usize].sample_area_inverse(p);
        let rem = (distr.cdf(k) + a.x * distr.pmf(k)).clamp(0.0, ONE_MINUS_EPSILON);
        let m = self.lights.len() as f32;
        Some(Vec2::new(
            ((i as f32 + rem) / m).clamp(0.0, ONE_MINUS_EPSILON),
            a.y,
        ))
        // END ASSIGNMENT
    }

    /// p_F(x), F's area density at a point of primitive `prim` of light `light`: 1/m times the
    /// primitive's selection probability over its area (= 1 / (m A_i) for selection by area).
    pub fn pdf(&self, scene: &Scene, light: u32, prim: u32) -> f32 {
        let Some(_) = self.slot(light) else {
            return 0.0;
        };
        let Light::Area { prims, distr, .. } = &scene.lights[light as usize] else {
            return 0.0;
        };
        match prims.iter().position(|&q| q == prim) {
            Some(k) => distr.pmf(k) / (scene.prims[prim as usize].area() * self.len() as f32),
            None => 0.0,
        }
    }
}
// ANCHOR_END: light_map

/// What the pre-pass cost and found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AdjointStats {
    /// BDPT camera samples traced.
    pub samples: u64,
    /// Wall-clock seconds of the pre-pass.
    pub seconds: f64,
    /// Cells whose estimate is zero (they are sampled through eps only).
    pub zero_cells: usize,
}

/// The adjoint image over the light map and the distribution sampled from it.
#[derive(Clone, Debug)]
pub struct AdjointImage {
    pub map: LightMap,
    pub cols: u32,
    pub rows: u32,
    /// I*_j per cell (luminance), row-major from u_2 = 0; the cells sum to the sum of the
    /// image's pixel values carried by area-light paths.
    pub estimate: Vec<f64>,
    /// The absolute floor eps added to every cell.
    pub epsilon: f64,
    /// Marginal distribution of rows, and the columns of each row.
    rows_distr: Distribution1D,
    cols_distr: Vec<Distribution1D>,
    /// The probability that a light start is on an area light (their share of the scene's
    /// power-proportional light selection).
    pub area_fraction: f32,
    pub stats: AdjointStats,
}

impl AdjointImage {
    /// The grid size for `requested` (columns, rows) and m area lights: columns rounded up to a
    /// multiple of m.
    pub fn grid_size(requested: (u32, u32), m: usize) -> (u32, u32) {
        let m = m.max(1) as u32;
        (requested.0.div_ceil(m).max(1) * m, requested.1.max(1))
    }

    /// The image from per-cell estimates (length cols * rows) and the relative floor.
    pub fn from_estimate(
        scene: &Scene,
        cols: u32,
        rows: u32,
        estimate: Vec<f64>,
        epsilon_rel: f32,
    ) -> Result<Self, AdjointError> {
        let map = LightMap::new(scene);
        if map.is_empty() {
            return Err(AdjointError::NoAreaLight);
        }
        let n = cols as usize * rows as usize;
        if estimate.len() != n || !cols.is_multiple_of(map.len() as u32) {
            return Err(AdjointError::GridMismatch(
                cols,
                rows,
                estimate.len(),
                map.len(),
            ));
        }
        let clean: Vec<f64> = estimate
            .iter()
            .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
            .collect();
        let mean = clean.iter().sum::<f64>() / n as f64;
        // eps > 0: cells where nothing was found keep a positive density
        let (epsilon, weights): (f64, Vec<f64>) = if mean > 0.0 {
            let eps = epsilon_rel as f64 * mean;
            (eps, clean.iter().map(|v| v + eps).collect())
        } else {
            (1.0, vec![1.0; n])
        };
        let row_sums: Vec<f32> = weights
            .chunks(cols as usize)
            .map(|r| r.iter().sum::<f64>() as f32)
            .collect();
        let cols_distr = weights
            .chunks(cols as usize)
            .map(|r| Distribution1D::new(&r.iter().map(|&v| v as f32).collect::<Vec<_>>()))
            .collect();
        let area_fraction = map
            .lights
            .iter()
            .map(|&l| scene.light_pmf(l))
            .sum::<f32>()
            .min(1.0);
        Ok(AdjointImage {
            stats: AdjointStats {
                zero_cells: clean.iter().filter(|&&v| v == 0.0).count(),
                ..AdjointStats::default()
            },
            map,
            cols,
            rows,
            estimate: clean,
            epsilon,
            rows_distr: Distribution1D::new(&row_sums),
            cols_distr,
            area_fraction,
        })
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.cols as usize * self.rows as usize
    }

    /// P_j of cell (column, row).
    pub fn cell_probability(&self, col: u32, row: u32) -> f32 {
        self.rows_distr.pmf(row as usize) * self.cols_distr[row as usize].pmf(col as usize)
    }

    /// The cell of a point u of the unit square.
    pub fn cell_of(&self, u: Vec2) -> (u32, u32) {
        let c = ((u.x * self.cols as f32) as u32).min(self.cols - 1);
        let r = ((u.y * self.rows as f32) as u32).min(self.rows - 1);
        (c, r)
    }

    /// Samples a light start point: a cell by P_j (rows by the marginal, then the column, from
    /// `u_cell`), u uniform in it (from `u_in`), x_0 = F(u).
    // ANCHOR: adjoint_sample
    pub fn sample(&self, scene: &Scene, u_cell: Vec2, u_in: Vec2) -> Option<LightStart> {
        let (r, _, _) = self.rows_distr.sample(u_cell.y);
        let (c, _, _) = self.cols_distr[r].sample(u_cell.x);
        let u = Vec2::new(
            ((c as f32 + u_in.x) / self.cols as f32).min(ONE_MINUS_EPSILON),
            ((r as f32 + u_in.y) / self.rows as f32).min(ONE_MINUS_EPSILON),
        );
        let point = self.map.forward(scene, u)?;
        // the density through F^-1, as MIS and MLT evaluate it: a point within rounding of a
        // cell edge may map back to the neighbouring cell, and the weight 1/p must use the same
        // density as every other strategy's view of the point
        let pdf = self.pdf(scene, point.light, point.prim, point.p);
        (pdf > 0.0).then_some(LightStart { point, pdf })
    }
    // ANCHOR_END: adjoint_sample

    /// p(x_0) = P(area lights) P_j N_cells p_F(x_0) for point `p` on primitive `prim` of light
    /// `light`, with j = the cell of F^-1(x_0); 0 for lights the map does not cover.
    // ANCHOR: adjoint_pdf
    pub fn pdf(&self, scene: &Scene, light: u32, prim: u32, p: Vec3) -> f32 {
        let Some(u) = self.map.inverse(scene, light, prim, p) else {
            return 0.0;
        };
        let (c, r) = self.cell_of(u);
        self.area_fraction
            * self.cell_probability(c, r)
            * self.cells() as f32
            * self.map.pdf(scene, light, prim)
    }
    // ANCHOR_END: adjoint_pdf

    /// Estimates the adjoint image with a BDPT pre-pass: `settings.samples_per_cell` camera
    /// samples per cell at raster positions uniform over the film; every MIS-weighted
    /// contribution (splats included) is deposited, as luminance, in the cell of its path's
    /// light vertex. The light starts are `tech`'s (one without an adjoint image for the
    /// classical ones). Deterministic for a seed, whatever the thread count.
    // ANCHOR: adjoint_render
    pub fn render(
        scene: &Scene,
        tech: &dyn LocalSampling,
        settings: &AdjointSettings,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, AdjointError> {
        settings.validate()?;
        let start = Instant::now();
        let map = LightMap::new(scene);
        if map.is_empty() {
            return Err(AdjointError::NothingToSample);
        }
        let cam = scene.camera.as_ref().ok_or(AdjointError::NoCamera)?;
        let (cols, rows) = Self::grid_size(settings.resolution, map.len());
        let cells = cols as usize * rows as usize;
        let samples = settings.samples_per_cell as u64 * cells as u64;
        if settings.estimator == AdjointEstimator::Metropolis {
            return Self::render_metropolis(scene, tech, settings, seed, &map, (cols, rows), start);
        }
        let bdpt = Bdpt::new(tech, max_depth, Strategies::All);
        let film = Vec2::new(cam.width as f32, cam.height as f32);
        let chunks = samples.div_ceil(CHUNK);
        let n_pix = cam.width as f64 * cam.height as f64;
        let cell_index = |v: &Vertex| -> Option<usize> {
            let (light, prim) = v.area_light_point(scene)?;
            let u = map.inverse(scene, light, prim, v.p)?;
            let c = ((u.x * cols as f32) as u32).min(cols - 1);
            let r = ((u.y * rows as f32) as u32).min(rows - 1);
            Some((r * cols + c) as usize)
        };
        let parts: Vec<Vec<(usize, f64)>> = (0..chunks)
            .into_par_iter()
            .map(|ci| {
                let mut sampler = Sampler::new(seed, ci ^ ADJOINT_SALT, 0);
                let mut walks = crate::bidir::Scratch::default();
                let mut out = Vec::new();
                for _ in 0..CHUNK.min(samples - ci * CHUNK) {
                    let raster = sampler.next_2d() * film;
                    let start = crate::bidir::SensorStart::Camera(raster);
                    bdpt.sample(scene, start, &mut sampler, &mut walks);
                    let (light, eye) = (&walks.light, &walks.eye);
                    bdpt.for_each_strategy(
                        scene,
                        light,
                        eye,
                        &mut sampler,
                        &mut |s, t, l, splat, sampled| {
                            // a splat lands on any pixel and the film divides it by the number
                            // of light paths (one per camera sample): per sample it counts 1 /
                            // n_pix of a camera contribution in the sum of pixel values
                            let y = crate::spectrum::average(l) as f64
                                / if splat.is_some() { n_pix } else { 1.0 };
                            if !(y.is_finite() && y > 0.0) {
                                return true;
                            }
                            let y0 = match s {
                                0 => eye.get(t - 1),
                                1 => sampled.as_ref(),
                                _ => light.first(),
                            };
                            if let Some(j) = y0.and_then(cell_index) {
                                out.push((j, y));
                            }
                            true
                        },
                    );
                }
                out
            })
            .collect();
        // I*_j as a sum of pixel values: contributions over samples, times the pixel count
        let scale = (cam.width as f64 * cam.height as f64) / samples as f64;
        let mut estimate = vec![0.0f64; cells];
        for part in parts {
            for (j, y) in part {
                estimate[j] += y * scale;
            }
        }
        let mut image = Self::from_estimate(scene, cols, rows, estimate, settings.epsilon)?;
        image.stats.samples = samples;
        image.stats.seconds = start.elapsed().as_secs_f64();
        Ok(image)
    }
    // ANCHOR_END: adjoint_render

    /// The Metropolis pre-pass (`AdjointEstimator::Metropolis`): chains over the
    /// bidirectional particle sampler's full paths from the camera, each state depositing
    /// I(u) b_T / (T(u) N) in the cell of its light vertex. With the target T = I (no
    /// defensive part) that weight is the same for every state, so a cell's estimate is the
    /// share of states whose path starts in it, times b: the thesis's by-product of its
    /// preprocessing MLT. Paths through mirrors or glass carry no contribution in that sampler
    /// (see `particles::trace_bidirectional`), so the cells they would raise keep the floor.
    // ANCHOR: adjoint_metropolis
    fn render_metropolis(
        scene: &Scene,
        tech: &dyn LocalSampling,
        settings: &AdjointSettings,
        seed: u64,
        map: &LightMap,
        (cols, rows): (u32, u32),
        start: Instant,
    ) -> Result<Self, AdjointError> {
        use crate::enlightened::metropolis::{
            trace_metropolis_with_starts, MetropolisParticleSettings,
        };
        use crate::enlightened::particles::ImportonSource;
        let cells = cols as usize * rows as usize;
        let steps = settings.samples_per_cell as u64 * cells as u64;
        let chain_settings = MetropolisParticleSettings {
            bootstrap: (steps / 4).clamp(1024, 65_536),
            defensive: 0.0,
            ..Default::default()
        };
        let (_, _, starts) = trace_metropolis_with_starts(
            scene,
            tech,
            ImportonSource::Camera,
            steps,
            seed ^ ADJOINT_SALT,
            &chain_settings,
            true,
        );
        let mut estimate = vec![0.0f64; cells];
        for s in &starts {
            if let Some(u) = map.inverse(scene, s.light, s.prim, s.p) {
                let c = ((u.x * cols as f32) as u32).min(cols - 1);
                let r = ((u.y * rows as f32) as u32).min(rows - 1);
                estimate[(r * cols + c) as usize] += s.weight;
            }
        }
        let mut image = Self::from_estimate(scene, cols, rows, estimate, settings.epsilon)?;
        image.stats.samples = steps;
        image.stats.seconds = start.elapsed().as_secs_f64();
        Ok(image)
    }
    // ANCHOR_END: adjoint_metropolis

    /// Cell values as an image (columns along u_1, rows along u_2): the estimate plus eps,
    /// divided by the largest cell so it can be viewed as it is.
    pub fn to_image(&self) -> crate::image_io::Image {
        let max = self
            .estimate
            .iter()
            .fold(0.0f64, |a, &v| a.max(v + self.epsilon))
            .max(f64::MIN_POSITIVE);
        let data = self
            .estimate
            .iter()
            .map(|&v| glam::Vec3::splat(((v + self.epsilon) / max) as f32))
            .collect();
        crate::image_io::Image {
            width: self.cols,
            height: self.rows,
            pixels: data,
        }
    }
}
