//! `pathspace render [SCENE] [--integrator I] [--spp N | --time S] [--seed S] [--threads N]
//! [--max-depth D] [-o OUT.exr] [--png OUT.png] [--json]`, and for `--integrator smc`
//! `[--smc-variant is1_cv2] [--smc-threshold T] [--cache-budget BYTES] [--smc-estimator
//! distance|march] [--smc-step MFP]`.

use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

use crate::enlightened::AdjointSettings;
use crate::image_io::{self, ImageMeta};
use crate::integrator::mlt::{mutation::MutationKind, MutationStats};
use crate::integrator::smc::{EstimatorForm, OctreeStats, SmcSettings, Variant};
use crate::integrator::{IntegratorKind, MeterEstimate, Renderer};
use crate::scene::Scene;

#[derive(Args, Debug, Default, Clone)]
pub struct RenderArgs {
    /// Scene file (TOML); without it, the embedded fog box.
    pub scene: Option<PathBuf>,
    /// Integrator (default: the scene's `[render] integrator`).
    #[arg(long)]
    pub integrator: Option<String>,
    /// Samples per pixel (default: the scene's `[render] spp`); for mlt, mutations per pixel.
    #[arg(long, conflicts_with_all = ["time", "mutations_per_pixel"])]
    pub spp: Option<u32>,
    /// Mutations per pixel for `--integrator mlt` (the same count as --spp).
    #[arg(long, conflicts_with = "time")]
    pub mutations_per_pixel: Option<u32>,
    /// MLT: independent chains (default: the scene's `[render.mlt] chains`).
    #[arg(long)]
    pub chains: Option<u32>,
    /// MLT: BDPT pre-pass samples n (default: `[render.mlt] bootstrap`).
    #[arg(long)]
    pub bootstrap: Option<u64>,
    /// MLT: BDPT samples per mutation that keep refining b during the run; 0 keeps the
    /// pre-pass estimate (default: `[render.mlt] b_refine`, 1/32).
    #[arg(long)]
    pub b_refine: Option<f64>,
    /// MLT: mutation selection weights, e.g. `bidirectional=1,sensor=100,light=100`
    /// (unnamed types get 0; default: `[render.mlt]`, all 1).
    #[arg(long)]
    pub mutation_weights: Option<String>,
    /// Render for this many seconds instead of a fixed spp.
    #[arg(long)]
    pub time: Option<f64>,
    /// Random seed (default: the scene's `[render] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Maximum number of scattering vertices (default: unlimited, Russian roulette).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Override the camera resolution, e.g. `64x64` (quick previews, golden images).
    #[arg(long, value_parser = parse_resolution)]
    pub resolution: Option<(u32, u32)>,
    /// Output EXR (default: the scene's name with .exr, in the current directory).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// PNG preview (default: next to the EXR).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// bdpt only: also write each (s, t) strategy's MIS-weighted image to this directory, as
    /// `s{S}-t{T}.exr` and `.png`, for paths of up to `--strategy-depth` scattering vertices.
    #[arg(long)]
    pub strategy_images: Option<PathBuf>,
    /// Deepest strategies written by `--strategy-images` (default 3).
    #[arg(long, default_value_t = 3)]
    pub strategy_depth: u32,
    /// Print one JSON object with the results on stdout instead of the summary line.
    #[arg(long)]
    pub json: bool,
    /// Options of the `smc` integrator (boxed: they are rarely given).
    #[command(flatten)]
    pub smc: Box<SmcArgs>,
    /// Guided local sampling (bdpt, light, mlt).
    #[command(flatten)]
    pub guide: GuideArgs,
    /// Options of the adjoint image (boxed: they are rarely given).
    #[command(flatten)]
    pub adjoint: Box<AdjointArgs>,
}

