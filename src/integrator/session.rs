//! A render session: the preprocessing stages a render asks for (the adjoint image's pre-pass,
//! Kristensen 2010 sec. 5.3.1, then the guide's particles and regions, sec. 5.3), each timed
//! and shown, then the passes of the integrator over the film and the meters until the sample
//! count or the time is used, and what the render produced.
//! Book: "Measuring a renderer" (the passes and their statistics).

use std::time::Instant;

use super::{IntegratorError, IntegratorKind, MeterEstimate, Renderer, Setup, Statistics};
use crate::enlightened::adjoint::AdjointStats;
use crate::enlightened::guide::GuideStats;
use crate::enlightened::{AdjointSettings, Enlightened, GuideKind, GuideSettings};
use crate::image_io;
use crate::scene::Scene;

/// One timed preprocessing stage.
#[derive(Clone, Debug)]
pub struct Stage {
    pub name: &'static str,
    pub seconds: f64,
}

/// What was built before the passes, with each stage's time.
#[derive(Clone, Debug, Default)]
pub struct Preprocessed {
    /// The local-sampling technique the stages built (plain where neither stage ran).
    pub technique: Enlightened,
    /// The adjoint image's pre-pass (the statistics the pre-pass returned).
    pub adjoint: Option<AdjointStats>,
    /// The guide's preprocessing (Kristensen 2010 Table 5.1's statistics).
    pub guide: Option<GuideStats>,
    pub stages: Vec<Stage>,
}

/// Runs the preprocessing stages on `scene`: the adjoint image when `adjoint` is given,
/// then the guide when `guide` guides any vertices (its particles are traced with the
/// adjoint image's light starts). With `show`, each stage's time is printed to stderr.
pub fn preprocess(
    scene: &Scene,
    adjoint: Option<&AdjointSettings>,
    guide: &GuideSettings,
    seed: u64,
    max_depth: Option<u32>,
    show: bool,
) -> Result<Preprocessed, IntegratorError> {
    let mut out = Preprocessed::default();
    if let Some(settings) = adjoint {
        let t0 = Instant::now();
        out.adjoint = Some(
            out.technique
                .install_adjoint(scene, settings, seed, max_depth)?,
        );
        out.stages.push(Stage {
            name: "adjoint image",
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    if guide.kind != GuideKind::Off {
        let t0 = Instant::now();
        out.guide = out.technique.install_guide(scene, guide, seed);
        out.stages.push(Stage {
            name: "guide",
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    if show {
        for s in &out.stages {
            eprintln!("preprocessing: {} in {:.2} s", s.name, s.seconds);
        }
    }
    Ok(out)
}

/// A render's passes: the integrator, the setup, and how long to render.
#[derive(Clone, Copy)]
pub struct Job<'s> {
    pub kind: IntegratorKind,
    pub setup: Setup<'s, 's>,
    /// Samples per pixel (for mlt, mutations per pixel); with `time`, ignored.
    pub spp: u32,
    /// Render for this many seconds instead.
    pub time: Option<f64>,
    /// Show a progress bar on stderr.
    pub progress: bool,
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
    /// The variance of each pixel's mean, where the integrator estimates it (not MLT's splats):
    /// the relMSE expected without a reference (`measure::stats::estimated_relmse`).
    pub variance_of_mean: Option<image_io::Image>,
    /// What the integrator reports (SMC's structure, MLT's b and mutation counts).
    pub statistics: Statistics,
}

impl RenderResult {
    pub fn paths_per_second(&self) -> f64 {
        self.paths as f64 / self.seconds.max(1e-9)
    }
}

/// Samples per pixel in one pass of a fixed-spp render (smaller passes: finer progress).
pub const PASS_SPP: u32 = 4;

/// Renders the job: passes of [`PASS_SPP`] (or of 1 spp until the time is used).
pub fn render(job: &Job) -> Result<RenderResult, IntegratorError> {
    let mut r = Renderer::prepared(job.kind, &job.setup)?;
    let bar = job.progress.then(|| progress_bar(job));
    let tick = || {
        if let Some(b) = &bar {
            b.inc(1)
        }
    };
    let start = Instant::now();
    match job.time {
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
            while done < job.spp {
                let n = PASS_SPP.min(job.spp - done);
                r.pass(n, &tick);
                done += n;
            }
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    Ok(result(&r, job, seconds))
}

/// The progress bar of a job: tiles of every pass, or a spinner for a timed render.
fn progress_bar(job: &Job) -> indicatif::ProgressBar {
    let tiles = job.setup.scene.camera.as_ref().map_or(1, |c| {
        (c.width.div_ceil(super::TILE) * c.height.div_ceil(super::TILE)) as u64
    });
    let total = match job.time {
        Some(_) => 0,
        None => job.spp.div_ceil(PASS_SPP) as u64 * tiles,
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
    b
}

/// What the finished renderer holds, as a [`RenderResult`].
fn result(r: &Renderer, job: &Job, seconds: f64) -> RenderResult {
    let spp_done = if job.setup.scene.camera.is_some() {
        r.spp()
    } else {
        r.passes
    };
    let image = r.film.as_ref().map(|f| f.image());
    let negative_pixels = image.as_ref().map_or(0, |img| {
        img.pixels.iter().filter(|p| p.min_element() < 0.0).count() as u64
    });
    RenderResult {
        integrator: r.integrator.label(),
        spp: if job.time.is_some() {
            spp_done
        } else {
            job.spp as u64
        },
        seconds,
        paths: r.paths,
        nan_count: r.nan_count,
        negative_pixels,
        image,
        meters: r.meter_estimates(),
        variance_of_mean: if r.integrator.pixel_variance() {
            r.film.as_ref().map(|f| f.variance_of_mean())
        } else {
            None
        },
        statistics: r.integrator.statistics(),
    }
}
