//! A render session: the preprocessing stages a render asks for (the adjoint image's pre-pass,
//! Kristensen 2010 sec. 5.3.1, then the guide's particles and regions, sec. 5.3), each timed
//! and shown, then the passes of the integrator over the film and the meters until the sample
//! count or the time is used, and what the render produced.
//! Book: "Measuring a renderer" (the passes and their statistics).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use super::checkpoint::{Checkpoint, CheckpointError, Earlier, Identity, Progress, Recipe};
use super::plan;
use super::provenance::Streams;
use super::RenderError;

use crate::enlightened::adjoint::AdjointStats;
use crate::enlightened::guide::GuideStats;
use crate::enlightened::{AdjointSettings, Enlightened, GuideKind, GuideSettings};
use crate::film::Film;
use crate::image_io;
use crate::integrator::{
    IntegratorError, IntegratorKind, MeterEstimate, Renderer, Setup, Statistics,
};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// One timed preprocessing stage.
#[derive(Clone, Debug)]
pub struct Stage {
    pub name: String,
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
        let technique = &mut out.technique;
        let (stats, s) = stage("adjoint image (BDPT pre-pass)", show, || {
            technique.install_adjoint(scene, settings, seed, max_depth)
        });
        out.adjoint = Some(stats?);
        out.stages.push(s);
    }
    if guide.kind != GuideKind::Off {
        let technique = &mut out.technique;
        let (stats, s) = stage("guide (particles and regions)", show, || {
            technique.install_guide(scene, guide, seed)
        });
        out.guide = stats;
        out.stages.push(s);
    }
    Ok(out)
}

/// Runs `work` as the preprocessing stage `name`: with `show`, its name is printed when it
/// starts and its time when it ends (a stage may take minutes, with no bar meanwhile).
pub fn stage<T>(name: &str, show: bool, work: impl FnOnce() -> T) -> (T, Stage) {
    if show {
        eprintln!("preprocessing: {name} ...");
    }
    let t0 = Instant::now();
    let out = work();
    let seconds = t0.elapsed().as_secs_f64();
    if show {
        eprintln!("preprocessing: {name} done in {seconds:.2} s");
    }
    (
        out,
        Stage {
            name: name.to_string(),
            seconds,
        },
    )
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
    /// The pass the render starts at (a shard's first pass; 0 for a whole render): pass p
    /// draws the streams `Sampler::new(seed, pixel, p)`.
    pub first_pass: u64,
    /// Show a progress bar on stderr.
    pub progress: bool,
}

/// Everything a render produced.
pub struct RenderResult {
    pub integrator: String,
    /// Samples per pixel done (mutations per pixel for MLT; passes' samples for meters).
    pub spp: u64,
    /// Whether every sample asked for was done (false: stopped by a signal, or a checkpoint).
    pub complete: bool,
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
    /// The sample streams the image holds (its provenance): the seed and the passes of each
    /// run, MLT's earlier runs first.
    pub streams: Vec<Streams>,
}

impl RenderResult {
    pub fn paths_per_second(&self) -> f64 {
        self.paths as f64 / self.seconds.max(1e-9)
    }
}

/// How a render may be stopped, saved and continued (none of it by default).
#[derive(Default)]
pub struct Control<'c> {
    /// Set to a signal's number by its handler: the render ends after the pass in flight.
    pub stop: Option<&'c AtomicUsize>,
    /// Seconds between checkpoints (each one handed to `on_checkpoint`).
    pub every: Option<f64>,
    /// What a checkpoint must match to be resumed; needed to make checkpoints.
    pub identity: Option<Identity>,
    /// How the render was asked for, kept in every checkpoint (`--resume FILE` alone repeats it).
    pub recipe: Option<Recipe>,
    /// Continue from this checkpoint (its identity checked by the caller).
    pub resume: Option<Checkpoint>,
    /// Writes a periodic checkpoint and the image so far.
    #[allow(clippy::type_complexity)]
    pub on_checkpoint: Option<
        &'c mut (dyn FnMut(&RenderResult, &Checkpoint) -> Result<(), CheckpointError> + Send),
    >,
    /// Called after every pass with how far the render is and the image so far on demand
    /// (asking for it copies the film): a view that only reads, so the render is the same with
    /// or without it, and whose time the render's seconds leave out (a study's metrics cost
    /// the integrator nothing).
    pub on_pass: Option<&'c mut (dyn FnMut(&PassView) + Send)>,
}

/// What the session shows after a pass.
pub struct PassView<'v> {
    /// Samples per pixel done (mutations per pixel for MLT).
    pub spp: u64,
    /// The render's seconds so far (the preprocessing and these views left out): the number
    /// a timed render compares with its time.
    pub seconds: f64,
    /// The image so far (asking for it copies the film).
    pub image: &'v dyn Fn() -> Option<image_io::Image>,
}