/// The adjoint image's pre-pass options, shared by `render` and `converge` (`+adjoint` lines);
/// each overrides its `[render.adjoint]` key.
#[derive(Args, Debug, Default, Clone)]
pub struct AdjointTuning {
    /// Adjoint grid COLSxROWS (columns rounded up to a multiple of the area lights; default
    /// `[render.adjoint] resolution` or 64x64).
    #[arg(long, value_parser = parse_resolution)]
    pub adjoint_resolution: Option<(u32, u32)>,
    /// Pre-pass samples (BDPT) or chain steps (Metropolis) per adjoint cell (default
    /// `[render.adjoint] samples_per_cell` or 8).
    #[arg(long)]
    pub adjoint_samples: Option<u32>,
    /// Floor added to every adjoint cell, as a fraction of the mean cell (default 0.5).
    #[arg(long)]
    pub adjoint_epsilon: Option<f32>,
    /// How the pre-pass estimates the cells: `bdpt` (default) or `metropolis` (chains of the
    /// Metropolis particle sampler).
    #[arg(long)]
    pub adjoint_estimator: Option<String>,
}

impl AdjointTuning {
    /// True when any option was given.
    pub fn any(&self) -> bool {
        self.adjoint_resolution.is_some()
            || self.adjoint_samples.is_some()
            || self.adjoint_epsilon.is_some()
            || self.adjoint_estimator.is_some()
    }

    /// `base` with these overrides, checked.
    pub fn apply(&self, base: AdjointSettings) -> Result<AdjointSettings, String> {
        base.overridden(
            self.adjoint_resolution,
            self.adjoint_samples,
            self.adjoint_epsilon,
            self.adjoint_estimator.as_deref(),
        )
    }
}

/// The adjoint image's options (Kristensen 2010, sec. 5.3.1).
#[derive(Args, Debug, Default, Clone)]
pub struct AdjointArgs {
    /// bdpt, light, mlt: sample area-light start points from the adjoint image, estimated by a
    /// BDPT pre-pass first (default: the scene's `[render] adjoint_image`).
    #[arg(long)]
    pub adjoint_image: bool,
    #[command(flatten)]
    pub tuning: AdjointTuning,
    /// Also write the adjoint image's cells as this EXR (and a PNG next to it).
    #[arg(long)]
    pub adjoint_output: Option<PathBuf>,
}

impl AdjointArgs {
    /// The adjoint settings if the image is wanted (flag or scene key): the scene's
    /// `[render.adjoint]` overridden by the options; an error for invalid values, for options
    /// without the image, or for an integrator that samples no light starts.
    pub fn settings(
        &self,
        kind: IntegratorKind,
        scene: &Scene,
    ) -> Result<Option<AdjointSettings>, String> {
        let wanted = self.adjoint_image || scene.render.adjoint_image;
        let given = self.tuning.any() || self.adjoint_output.is_some();
        if !wanted {
            if given {
                return Err("--adjoint-* options need --adjoint-image".into());
            }
            return Ok(None);
        }
        if !kind.samples_light_starts() {
            if self.adjoint_image {
                return Err(format!(
                    "--adjoint-image applies to bdpt, light and mlt (they sample light start points), not `{}`",
                    kind.name()
                ));
            }
            // the scene's key is a default for the integrators it applies to
            return Ok(None);
        }
        self.tuning.apply(scene.render.adjoint).map(Some)
    }
}

