//! Integrators and the render loop they share: passes of samples over image tiles (in parallel
//! with rayon) and over irradiance meters, with every random stream derived from the seed and
//! the pixel (or meter chunk) and pass index, so the image is bit-identical whatever the thread
//! count.
//! Book: "The Neumann series and the path tracer" (path), "Measuring a renderer" (statistics),
//! "Sequential Monte Carlo adaptation" (smc: records merged between passes in tile order).

pub mod bdpt;
pub mod mlt;
pub mod path;
pub mod reach;
pub mod smc;

pub use path::PathTracer;

use rayon::prelude::*;

use crate::film::Film;
use crate::math::Sampler;
use crate::path::{LocalSampling, PLAIN};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// The integrators a user can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IntegratorKind {
    /// Volumetric path tracing with next-event estimation and MIS.
    Path,
    /// Light tracing: light subpaths connected to the sensor (t = 1), splatted.
    Light,
    /// Bidirectional path tracing with MIS over all (s, t).
    Bdpt,
    /// Sequential Monte Carlo adaptation with a B-spline radiance cache (Pegoraro et al. 2008).
    Smc,
    /// Metropolis light transport (film-wide; `spp` counts mutations per pixel).
    Mlt,
}

impl IntegratorKind {
    pub const ALL: &'static [IntegratorKind] = &[
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Smc,
        IntegratorKind::Mlt,
    ];

    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Path => "path",
            IntegratorKind::Light => "light",
            IntegratorKind::Bdpt => "bdpt",
            IntegratorKind::Smc => "smc",
            IntegratorKind::Mlt => "mlt",
        }
    }

    pub fn parse(s: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|k| k.name()).collect();
                format!("unknown integrator `{s}` (available: {})", names.join(", "))
            })
    }

    /// Whether the integrator samples light start points (and so can use the adjoint image).
    pub fn samples_light_starts(self) -> bool {
        matches!(self, Self::Bdpt | Self::Light | Self::Mlt)
    }
}

/// Side of a square image tile.
pub const TILE: u32 = 16;
/// Meter samples per parallel work item.
pub const METER_CHUNK: u64 = 1024;
/// The stream of the path tracer's direct view of delta lights (apart from every pixel's).
const DELTA_VIEW_STREAM: u64 = u64::MAX - 1;
/// Salt that keeps meter streams apart from pixel streams of the same index.
const METER_STREAM_SALT: u64 = 0x6D65_7465_7200_0000;

/// One tile's results: (pixel index, sum, sum of squares) per pixel, splats, its NaN count and
/// its SMC records.
type TileResult = (
    Vec<(usize, [f64; 3], [f64; 3])>,
    Vec<bdpt::Splat>,
    u64,
    Vec<smc::Record>,
);

/// A meter's running statistics.
#[derive(Clone, Debug, Default)]
pub struct MeterAccum {
    pub sum: [f64; 3],
    pub sum_sq: [f64; 3],
    pub samples: u64,
}

/// A meter's estimate with its standard error.
#[derive(Clone, Debug)]
pub struct MeterEstimate {
    pub name: String,
    pub value: Rgb,
    pub stderr: Rgb,
    pub samples: u64,
}

impl MeterAccum {
    pub fn estimate(&self, name: &str) -> MeterEstimate {
        let n = self.samples.max(1) as f64;
        let mut v = [0.0f32; 3];
        let mut e = [0.0f32; 3];
        for c in 0..3 {
            let mean = self.sum[c] / n;
            let var = if self.samples > 1 {
                ((self.sum_sq[c] / n - mean * mean) * n / (n - 1.0)).max(0.0)
            } else {
                0.0
            };
            v[c] = mean as f32;
            e[c] = (var / n).sqrt() as f32;
        }
        MeterEstimate {
            name: name.to_string(),
            value: Rgb::from_array(v),
            stderr: Rgb::from_array(e),
            samples: self.samples,
        }
    }
}

/// Accumulates passes of an integrator over the camera film and the meters.
pub struct Renderer<'a> {
    pub scene: &'a Scene,
    /// The local-sampling technique of every walk and density (plain or enlightened).
    pub technique: &'a dyn LocalSampling,
    pub kind: IntegratorKind,
    pub seed: u64,
    pub tracer: PathTracer,
    /// The bidirectional engine for `light` and `bdpt`.
    pub bdpt: Option<bdpt::Bdpt<'a>>,
    pub film: Option<Film>,
    pub meters: Vec<MeterAccum>,
    /// Passes done so far (each pass has its own random streams).
    pub passes: u64,
    /// Samples that came out NaN or infinite and were dropped (counted as zero).
    pub nan_count: u64,
    /// Camera paths plus meter paths traced.
    pub paths: u64,
    /// Meter samples per pixel sample.
    pub meter_samples: u64,
    /// The SMC state for `smc`: the structure is read-only during a pass, its records are
    /// merged after it.
    pub smc: Option<smc::Smc>,
    /// The Metropolis engine for `mlt`.
    pub mlt: Option<mlt::Mlt<'a>>,
}