/// How a render ended.
pub struct Ended {
    pub result: RenderResult,
    /// The signal that stopped it before its samples were done.
    pub stopped_by: Option<i32>,
    /// Its state, when a checkpoint identity was given.
    pub checkpoint: Option<Checkpoint>,
}

/// Renders the job: passes of [`plan::PASS_SPP`] (or of 1 spp until the time is used).
pub fn render(job: &Job) -> Result<RenderResult, RenderError> {
    Ok(render_with(job, Control::default())?.result)
}

/// Renders the job under `control`: resumed from a checkpoint, checkpointed every so many
/// seconds, stopped by a signal after the pass in flight.
pub fn render_with(job: &Job, mut control: Control) -> Result<Ended, RenderError> {
    let (mut r, mut progress, earlier) = start(job, control.resume.take())?;
    // a bar on a terminal; lines in a log file or a pipe (a batch job's output)
    let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let bar = (job.progress && terminal).then(|| progress_bar(job, progress.spp));
    let mut log = (job.progress && !terminal).then(ProgressLog::default);
    let tick = || {
        if let Some(b) = &bar {
            b.inc(1)
        }
    };
    let start = Instant::now();
    // the render's clock: the time since the start less the views' (`on_pass`)
    let mut viewing = 0.0;
    let clock = |viewing: f64| start.elapsed().as_secs_f64() - viewing;
    // counted in the render's time, as when the first pass did it
    if let Some(name) = r.integrator.pending_stage() {
        let scene = job.setup.scene;
        let mut run = || stage(&name, job.progress, || r.integrator.run_stage(scene));
        match &bar {
            Some(b) => b.suspend(run),
            None => run(),
        };
    }
    let prior_seconds = progress.seconds;
    progress.seconds = prior_seconds + clock(viewing);
    let first_spp = progress.spp;
    let mut last_checkpoint = Instant::now();
    let stop = || control.stop.map_or(0, |s| s.load(Ordering::SeqCst));
    let mut stopped_by = None;
    loop {
        // a timed render compares the seconds the last view was shown with its time
        let spp = match job.time {
            Some(budget) if progress.seconds < budget => 1,
            Some(_) if r.passes == 0 && progress.spp == 0 => 1,
            Some(_) => break,
            None => match plan::next_pass_spp(progress.spp, job.spp) {
                Some(spp) => spp,
                None => break,
            },
        };
        if stop() != 0 {
            stopped_by = Some(stop() as i32);
            break;
        }
        r.pass(spp, &tick);
        progress.spp += spp as u64;
        progress.seconds = prior_seconds + clock(viewing);
        if bar.is_some() || log.is_some() {
            let pixels = job
                .setup
                .scene
                .camera
                .as_ref()
                .map_or(0, |c| c.width * c.height);
            let elapsed = clock(viewing);
            let rate = ((progress.spp - first_spp) * pixels as u64) as f64 / elapsed;
            let message = progress_message(
                progress.spp,
                job.time.is_none().then_some(job.spp),
                (pixels > 0 && elapsed > 0.0).then_some(rate),
                job.time.map(|t| t - progress.seconds),
            );
            match (&bar, &mut log) {
                (Some(b), _) => b.set_message(message),
                (None, Some(l)) => {
                    let run = (progress.spp - first_spp, elapsed);
                    l.pass(&message, progress.spp, run, job)
                }
                (None, None) => {}
            }
        }
        let due = control
            .every
            .is_some_and(|e| last_checkpoint.elapsed().as_secs_f64() >= e);
        if let (true, Some(id), Some(write)) =
            (due, &control.identity, control.on_checkpoint.as_mut())
        {
            let c = snapshot(
                &r,
                (id, control.recipe.as_ref()),
                &progress,
                earlier.as_ref(),
            );
            // a full disk now may have room at the next checkpoint: warn and render on
            if let Err(e) = write(&result(&r, job, &progress, earlier.as_ref()), &c) {
                let warning = format!(
                    "warning: {e}; the render goes on and tries again at the next checkpoint"
                );
                match &bar {
                    Some(b) => b.suspend(|| eprintln!("{warning}")),
                    None => eprintln!("{warning}"),
                }
            }
            last_checkpoint = Instant::now();
        }
        if let Some(show) = control.on_pass.as_mut() {
            let shown = Instant::now();
            show(&PassView {
                spp: progress.spp,
                seconds: progress.seconds,
                image: &|| image(&r, job, earlier.as_ref()),
            });
            viewing += shown.elapsed().as_secs_f64();
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    progress.seconds = prior_seconds + clock(viewing);
    let checkpoint = control.identity.as_ref().map(|id| {
        snapshot(
            &r,
            (id, control.recipe.as_ref()),
            &progress,
            earlier.as_ref(),
        )
    });
    Ok(Ended {
        result: result(&r, job, &progress, earlier.as_ref()),
        stopped_by,
        checkpoint,
    })
}

/// Sets `r` to continue with pass `pass` of `job`, and its film positions with that pass's
/// first sample: passes of [`plan::PASS_SPP`] samples before it, or of 1 in a timed render.
fn start_at(r: &mut Renderer, job: &Job, pass: u64) {
    r.passes = pass;
    r.samples = match job.time {
        Some(_) => pass,
        None => pass * plan::PASS_SPP as u64,
    };
}

/// The renderer of a job, and how far it is: new, or continued from a checkpoint. MLT's run
/// is not continued: a new independent run starts, and the saved image joins the earlier ones.
fn start<'s>(
    job: &Job<'s>,
    resume: Option<Checkpoint>,
) -> Result<(Renderer<'s>, Progress, Option<Earlier>), RenderError> {
    let Some(c) = resume else {
        let mut r = Renderer::prepared(job.kind, &job.setup)?;
        start_at(&mut r, job, job.first_pass);
        return Ok((r, Progress::default(), None));
    };
    if job.time.is_none() && c.progress.spp > job.spp as u64 {
        return Err(CheckpointError::TooFar(c.progress.spp, job.spp).into());
    }
    let mut progress = c.progress.clone();
    let mut r = Renderer::prepared(job.kind, &job.setup)?;
    if r.integrator.resumes_exactly() {
        r.integrator
            .restore_state(c.state.as_deref())
            .map_err(|why| CheckpointError::BadState("being resumed".into(), why))?;
        r.film = c.film;
        r.meters = c.meters;
        start_at(&mut r, job, progress.passes);
        r.nan_count = progress.nan_count;
        r.paths = progress.paths;
        return Ok((r, progress, None));
    }
    progress.resumes += 1;
    let seed = Checkpoint::resume_seed(job.setup.seed, progress.resumes);
    let setup = Setup { seed, ..job.setup };
    let mut r = Renderer::prepared(job.kind, &setup)?;
    start_at(&mut r, job, job.first_pass);
    progress.passes = job.first_pass;
    if job.progress {
        eprintln!(
            "resuming {} as an independent run with seed {seed}, merged with the {} spp saved",
            job.kind.name(),
            progress.spp
        );
    }
    Ok((r, progress, Some(merged(&c, job.first_pass))))
}

/// The earlier runs of a checkpoint with its own run folded in (MLT), its run having started
/// at pass `first`.
fn merged(c: &Checkpoint, first: u64) -> Earlier {
    let mut e = c.earlier.clone().unwrap_or(Earlier {
        weighted: vec![[0.0; 3]; c.film.as_ref().map_or(0, |f| f.sum.len())],
        spp: 0,
        runs: Vec::new(),
    });
    if let Some(f) = c.film.as_ref().filter(|f| f.spp > 0) {
        let seed = Checkpoint::run_seed(c.identity.seed, c.progress.resumes);
        fold(&mut e, f, run_streams(seed, first, c.progress.passes));
    }
    e
}

/// The streams of a run from pass `first` to pass `end` (the next pass it would draw).
fn run_streams(seed: u64, first: u64, end: u64) -> Streams {
    Streams { seed, first, end }
}

/// Adds a run's image, weighted by its sample count, and its streams.
fn fold(e: &mut Earlier, film: &Film, streams: Streams) {
    e.runs.push(streams);
    let image = film.image();
    for (w, p) in e.weighted.iter_mut().zip(&image.pixels) {
        for c in 0..3 {
            w[c] += film.spp as f64 * p[c] as f64;
        }
    }
    e.spp += film.spp;
}

/// The renderer's state as a checkpoint.
fn snapshot(
    r: &Renderer,
    (id, recipe): (&Identity, Option<&Recipe>),
    p: &Progress,
    earlier: Option<&Earlier>,
) -> Checkpoint {
    let progress = Progress {
        passes: r.passes,
        nan_count: r.nan_count,
        paths: r.paths,
        ..p.clone()
    };
    Checkpoint {
        identity: id.clone(),
        recipe: recipe.cloned(),
        progress,
        film: r.film.clone(),
        meters: r.meters.clone(),
        state: r.integrator.checkpoint_state(),
        earlier: earlier.cloned(),
    }
}

/// Seconds between two progress lines written to a log file or a pipe.
pub const LOG_SECONDS: f64 = 10.0;

/// Progress where no bar can be drawn (stderr is a file or a pipe: a batch job's log): a line
/// after the first pass, then one at most every [`LOG_SECONDS`], and one after the last pass.
#[derive(Default)]
struct ProgressLog {
    last: Option<Instant>,
}

impl ProgressLog {
    /// After a pass: `message` (as the bar shows it), `spp` done in all, and the ETA of a
    /// fixed spp from the rate of this run (`done` samples per pixel in `elapsed` seconds).
    fn pass(&mut self, message: &str, spp: u64, (done, elapsed): (u64, f64), job: &Job) {
        let left = (job.spp as u64).saturating_sub(spp);
        let finished = job.time.is_none() && left == 0;
        let due = self
            .last
            .is_none_or(|t| t.elapsed().as_secs_f64() >= LOG_SECONDS);
        if !(due || finished) {
            return;
        }
        self.last = Some(Instant::now());
        let eta = match job.time {
            None if done > 0 && !finished => {
                format!(", eta {:.0} s", left as f64 * elapsed / done as f64)
            }
            _ => String::new(),
        };
        eprintln!("render: {message}{eta} ({elapsed:.1} s)");
    }
}

/// The progress bar of a job: tiles of every pass, or a spinner for a timed render.
fn progress_bar(job: &Job, done: u64) -> indicatif::ProgressBar {
    let tiles = job.setup.scene.camera.as_ref().map_or(1, |c| {
        (c.width.div_ceil(crate::integrator::TILE) * c.height.div_ceil(crate::integrator::TILE))
            as u64
    });
    let total = match job.time {
        Some(_) => 0,
        None => plan::passes((job.spp as u64).saturating_sub(done)) * tiles,
    };
    let b = if total > 0 {
        indicatif::ProgressBar::new(total)
    } else {
        indicatif::ProgressBar::new_spinner()
    };
    b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
    // the ETA of a fixed spp is indicatif's, from the tiles done; a timed render shows the time left
    let template = if total > 0 {
        "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}%, eta {eta} {msg}"
    } else {
        "{spinner} [{elapsed_precise}] {msg}"
    };
    b.set_style(
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    b.enable_steady_tick(std::time::Duration::from_millis(250));
    b
}

/// The progress line after a pass: samples per pixel so far (of the `target`, for a fixed
/// spp), camera samples per second, and for a timed render the seconds `left`.
pub fn progress_message(
    spp: u64,
    target: Option<u32>,
    samples_per_second: Option<f64>,
    left: Option<f64>,
) -> String {
    let mut m = match target {
        Some(t) => format!("{spp}/{t} spp"),
        None => format!("{spp} spp"),
    };
    if let Some(rate) = samples_per_second {
        m += &format!(", {rate:.3e} samples/s");
    }
    if let Some(l) = left {
        m += &format!(", {:.0} s left", l.max(0.0));
    }
    m
}

/// What the renderer holds, as a [`RenderResult`]; with MLT's earlier runs, the image is their
/// merge with the run in progress, weighted by sample count.
fn result(r: &Renderer, job: &Job, progress: &Progress, earlier: Option<&Earlier>) -> RenderResult {
    let run = run_streams(r.seed, job.first_pass, r.passes);
    let image = image(r, job, earlier);
    let negative_pixels = image.as_ref().map_or(0, |img| {
        img.pixels.iter().filter(|p| p.min_element() < 0.0).count() as u64
    });
    RenderResult {
        integrator: r.integrator.label(),
        spp: progress.spp,
        complete: job.time.is_some() || progress.spp >= job.spp as u64,
        seconds: progress.seconds,
        paths: r.paths,
        nan_count: r.nan_count,
        negative_pixels,
        image,
        meters: r.meter_estimates(),
        variance_of_mean: if r.kind.facts().pixel_variance() {
            r.film.as_ref().map(|f| f.variance_of_mean())
        } else {
            None
        },
        statistics: r.integrator.statistics(),
        streams: earlier
            .map_or(Vec::new(), |e| e.runs.clone())
            .into_iter()
            .chain([run])
            .collect(),
    }
}

/// The image the renderer holds: the film's, or with MLT's earlier runs their merge with the
/// run in progress, weighted by sample count.
fn image(r: &Renderer, job: &Job, earlier: Option<&Earlier>) -> Option<image_io::Image> {
    let run = run_streams(r.seed, job.first_pass, r.passes);
    r.film.as_ref().map(|f| match earlier {
        Some(e) => {
            let mut all = e.clone();
            fold(&mut all, f, run);
            let inv = 1.0 / all.spp.max(1) as f64;
            let mut img = f.image();
            for (p, w) in img.pixels.iter_mut().zip(&all.weighted) {
                *p = Rgb::new(
                    (w[0] * inv) as f32,
                    (w[1] * inv) as f32,
                    (w[2] * inv) as f32,
                );
            }
            img
        }
        None => f.image(),
    })
}