/// The options of guided local sampling (Kristensen 2010, sec. 5.3; book chapter
/// "Enlightened local path sampling: guiding"); each overrides its `[render.guide]` key.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct GuideArgs {
    /// Guide directions at `surface`, `volume` (medium) or `both` kinds of vertices, or `off`.
    #[arg(long)]
    pub guide: Option<String>,
    /// Direction map resolution COLSxROWS (default 32x16, the thesis's).
    #[arg(long)]
    pub guide_map: Option<String>,
    /// Regions (k-means centres) per quantity (default 512).
    #[arg(long)]
    pub guide_regions: Option<usize>,
    /// Light and eye subpaths traced for photons and importons (default 200000 each).
    #[arg(long)]
    pub guide_particles: Option<usize>,
    /// c2 of eqs. (5.17)-(5.19), the probability of sampling the map (default 0.5).
    #[arg(long)]
    pub guide_weight: Option<f32>,
    /// alpha of eq. (5.16) per unit length (default 20 / scene radius).
    #[arg(long)]
    pub guide_alpha: Option<f32>,
    /// Guided Russian roulette with this normalization (default: the ordinary roulette).
    #[arg(long)]
    pub guide_roulette: Option<f32>,
    /// Only particles at this depth or deeper shape the maps (default 1: all; 2: indirect
    /// light and importance only).
    #[arg(long)]
    pub guide_min_depth: Option<u32>,
    /// Particle sampler of the guide: `classical` (default), `bidirectional` or `metropolis`.
    #[arg(long)]
    pub guide_sampler: Option<String>,
    /// Metropolis particles: small-step deviation in primary sample space (default 1/64).
    #[arg(long)]
    pub guide_sigma: Option<f64>,
    /// Metropolis particles: weight delta of the defensive part of the target (default 0.1;
    /// 0 is the thesis's eq. (5.15) alone).
    #[arg(long)]
    pub guide_defensive: Option<f64>,
}

impl GuideArgs {
    /// True when any option was given.
    pub fn any(&self) -> bool {
        self.guide.is_some()
            || self.guide_map.is_some()
            || self.guide_regions.is_some()
            || self.guide_particles.is_some()
            || self.guide_weight.is_some()
            || self.guide_alpha.is_some()
            || self.guide_roulette.is_some()
            || self.guide_min_depth.is_some()
            || self.guide_sampler.is_some()
            || self.guide_sigma.is_some()
            || self.guide_defensive.is_some()
    }

    /// The scene's settings with these options applied, each checked.
    pub fn apply(
        &self,
        base: crate::enlightened::GuideSettings,
    ) -> Result<crate::enlightened::GuideSettings, String> {
        use crate::enlightened::{GuideKind, GuideSettings};
        let mut s = base;
        if let Some(k) = &self.guide {
            s.kind = GuideKind::parse(k).map_err(|e| format!("--guide: {e}"))?;
        }
        if let Some(m) = &self.guide_map {
            (s.cols, s.rows) =
                GuideSettings::parse_map(m).map_err(|e| format!("--guide-map: {e}"))?;
        }
        s.check_regions(self.guide_regions)
            .map_err(|e| format!("--guide-regions: {e}"))?;
        if let Some(k) = self.guide_regions {
            s.regions.regions = k;
        }
        s.check_particles(self.guide_particles)
            .map_err(|e| format!("--guide-particles: {e}"))?;
        if let Some(n) = self.guide_particles {
            s.particles = n;
        }
        if let Some(w) = self.guide_weight {
            s.c_guide =
                GuideSettings::check_weight(w).map_err(|e| format!("--guide-weight: {e}"))?;
        }
        if let Some(a) = self.guide_alpha {
            s.regions.alpha =
                GuideSettings::check_alpha(a).map_err(|e| format!("--guide-alpha: {e}"))?;
        }
        if let Some(m) = &self.guide_sampler {
            s.sampler = crate::enlightened::guide::ParticleSampler::parse(m)
                .map_err(|e| format!("--guide-sampler: {e}"))?;
        }
        if let Some(x) = self.guide_sigma {
            s.metropolis.sigma = x;
        }
        if let Some(x) = self.guide_defensive {
            s.metropolis.defensive = x;
        }
        s.metropolis
            .check()
            .map_err(|e| format!("--guide-sigma / --guide-defensive: {e}"))?;
        if let Some(d) = self.guide_min_depth {
            if !(1..=64).contains(&d) {
                return Err(format!("--guide-min-depth {d} must be in 1..=64"));
            }
            s.min_depth = d;
        }
        if let Some(r) = self.guide_roulette {
            s.roulette = Some(
                GuideSettings::check_roulette(r).map_err(|e| format!("--guide-roulette: {e}"))?,
            );
        }
        Ok(s)
    }
}