impl<'a> Renderer<'a> {
    /// A renderer of `scene` with integrator `kind`.
    ///
    /// # Panics
    /// If the integrator refuses the scene or its settings ([`Renderer::try_new`] returns the
    /// reason instead: use it for scenes a user wrote).
    pub fn new(scene: &'a Scene, kind: IntegratorKind, seed: u64, max_depth: Option<u32>) -> Self {
        Self::try_new(scene, kind, seed, max_depth).unwrap_or_else(|e| panic!("{e}"))
    }

    /// A renderer of `scene` with integrator `kind`, or the reason the integrator refuses the
    /// scene (e.g. MLT without a camera) or the scene's `[render.mlt]` / `[render.smc]`.
    pub fn try_new(
        scene: &'a Scene,
        kind: IntegratorKind,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, String> {
        Self::try_with(scene, &PLAIN, kind, seed, max_depth)
    }

    /// [`Renderer::try_new`] sampling with `technique` (the enlightened one, built by
    /// `enlightened::Enlightened` from the scene) instead of the plain one.
    pub fn try_with(
        scene: &'a Scene,
        technique: &'a dyn LocalSampling,
        kind: IntegratorKind,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<Self, String> {
        let mlt = match kind {
            IntegratorKind::Mlt => Some(mlt::Mlt::new(
                scene,
                technique,
                scene.render.mlt.clone(),
                seed,
                max_depth,
            )?),
            _ => None,
        };
        let smc = match kind {
            IntegratorKind::Smc => Some(smc::Smc::new(scene, scene.render.smc, max_depth)?),
            _ => None,
        };
        let bdpt = match kind {
            IntegratorKind::Path | IntegratorKind::Smc | IntegratorKind::Mlt => None,
            IntegratorKind::Light => Some(bdpt::Bdpt::new(
                scene,
                technique,
                max_depth,
                bdpt::Strategies::LightTracing,
            )),
            IntegratorKind::Bdpt => Some(bdpt::Bdpt::new(
                scene,
                technique,
                max_depth,
                bdpt::Strategies::All,
            )),
        };
        Ok(Renderer {
            scene,
            technique,
            kind,
            seed,
            tracer: PathTracer::new(max_depth),
            mlt,
            bdpt,
            film: scene.camera.as_ref().map(|c| Film::new(c.width, c.height)),
            meters: vec![MeterAccum::default(); scene.sensors.len()],
            passes: 0,
            nan_count: 0,
            paths: 0,
            meter_samples: scene.render.meter_samples as u64,
            smc,
        })
    }

    /// Replaces the SMC settings (before the first pass); an error for invalid settings or
    /// another integrator.
    pub fn with_smc_settings(mut self, settings: smc::SmcSettings) -> Result<Self, String> {
        if self.kind != IntegratorKind::Smc {
            return Err(format!(
                "SMC options apply to the `smc` integrator, not `{}`",
                self.kind.name()
            ));
        }
        let max_depth = Some(self.tracer.max_depth);
        self.smc = Some(smc::Smc::new(self.scene, settings, max_depth)?);
        Ok(self)
    }

    /// Samples per pixel so far.
    pub fn spp(&self) -> u64 {
        self.film.as_ref().map_or(0, |f| f.spp)
    }

    /// Renders one pass of `spp` samples per pixel (and `spp * meter_samples` per meter).
    /// `on_tile` is called after each finished tile (progress bars).
    pub fn pass(&mut self, spp: u32, on_tile: &(dyn Fn() + Sync)) {
        let pass = self.passes;
        self.passes += 1;
        if self.kind == IntegratorKind::Mlt {
            // film-wide: spp mutations per pixel over all chains (meters are not rendered)
            if let (Some(film), Some(engine)) = (self.film.as_mut(), self.mlt.as_mut()) {
                let n = film.width as u64 * film.height as u64 * spp as u64;
                engine.run(self.scene, film, n);
                film.spp += spp as u64;
                self.paths += n;
            }
            on_tile();
            return;
        }
        let scene = self.scene;
        let tracer = self.tracer;
        let bidir = self.bdpt.as_ref();
        let smc_state = self.smc.as_ref();
        let seed = self.seed;
        let mut smc_records: Vec<Vec<smc::Record>> = Vec::new();
        if let (Some(film), Some(cam)) = (self.film.as_mut(), scene.camera.as_ref()) {
            let (w, h) = (cam.width, cam.height);
            let tiles_x = w.div_ceil(TILE);
            let tiles_y = h.div_ceil(TILE);
            let results: Vec<TileResult> = (0..tiles_x * tiles_y)
                .into_par_iter()
                .map(|t| {
                    let (tx, ty) = (t % tiles_x, t / tiles_x);
                    let mut out = Vec::with_capacity((TILE * TILE) as usize);
                    let mut splats = Vec::new();
                    let mut scratch = bdpt::Scratch::default();
                    let mut smc_scratch = smc::Scratch::default();
                    let mut records = Vec::new();
                    let mut nans = 0u64;
                    for y in ty * TILE..((ty + 1) * TILE).min(h) {
                        for x in tx * TILE..((tx + 1) * TILE).min(w) {
                            let index = (y * w + x) as usize;
                            let mut sampler = Sampler::new(seed, index as u64, pass);
                            let mut sum = [0.0f64; 3];
                            let mut sum_sq = [0.0f64; 3];
                            for _ in 0..spp {
                                let raster =
                                    glam::Vec2::new(x as f32, y as f32) + sampler.next_2d();
                                let first_splat = splats.len();
                                let l = match (bidir, smc_state) {
                                    (None, Some(s)) => s.radiance(
                                        scene,
                                        cam.generate_ray(raster),
                                        scene.camera_medium,
                                        &mut sampler,
                                        &mut smc_scratch,
                                        &mut records,
                                    ),
                                    (None, None) => tracer.radiance(
                                        scene,
                                        cam.generate_ray(raster),
                                        scene.camera_medium,
                                        &mut sampler,
                                    ),
                                    (Some(b), _) => {
                                        b.camera_subpath(
                                            scene,
                                            raster,
                                            &mut sampler,
                                            &mut scratch.eye,
                                        );
                                        b.light_subpath(scene, &mut sampler, &mut scratch.light);
                                        b.combine(scene, &scratch, &mut sampler, &mut splats)
                                    }
                                };
                                if !l.is_finite()
                                    || splats[first_splat..].iter().any(|s| !s.1.is_finite())
                                {
                                    nans += 1;
                                    splats.truncate(first_splat);
                                    continue;
                                }
                                for c in 0..3 {
                                    let v = l[c] as f64;
                                    sum[c] += v;
                                    sum_sq[c] += v * v;
                                }
                            }
                            out.push((index, sum, sum_sq));
                        }
                    }
                    on_tile();
                    (out, splats, nans, records)
                })
                .collect();
            for (pixels, splats, nans, records) in results {
                smc_records.push(records);
                self.nan_count += nans;
                for (i, s, q) in pixels {
                    film.add_pixel(i, s, q);
                }
                for (r, l) in splats {
                    film.add_splat(r, l);
                }
            }
            let samples = (w * h) as u64 * spp as u64;
            if bidir.is_some() {
                film.splat_count += samples;
            } else {
                // the path tracer and SMC: the direct image of delta lights, one splat per light
                // standing for the pass's camera samples (BDPT's (1, 1) strategy does this per
                // sample)
                let mut sampler = Sampler::new(seed, DELTA_VIEW_STREAM, pass);
                for (raster, l) in path::delta_light_view(scene, &mut sampler) {
                    film.add_splat(raster, l * samples as f32);
                }
                film.splat_count += samples;
            }
            film.spp += spp as u64;
            self.paths += (w * h) as u64 * spp as u64;
        }
        let per_meter = spp as u64 * self.meter_samples;
        for (mi, meter) in scene.sensors.iter().enumerate() {
            let chunks = per_meter.div_ceil(METER_CHUNK);
            let results: Vec<(MeterAccum, u64, Vec<smc::Record>)> = (0..chunks)
                .into_par_iter()
                .map(|c| {
                    let n = METER_CHUNK.min(per_meter - c * METER_CHUNK);
                    let stream = METER_STREAM_SALT ^ ((mi as u64) << 40) ^ c;
                    let mut sampler = Sampler::new(seed, stream, pass);
                    let mut acc = MeterAccum::default();
                    let mut nans = 0;
                    let mut scratch = bdpt::Scratch::default();
                    let mut splats = Vec::new();
                    let mut smc_scratch = smc::Scratch::default();
                    let mut records = Vec::new();
                    for _ in 0..n {
                        let e = match (bidir, smc_state) {
                            (None, Some(s)) => s.meter_irradiance(
                                scene,
                                meter,
                                &mut sampler,
                                &mut smc_scratch,
                                &mut records,
                            ),
                            (None, None) => tracer.meter_irradiance(scene, meter, &mut sampler),
                            (Some(b), _) => {
                                b.meter_subpath(scene, mi as u32, &mut sampler, &mut scratch.eye);
                                b.light_subpath(scene, &mut sampler, &mut scratch.light);
                                b.combine(scene, &scratch, &mut sampler, &mut splats)
                            }
                        };
                        acc.samples += 1;
                        if !e.is_finite() {
                            nans += 1;
                            continue;
                        }
                        for ch in 0..3 {
                            let v = e[ch] as f64;
                            acc.sum[ch] += v;
                            acc.sum_sq[ch] += v * v;
                        }
                    }
                    (acc, nans, records)
                })
                .collect();
            for (acc, nans, records) in results {
                smc_records.push(records);
                let m = &mut self.meters[mi];
                for ch in 0..3 {
                    m.sum[ch] += acc.sum[ch];
                    m.sum_sq[ch] += acc.sum_sq[ch];
                }
                m.samples += acc.samples;
                self.nan_count += nans;
            }
            self.paths += per_meter;
        }
        // SMC: the pass's records, in tile then meter-chunk order, refine the structure for
        // the next pass [PWP08 Fig. 2 lines 13-14]
        if let Some(s) = self.smc.as_mut() {
            for records in &smc_records {
                s.merge(records);
            }
        }
    }

    /// BDPT's strategies one by one (MIS-weighted, so they sum to the BDPT image): one image per
    /// (s, t) with s + t - 2 <= `max_depth_shown` scattering vertices, a user's favourite
    /// debugging view. One pass of `spp` samples per pixel, deterministic like `pass`.
    pub fn strategy_images(
        &self,
        spp: u32,
        max_depth_shown: u32,
    ) -> std::collections::BTreeMap<(usize, usize), Film> {
        let mut films = std::collections::BTreeMap::new();
        let (Some(b), Some(cam)) = (self.bdpt.as_ref(), self.scene.camera.as_ref()) else {
            return films;
        };
        let scene = self.scene;
        let seed = self.seed;
        let pass = self.passes;
        let (w, h) = (cam.width, cam.height);
        type Row = Vec<(usize, usize, Option<glam::Vec2>, usize, Rgb)>;
        let rows: Vec<Row> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut out = Vec::new();
                let mut scratch = bdpt::Scratch::default();
                for x in 0..w {
                    let index = (y * w + x) as usize;
                    let mut sampler = Sampler::new(seed, index as u64, pass);
                    for _ in 0..spp {
                        let raster = glam::Vec2::new(x as f32, y as f32) + sampler.next_2d();
                        b.camera_subpath(scene, raster, &mut sampler, &mut scratch.eye);
                        b.light_subpath(scene, &mut sampler, &mut scratch.light);
                        for t in 1..=scratch.eye.len() {
                            for s in 0..=bdpt::Bdpt::max_light_vertices(scene, &scratch.light) {
                                let depth = s + t;
                                if depth < 2
                                    || depth - 2 > max_depth_shown as usize
                                    || depth - 2 > b.max_depth as usize
                                {
                                    continue;
                                }
                                if let Some((l, r)) = b.connect(
                                    scene,
                                    &scratch.light,
                                    &scratch.eye,
                                    s,
                                    t,
                                    &mut sampler,
                                ) {
                                    if l.is_finite() {
                                        out.push((s, t, r, index, l));
                                    }
                                }
                            }
                        }
                    }
                }
                out
            })
            .collect();
        for row in rows {
            for (s, t, r, index, l) in row {
                let film = films.entry((s, t)).or_insert_with(|| {
                    let mut f = Film::new(w, h);
                    f.spp = spp as u64;
                    f.splat_count = (w * h) as u64 * spp as u64;
                    f
                });
                match r {
                    Some(r) => film.add_splat(r, l),
                    None => film.add_pixel(index, [l.x as f64, l.y as f64, l.z as f64], [0.0; 3]),
                }
            }
        }
        films
    }

    /// Every meter's estimate.
    pub fn meter_estimates(&self) -> Vec<MeterEstimate> {
        self.scene
            .sensors
            .iter()
            .zip(&self.meters)
            .map(|(s, a)| a.estimate(&s.name))
            .collect()
    }
}