/// Whether integrator `kind` samples with the guide (the ones built on BDPT's walks).
pub fn guides(kind: IntegratorKind) -> bool {
    matches!(
        kind,
        IntegratorKind::Bdpt | IntegratorKind::Light | IntegratorKind::Mlt
    )
}

/// The options of `--integrator smc`.
#[derive(Args, Debug, Default, Clone)]
pub struct SmcArgs {
    /// SMC: the variant, is0|is1 x cv0|cv1|cv2 (default is1_cv2, the proposed method).
    #[arg(long)]
    pub smc_variant: Option<String>,
    /// SMC: the refinement threshold on the average record count (default 64).
    #[arg(long)]
    pub smc_threshold: Option<f64>,
    /// SMC: memory budget of the structure, bytes or with a KiB/MiB/GiB suffix (default 1GiB).
    #[arg(long, value_parser = parse_bytes)]
    pub cache_budget: Option<usize>,
    /// SMC: `march` (eq. 8-9, the default) or `distance` (eq. 7, Fig. 2).
    #[arg(long)]
    pub smc_estimator: Option<String>,
    /// SMC: the ray-marching step in mean free paths (default 1).
    #[arg(long)]
    pub smc_step: Option<f32>,
}

/// Parses a byte count: `1073741824`, `512MiB`, `1GiB`, `64KiB` (shared with the scene key
/// `[render.smc] cache_budget`).
pub use crate::integrator::smc::parse_bytes;

impl SmcArgs {
    /// The SMC settings: the scene's `[render.smc]` (`base`) overridden by the options; an
    /// error when they are invalid or given to another integrator.
    pub fn smc_settings(
        &self,
        kind: IntegratorKind,
        base: SmcSettings,
    ) -> Result<Option<SmcSettings>, String> {
        let given = self.smc_variant.is_some()
            || self.smc_threshold.is_some()
            || self.cache_budget.is_some()
            || self.smc_estimator.is_some()
            || self.smc_step.is_some();
        if kind != IntegratorKind::Smc {
            if given {
                return Err(format!(
                    "--smc-* and --cache-budget apply to --integrator smc, not `{}`",
                    kind.name()
                ));
            }
            return Ok(None);
        }
        let mut s = base;
        if let Some(v) = &self.smc_variant {
            s.variant = Variant::parse(v)?;
        }
        if let Some(t) = self.smc_threshold {
            s.threshold = t;
        }
        if let Some(b) = self.cache_budget {
            s.budget = b;
        }
        // the step of the scene's march form carries over unless --smc-step replaces it
        let base_step = match base.form {
            EstimatorForm::RayMarching { step } => Some(step),
            EstimatorForm::Distance => None,
        };
        let estimator = self.smc_estimator.as_deref().unwrap_or(base.form.name());
        if self.smc_step.is_some() && estimator != "march" {
            return Err(format!(
                "--smc-step applies to the march estimator, not `{estimator}`"
            ));
        }
        s.form = EstimatorForm::parse(estimator, self.smc_step.or(base_step))?;
        Ok(Some(s))
    }
}

/// Parses `WxH`.
pub fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WIDTHxHEIGHT, e.g. 64x64"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| format!("`{v}` in `{s}` is not a size in 1..=16384"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// Everything a render produced.
pub struct RenderResult {
    pub integrator: String,
    pub spp: u64,
    pub seconds: f64,
    pub paths: u64,
    pub nan_count: u64,
    /// Pixels whose estimate is negative in some channel: radiance never is, so each one is an
    /// estimator excursion (SMC's control variates before they converge) or a bug; the image's
    /// finite garbage that `nan_count` cannot see.
    pub negative_pixels: u64,
    pub image: Option<image_io::Image>,
    pub meters: Vec<MeterEstimate>,
    /// relMSE expected from the image's own per-pixel variance (no reference needed); None
    /// without a camera. See `measure::stats::estimated_relmse`.
    pub estimated_relmse: Option<f64>,
    /// The SMC structure's statistics after the render (Pegoraro et al. Table 1).
    pub smc_stats: Option<OctreeStats>,
    /// MLT: b of the pre-pass and each mutation type's counts.
    pub mlt: Option<(f64, Vec<(MutationKind, MutationStats)>)>,
}

impl RenderResult {
    pub fn paths_per_second(&self) -> f64 {
        self.paths as f64 / self.seconds.max(1e-9)
    }
}

/// Samples per pixel in one pass of a fixed-spp render (smaller passes: finer progress).
const PASS_SPP: u32 = 4;

/// Renders `scene`; with `time` the passes go on until the time is used.
#[allow(clippy::too_many_arguments)]
pub fn render_scene(
    scene: &Scene,
    kind: IntegratorKind,
    spp: u32,
    time: Option<f64>,
    seed: u64,
    max_depth: Option<u32>,
    progress: bool,
) -> RenderResult {
    render_scene_with(
        scene,
        &crate::path::PLAIN,
        kind,
        None,
        spp,
        time,
        seed,
        max_depth,
        progress,
    )
    .expect("the default SMC settings are valid")
}

/// [`render_scene`] with SMC settings (for `smc`; `None`: the defaults) and the local-sampling
/// technique `technique` (plain, or the enlightened one the preprocessing built).
#[allow(clippy::too_many_arguments)]
pub fn render_scene_with(
    scene: &Scene,
    technique: &dyn crate::path::LocalSampling,
    kind: IntegratorKind,
    smc: Option<SmcSettings>,
    spp: u32,
    time: Option<f64>,
    seed: u64,
    max_depth: Option<u32>,
    progress: bool,
) -> Result<RenderResult, String> {
    let mut r = Renderer::try_with(scene, technique, kind, seed, max_depth)?;
    if let Some(settings) = smc {
        r = r.with_smc_settings(settings)?;
    }
    let tiles = scene.camera.as_ref().map_or(1, |c| {
        (c.width.div_ceil(crate::integrator::TILE) * c.height.div_ceil(crate::integrator::TILE))
            as u64
    });
    let bar = if progress {
        let total = match time {
            Some(_) => 0,
            None => spp.div_ceil(PASS_SPP) as u64 * tiles,
        };
        let b = if total > 0 {
            indicatif::ProgressBar::new(total)
        } else {
            indicatif::ProgressBar::new_spinner()
        };
        b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} tiles {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(b)
    } else {
        None
    };
    let tick = || {
        if let Some(b) = &bar {
            b.inc(1)
        }
    };
    let start = Instant::now();
    match time {
        Some(budget) => {
            while start.elapsed().as_secs_f64() < budget || r.passes == 0 {
                r.pass(1, &tick);
                if let Some(b) = &bar {
                    b.set_message(format!("{} spp", r.spp()));
                }
            }
        }
        None => {
            let mut done = 0;
            while done < spp {
                let n = PASS_SPP.min(spp - done);
                r.pass(n, &tick);
                done += n;
            }
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let spp_done = if scene.camera.is_some() {
        r.spp()
    } else {
        r.passes
    };
    let image = r.film.as_ref().map(|f| f.image());
    let negative_pixels = image.as_ref().map_or(0, |img| {
        img.pixels.iter().filter(|p| p.min_element() < 0.0).count() as u64
    });
    Ok(RenderResult {
        integrator: match &r.smc {
            Some(s) => format!(
                "smc ({}, {})",
                s.settings.variant.name(),
                s.settings.form.name()
            ),
            None => kind.name().to_string(),
        },
        spp: if time.is_some() { spp_done } else { spp as u64 },
        seconds,
        paths: r.paths,
        nan_count: r.nan_count,
        negative_pixels,
        image,
        meters: r.meter_estimates(),
        estimated_relmse: if kind == IntegratorKind::Mlt {
            None // the per-pixel variance of splats is not recorded
        } else {
            r.film.as_ref().and_then(|f| {
                crate::measure::stats::estimated_relmse(&f.image(), &f.variance_of_mean()).ok()
            })
        },
        mlt: r.mlt.as_ref().map(|m| (m.b, m.report())),
        smc_stats: r.smc.as_ref().map(|s| s.stats()),
    })
}

fn mlt_json(m: &(f64, Vec<(MutationKind, MutationStats)>)) -> serde_json::Value {
    let mut muts = serde_json::Map::new();
    for (k, st) in &m.1 {
        muts.insert(
            k.name().to_string(),
            serde_json::json!({"attempted": st.attempted, "proposed": st.proposed,
                "accepted": st.accepted, "acceptance_rate": st.acceptance_rate()}),
        );
    }
    serde_json::json!({"b": m.0, "mutations": muts})
}

fn rgb_json(c: glam::Vec3) -> serde_json::Value {
    serde_json::json!([c.x, c.y, c.z])
}

pub fn run(args: RenderArgs) -> Result<(), String> {
    let (mut scene, source) = super::load_scene(args.scene.as_deref())?;
    if let Some((w, h)) = args.resolution {
        let cam = scene
            .camera
            .as_ref()
            .ok_or("--resolution needs a scene with a camera")?;
        scene.camera = cam.with_resolution(w, h);
    }
    let kind = IntegratorKind::parse(
        args.integrator
            .as_deref()
            .unwrap_or(&scene.render.integrator),
    )?;
    if let Some(c) = args.chains {
        scene.render.mlt.chains = c;
    }
    if let Some(n) = args.bootstrap {
        scene.render.mlt.bootstrap = n;
    }
    if let Some(r) = args.b_refine {
        scene.render.mlt.b_refine = r;
    }
    if let Some(w) = &args.mutation_weights {
        scene.render.mlt.weights = crate::integrator::mlt::MltSettings::parse_weights(w)?;
    }
    if kind == IntegratorKind::Mlt {
        scene.render.mlt.validate()?;
        crate::integrator::mlt::check_scene(&scene)?;
    } else if args.mutations_per_pixel.is_some() {
        return Err("--mutations-per-pixel needs --integrator mlt".into());
    }
    // light paths this integrator cannot sample: said once, before the work
    if let Some(w) = crate::integrator::reach::unreachable_paths(&scene, kind) {
        eprintln!("warning: {w}");
    }
    let spp = args
        .mutations_per_pixel
        .or(args.spp)
        .unwrap_or(scene.render.spp);
    if spp == 0 {
        return Err("--spp must be at least 1".into());
    }
    if let Some(t) = args.time {
        if !(t > 0.0 && t.is_finite()) {
            return Err(format!("--time {t} must be a positive number of seconds"));
        }
    }
    let smc = args.smc.smc_settings(kind, scene.render.smc)?;
    if let Some(w) = smc.and_then(|s| crate::integrator::smc::anisotropy_warning(&scene, s.variant))
    {
        eprintln!("warning: {w}");
    }
    let seed = args.seed.unwrap_or(scene.render.seed);
    scene.render.guide = args.guide.apply(scene.render.guide)?;
    if scene.render.guide.kind != crate::enlightened::GuideKind::Off && !guides(kind) {
        return Err(format!(
            "guiding (--guide or [render.guide] vertices) applies to bdpt, light and mlt, not `{}`",
            kind.name()
        ));
    }
    let max_depth = args.max_depth.or(scene.render.max_depth);
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = args.threads {
        if t == 0 {
            return Err("--threads must be at least 1".into());
        }
        pool = pool.num_threads(t);
    }
    let pool = pool
        .build()
        .map_err(|e| format!("cannot start worker threads: {e}"))?;
    // the enlightened technique, built as a preprocessing stage: the adjoint image first (its
    // pre-pass samples with the plain technique), then the guide (its particles start from
    // the adjoint image when there is one)
    let mut technique = crate::enlightened::Enlightened::default();
    let adjoint = match args.adjoint.settings(kind, &scene)? {
        Some(settings) => {
            let stats =
                pool.install(|| technique.install_adjoint(&scene, &settings, seed, max_depth))?;
            let image = technique
                .adjoint
                .as_ref()
                .ok_or("the adjoint image was not installed")?;
            if !args.json {
                eprintln!(
                    "adjoint image: {}x{} cells over {} area lights, {} pre-pass samples in {:.2} s, {} empty cells (floor eps = {:.3e})",
                    image.cols,
                    image.rows,
                    image.map.len(),
                    stats.samples,
                    stats.seconds,
                    stats.zero_cells,
                    image.epsilon
                );
            }
            if let Some(out) = &args.adjoint.adjoint_output {
                let img = image.to_image();
                let mut meta = ImageMeta::default();
                meta.set(
                    "adjoint_image",
                    "cells: I* + eps, columns along u1 (light strips)",
                )
                .set("seed", seed)
                .set("scene_hash", format!("{:016x}", source.hash()));
                image_io::write_exr(out, &img, &meta).map_err(|e| e.to_string())?;
                image_io::write_png(&out.with_extension("png"), &img).map_err(|e| e.to_string())?;
            }
            Some(image.stats)
        }
        None => None,
    };
    // the preprocessing pass of guided sampling (Kristensen 2010 Table 5.1's statistics)
    let guide_stats = pool.install(|| technique.install_guide(&scene, seed));
    if let (Some(g), false) = (&guide_stats, args.json) {
        eprint!("{}", g.table());
    }
    if let Some(dir) = &args.strategy_images {
        if kind != IntegratorKind::Bdpt {
            return Err("--strategy-images needs --integrator bdpt".into());
        }
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let renderer =
            crate::integrator::Renderer::try_with(&scene, &technique, kind, seed, max_depth)?;
        let films = pool.install(|| renderer.strategy_images(spp, args.strategy_depth));
        for ((s, t), film) in &films {
            let img = film.image();
            let base = dir.join(format!("s{s}-t{t}"));
            let mut meta = ImageMeta::default();
            meta.set(
                "integrator",
                format!("bdpt strategy s={s} t={t} (MIS-weighted)"),
            )
            .set("spp", spp)
            .set("seed", seed)
            .set("scene_hash", format!("{:016x}", source.hash()));
            image_io::write_exr(&base.with_extension("exr"), &img, &meta)
                .map_err(|e| e.to_string())?;
            image_io::write_png(&base.with_extension("png"), &img).map_err(|e| e.to_string())?;
        }
        if !args.json {
            eprintln!("wrote {} strategy images to {}", films.len(), dir.display());
        }
    }
    let result = pool.install(|| {
        render_scene_with(
            &scene, &technique, kind, smc, spp, args.time, seed, max_depth, !args.json,
        )
    })?;

    let stem = args
        .scene
        .as_ref()
        .and_then(|p| p.file_stem())
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "fog-box".into());
    let mut written = Vec::new();
    if let Some(image) = &result.image {
        let exr = args
            .output
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("{stem}.exr")));
        let png = args
            .png
            .clone()
            .unwrap_or_else(|| exr.with_extension("png"));
        let mut meta = ImageMeta::default();
        meta.set("integrator", &result.integrator)
            .set("spp", result.spp)
            .set("seed", seed)
            .set("seconds", format!("{:.3}", result.seconds))
            .set("scene", &source.name)
            .set("scene_hash", format!("{:016x}", source.hash()))
            .set("nan_count", result.nan_count)
            .set("negative_pixels", result.negative_pixels);
        if let Some(g) = &guide_stats {
            let gs = scene.render.guide;
            meta.set(
                "guide",
                format!(
                    "{} map {}x{} regions {} particles {} weight {} preprocessing {:.3} s",
                    gs.kind.name(),
                    gs.cols,
                    gs.rows,
                    gs.regions.regions,
                    gs.particles,
                    gs.c_guide,
                    g.seconds()
                ),
            );
        }
        image_io::write_exr(&exr, image, &meta).map_err(|e| e.to_string())?;
        image_io::write_png(&png, image).map_err(|e| e.to_string())?;
        written.push(exr.display().to_string());
        written.push(png.display().to_string());
    }
    if result.negative_pixels > 0 {
        eprintln!(
            "warning: {} pixels have a negative estimate (radiance is never negative): the \
             estimator has not converged there{}",
            result.negative_pixels,
            if kind == IntegratorKind::Smc {
                " (SMC's control variates: more samples per pixel, or --smc-variant is1_cv0)"
            } else {
                ""
            }
        );
    }
    let mean = result.image.as_ref().map(|i| i.mean());
    if args.json {
        let sensors: Vec<serde_json::Value> = result
            .meters
            .iter()
            .map(|m| serde_json::json!({"name": m.name, "value": rgb_json(m.value), "stderr": rgb_json(m.stderr), "samples": m.samples}))
            .collect();
        let out = serde_json::json!({
            "integrator": result.integrator,
            "spp": result.spp,
            "seconds": result.seconds,
            "paths_per_second": result.paths_per_second(),
            "mean": mean.map(rgb_json),
            "nan_count": result.nan_count,
            "negative_pixels": result.negative_pixels,
            "estimated_relmse": result.estimated_relmse,
            "sensors": sensors,
            "outputs": written,
            "smc": result.smc_stats.as_ref().map(|s| serde_json::json!({
                "refinement_threshold": s.threshold,
                "max_depth": s.max_depth,
                "nodes": s.nodes,
                "leaves": s.leaves,
                "cells": s.cells,
                "bytes": s.bytes,
                "budget": s.budget,
                "budget_reached": s.budget_reached,
                "records": s.records,
            })),
            "mlt": result.mlt.as_ref().map(mlt_json),
            "guide": guide_stats.as_ref().map(|g| serde_json::json!({
                "vertices": scene.render.guide.kind.name(),
                "map": [g.map.0, g.map.1],
                "photons": g.photons,
                "importons": g.importons,
                "regions_radiance": [g.regions_radiance.0, g.regions_radiance.1],
                "regions_importance": [g.regions_importance.0, g.regions_importance.1],
                "bytes_radiance": g.bytes_radiance,
                "bytes_importance": g.bytes_importance,
                "seconds_particles": g.seconds_particles,
                "seconds_build": g.seconds_build,
            })),
            "adjoint": adjoint.map(|a| serde_json::json!({
                "samples": a.samples,
                "seconds": a.seconds,
                "zero_cells": a.zero_cells,
            })),
        });
        println!("{out}");
    } else {
        let mean = mean.map_or("no camera".to_string(), |m| {
            format!("mean pixel ({:.4}, {:.4}, {:.4})", m.x, m.y, m.z)
        });
        println!(
            "{}: {} spp in {:.2} s, {:.3e} paths/s, {}, {} NaN/inf{}",
            result.integrator,
            result.spp,
            result.seconds,
            result.paths_per_second(),
            mean,
            result.nan_count,
            if written.is_empty() {
                String::new()
            } else {
                format!(" -> {}", written.join(", "))
            }
        );
        if let Some((b, stats)) = &result.mlt {
            println!("  mlt: b = {b:.5}");
            for (k, st) in stats {
                println!(
                    "  mutation {:<13} attempted {:>10} proposed {:>10} accepted {:>10} acceptance {:.4}",
                    k.name(),
                    st.attempted,
                    st.proposed,
                    st.accepted,
                    st.acceptance_rate()
                );
            }
        }
        for m in &result.meters {
            println!(
                "  sensor {}: ({:.5}, {:.5}, {:.5}) +- ({:.5}, {:.5}, {:.5}) [{} samples]",
                m.name,
                m.value.x,
                m.value.y,
                m.value.z,
                m.stderr.x,
                m.stderr.y,
                m.stderr.z,
                m.samples
            );
        }
        if let Some(s) = &result.smc_stats {
            println!("  {s}");
        }
    }
    Ok(())
}
