//! Equal-time convergence runs: each integrator gets the same wall-clock budget, renders passes
//! of 1 sample per pixel, and its film is compared with a reference at checkpoints spaced
//! geometrically in time.
//!
//! * Checkpoints: t_k = T f^(1 - k/(K-1)), k = 0..K-1, from f T to the budget T (f = 1/100).
//! * At each: RMSE, relMSE against the reference, efficiency = 1 / (relMSE x seconds).
//! * Runs r = 0..R-1 use independent seeds (run 0 uses the seed itself); their mean and standard
//!   error per checkpoint, and the log-log slope of the means, summarize an integrator.
//!
//! Book: "Measuring a renderer".

use std::fmt::Write;
use std::path::Path;
use std::sync::Mutex;

use crate::image_io::{self, Image};
use crate::integrator::settings::{RenderOptions, Spelling};
use crate::integrator::{IntegratorKind, RenderSettings};
use crate::math::sampler::mix64;
use crate::measure::metrics;
use crate::measure::stats::{self, MeanStderr, PowerLawFit};
use crate::render::run::LiveView;
use crate::render::session::{PassView, Preprocessed, RenderResult};
use crate::render::{Frontend, Outputs, Render, RenderError};
use crate::scene::{Scene, SceneSource};

/// The CSV header of `convergence.csv`; other tools read the columns by these names.
pub const CSV_HEADER: &str = "integrator,run,checkpoint,seconds,samples,rmse,relmse,efficiency";

/// The first checkpoint is at this fraction of the budget: two decades of time are enough to
/// see a slope, and the first is still late enough to be more than one pass on most scenes.
pub const FIRST_CHECKPOINT_FRACTION: f64 = 0.01;

/// How a convergence study is run.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvergeConfig {
    /// Wall-clock seconds of rendering per integrator and run (metrics excluded).
    pub budget: f64,
    /// Number of checkpoints K.
    pub checkpoints: usize,
    /// Number of independent runs R.
    pub runs: usize,
    /// Base seed; run r renders with `run_seed(seed, r)`.
    pub seed: u64,
    /// Maximum path depth (None: Russian roulette only).
    pub max_depth: Option<u32>,
    /// The part of the runs this process renders (`converge --shard I/N`): runs
    /// `(I-1)R/N .. IR/N`, each with the seed it has in the whole study; `None`, all of them.
    pub shard: Option<crate::render::shard::Shard>,
}

impl ConvergeConfig {
    /// The indices of the runs this process renders.
    pub fn run_indices(&self) -> std::ops::Range<usize> {
        match self.shard {
            Some(s) => {
                let (i, n) = (s.index as usize, s.count as usize);
                (i - 1) * self.runs / n..i * self.runs / n
            }
            None => 0..self.runs,
        }
    }
}

/// One row of `convergence.csv`: one integrator, one run, one checkpoint.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckpointRow {
    pub integrator: String,
    pub run: usize,
    /// Index k of the checkpoint (0-based); checkpoints that fell inside one pass share a row,
    /// which carries the index of the last of them.
    pub checkpoint: usize,
    /// Rendering time so far, metric computations excluded.
    pub seconds: f64,
    /// Samples per pixel so far (0 when unknown, for images from another renderer).
    pub samples: u64,
    pub rmse: f64,
    pub relmse: f64,
    /// 1 / (relMSE x seconds).
    pub efficiency: f64,
}

// ANCHOR: efficiency
/// Efficiency of an estimator: 1 / (relMSE x seconds), the inverse of the time needed for a
/// relMSE of 1 if relMSE falls as 1/t. Constant in time for an unbiased Monte Carlo estimator
/// (relMSE ~ 1/t), so it ranks integrators independently of the budget; it is the inverse of
/// the "time-to-unit-variance" of Veach's thesis sec. 2.5.
pub fn efficiency(relmse: f64, seconds: f64) -> f64 {
    1.0 / (relmse * seconds)
}
// ANCHOR_END: efficiency

/// Why a convergence study cannot start or stops (its budget and checkpoints, the reference,
/// the integrators it measures, the files it reads and writes); the messages are what
/// `pathspace converge` prints.
#[derive(Debug, thiserror::Error)]
pub enum ConvergenceError {
    /// A budget that is no positive, finite number of seconds.
    #[error("the budget must be a positive number of seconds, not {0}")]
    BadBudget(f64),
    /// No checkpoint: nothing to fit the slope on.
    #[error("at least one checkpoint is needed")]
    NoCheckpoint,
    /// No camera: no image to compare with the reference.
    #[error("the scene has no camera: there is no image to compare with the reference")]
    NoCamera,
    /// The scene's image size and the reference's ((width, height) of each).
    #[error("the scene renders {}x{} images but the reference is {}x{}", .0.0, .0.1, .1.0, .1.1)]
    SizeMismatch((u32, u32), (u32, u32)),
    /// An empty list of integrators.
    #[error("no integrator to measure")]
    NoIntegrator,
    /// Zero runs.
    #[error("at least one run is needed")]
    NoRun,
    /// `NAME+adjoint` for an integrator that starts no light subpaths (the name, the kind).
    #[error("`{0}`: the adjoint image applies to bdpt, light and mlt, not `{1}`")]
    NoAdjoint(String, String),
    /// `NAME(key=value, ...)` whose options are refused (the name, why).
    #[error("`{0}`: {1}")]
    Options(String, String),
    /// `NAME+equiangular` for another integrator than the path tracer (the name, the kind).
    #[error("`{0}`: equiangular distance sampling applies to path, not `{1}`")]
    NoEquiangular(String, String),
    /// An integrator that is none.
    #[error(transparent)]
    Integrator(#[from] crate::integrator::IntegratorError),
    /// A line's render that refuses the scene or its settings (the integrator, the adjoint
    /// image's estimation, Kristensen 2010 sec. 5.3.1).
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The worker threads cannot be started.
    #[error("cannot start the worker threads: {0}")]
    Threads(String),
    /// A rendered image that cannot be compared with the reference.
    #[error(transparent)]
    Measure(#[from] crate::measure::MeasureError),
    /// An external image that cannot be read.
    #[error(transparent)]
    Image(#[from] image_io::ImageError),
    /// A file or directory that cannot be read or written (its path, the cause).
    #[error("{0}: {1}")]
    Io(String, #[source] std::io::Error),
    /// An `--external` directory that cannot be read (the line's name, the directory, the cause).
    #[error("--external {0}: {1}: {2}")]
    ExternalDir(String, String, #[source] std::io::Error),
    /// An external image with neither a `seconds` attribute nor a time as its name.
    #[error("{0}: no render time: give it a `seconds` attribute or name it `<seconds>.exr`")]
    NoRenderTime(String),
    /// An external image that cannot be compared with the reference (its path, the cause).
    #[error("{0}: {1}")]
    ExternalImage(String, #[source] crate::measure::MeasureError),
    /// An `--external` directory without images (the line's name, the directory).
    #[error("--external {0}: no .exr images in {1}")]
    NoExternalImages(String, String),
}

impl From<ConvergenceError> for String {
    fn from(e: ConvergenceError) -> Self {
        e.to_string()
    }
}

// ANCHOR: checkpoint_times
/// The K checkpoint times: geometric from `FIRST_CHECKPOINT_FRACTION x budget` to the budget, so
/// they are evenly spaced on the log-log chart where the slope is fitted.
pub fn checkpoint_times(budget: f64, checkpoints: usize) -> Result<Vec<f64>, ConvergenceError> {
    if !(budget > 0.0 && budget.is_finite()) {
        return Err(ConvergenceError::BadBudget(budget));
    }
    if checkpoints == 0 {
        return Err(ConvergenceError::NoCheckpoint);
    }
    if checkpoints == 1 {
        return Ok(vec![budget]);
    }
    let last = (checkpoints - 1) as f64;
    Ok((0..checkpoints)
        .map(|k| budget * FIRST_CHECKPOINT_FRACTION.powf(1.0 - k as f64 / last))
        .collect())
}
// ANCHOR_END: checkpoint_times

/// The seed of run `run`: run 0 keeps `seed` (so a one-run study renders what `render --seed`
/// renders); later runs get decorrelated seeds through SplitMix64.
pub fn run_seed(seed: u64, run: usize) -> u64 {
    if run == 0 {
        seed
    } else {
        mix64(seed ^ mix64(run as u64))
    }
}

/// One line of a study: the label of its rows, its integrator and its settings. The
/// preprocessing those settings ask for (the adjoint image, the guide) is built for each run
/// with the run's seed and charged to the run.
#[derive(Clone, Debug)]
pub struct Line {
    pub label: String,
    pub kind: IntegratorKind,
    pub settings: RenderSettings,
}

impl Line {
    /// The plain line of integrator `kind` with the scene's `settings` (no adjoint image, no
    /// guide: those are lines of their own).
    pub fn plain(kind: IntegratorKind, settings: &RenderSettings) -> Line {
        let mut settings = settings.clone();
        settings.adjoint_image = false;
        settings.guide.kind = crate::enlightened::GuideKind::Off;
        Line {
            label: kind.name().to_string(),
            kind,
            settings,
        }
    }
}

// ANCHOR: measure_run
/// One run of one line: a render of passes of 1 spp for the last checkpoint's time, its
/// preprocessing counted, through the render API that `render` uses ([`Render::run`]); when the
/// render's time passes a checkpoint, the image is compared with the reference. The session
/// leaves the comparisons (its views of the passes) out of the render's time, so the metrics
/// cost the integrator nothing.
pub fn measure_run(
    render: &Render,
    reference: &Image,
    times: &[f64],
    run: usize,
    label: &str,
) -> Result<Vec<CheckpointRow>, ConvergenceError> {
    check_reference(render.scene, reference)?;
    let mut study = Checkpoints {
        reference,
        times,
        label,
        run,
        preprocessing: 0.0,
        rows: Mutex::new(Vec::with_capacity(times.len())),
        error: Mutex::new(None),
    };
    // the study checked the memory of its lines before the runs, with its own limit
    let unlimited = crate::render::memory::Limit {
        max_gib: Some(f64::INFINITY),
    };
    let out = Outputs {
        max_memory: unlimited,
        ..Outputs::default()
    };
    render.run(&out, &mut study)?;
    if let Some(e) = study.error.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(e.into());
    }
    Ok(study.rows.into_inner().unwrap_or_else(|e| e.into_inner()))
}
// ANCHOR_END: measure_run

/// The study's part of a run ([`Frontend`]): no files, and after every pass the checkpoints
/// the render's time has passed, compared with the reference.
struct Checkpoints<'a> {
    reference: &'a Image,
    times: &'a [f64],
    label: &'a str,
    run: usize,
    /// The preprocessing's seconds, charged to the run.
    preprocessing: f64,
    rows: Mutex<Vec<CheckpointRow>>,
    error: Mutex<Option<crate::measure::MeasureError>>,
}

impl Frontend for Checkpoints<'_> {
    type Error = ConvergenceError;

    /// The caller's thread count (a study runs in its pool).
    fn pool(&mut self) -> Result<rayon::ThreadPool, ConvergenceError> {
        rayon::ThreadPoolBuilder::new()
            .num_threads(rayon::current_num_threads())
            .build()
            .map_err(|e| ConvergenceError::Threads(e.to_string()))
    }

    fn preprocessed(
        &mut self,
        _: &Render,
        pre: &Preprocessed,
        seconds: f64,
        _: &rayon::ThreadPool,
    ) -> Result<(), ConvergenceError> {
        self.preprocessing = seconds;
        if let Some(g) = &pre.guide {
            eprint!("{}", g.table());
        }
        Ok(())
    }

    fn write(
        &self,
        _: &Render,
        _: &RenderResult,
        _: &Preprocessed,
    ) -> Result<Vec<String>, ConvergenceError> {
        Ok(Vec::new())
    }

    fn live(&self, _size: Option<(u32, u32)>) -> Option<LiveView<'_>> {
        let mut next = 0;
        Some(Box::new(move |pass: &PassView| {
            // the render's clock leaves the preprocessing out: a checkpoint at t is passed at
            // t - preprocessing, the difference the session's own time limit is
            let mut passed = None;
            while next < self.times.len() && pass.seconds >= self.times[next] - self.preprocessing {
                passed = Some(next);
                next += 1;
            }
            // a slow pass can pass several checkpoints at once: one row stands for them all
            let Some(checkpoint) = passed else {
                return;
            };
            let Some(image) = (pass.image)() else {
                return;
            };
            let seconds = self.preprocessing + pass.seconds;
            match metrics::compare(&image, self.reference) {
                Ok(m) => lock(&self.rows).push(CheckpointRow {
                    integrator: self.label.to_string(),
                    run: self.run,
                    checkpoint,
                    seconds,
                    samples: pass.spp,
                    rmse: m.rmse,
                    relmse: m.relmse,
                    efficiency: efficiency(m.relmse, seconds),
                }),
                Err(e) => {
                    lock(&self.error).get_or_insert(e);
                }
            }
        }))
    }
}

/// The value behind a mutex, whether or not a panic poisoned it.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Checks that the scene renders an image the reference can be compared with.
fn check_reference(scene: &Scene, reference: &Image) -> Result<(), ConvergenceError> {
    let Some(cam) = scene.camera.as_ref() else {
        return Err(ConvergenceError::NoCamera);
    };
    if (cam.width, cam.height) != (reference.width, reference.height) {
        return Err(ConvergenceError::SizeMismatch(
            (cam.width, cam.height),
            (reference.width, reference.height),
        ));
    }
    Ok(())
}

/// The checks every study makes before it starts (something to measure, at least one run, a
/// reference of this scene) and its checkpoint times.
fn study_checkpoints(
    scene: &Scene,
    reference: &Image,
    integrators: usize,
    config: &ConvergeConfig,
) -> Result<Vec<f64>, ConvergenceError> {
    if integrators == 0 {
        return Err(ConvergenceError::NoIntegrator);
    }
    if config.runs == 0 {
        return Err(ConvergenceError::NoRun);
    }
    check_reference(scene, reference)?;
    checkpoint_times(config.budget, config.checkpoints)
}

/// Runs every integrator `config.runs` times for the same budget and returns every checkpoint
/// row, integrator by integrator, run by run. `on_run` hears of each finished run (progress).
pub fn converge(
    scene: &Scene,
    source: &SceneSource,
    settings: &RenderSettings,
    reference: &Image,
    kinds: &[IntegratorKind],
    config: &ConvergeConfig,
    on_run: &mut dyn FnMut(&[CheckpointRow]),
) -> Result<Vec<CheckpointRow>, ConvergenceError> {
    let lines: Vec<Line> = kinds.iter().map(|&k| Line::plain(k, settings)).collect();
    converge_lines((scene, source), reference, &lines, config, on_run)
}

/// Runs every line `config.runs` times for the same budget, each run a render of its own
/// (the seed of run r `run_seed(seed, r)`, its preprocessing built with that seed and charged
/// to it); every checkpoint row, line by line, run by run.
pub fn converge_lines(
    (scene, source): (&Scene, &SceneSource),
    reference: &Image,
    lines: &[Line],
    config: &ConvergeConfig,
    on_run: &mut dyn FnMut(&[CheckpointRow]),
) -> Result<Vec<CheckpointRow>, ConvergenceError> {
    let times = study_checkpoints(scene, reference, lines.len(), config)?;
    let mut rows = Vec::new();
    for line in lines {
        let mut settings = line.settings.clone();
        settings.max_depth = config.max_depth;
        // checked (and its warnings given) once per line
        let mut render = Render::new(scene, source, line.kind, settings, None)?;
        render.time = times.last().copied();
        render.show = false;
        for run in config.run_indices() {
            render.settings.seed = run_seed(config.seed, run);
            let run_rows = measure_run(&render, reference, &times, run, &line.label)?;
            on_run(&run_rows);
            rows.extend(run_rows);
        }
    }
    Ok(rows)
}

/// An integrator as `converge` names it: a kind, optionally with the adjoint image
/// (`bdpt+adjoint`, `mlt+adjoint`, `light+adjoint`; Kristensen 2010, sec. 5.3.1), or the path
/// tracer with equiangular distance sampling (`path+equiangular`; Kulla and Fajardo 2012), or
/// `KIND(key=value, ...)` with any `[render]` options of the schema over the scene's (a nested
/// table's key dotted: `guide.vertices`, `smc.variant`).
#[derive(Clone, Debug, PartialEq)]
pub struct Variant {
    pub kind: IntegratorKind,
    pub adjoint: Option<crate::enlightened::AdjointSettings>,
    /// `distance = "equiangular-mis"` for this line (the path tracer only).
    pub equiangular: bool,
    /// The options of `KIND(key=value, ...)` and the line's name as given.
    pub options: Option<(RenderOptions, String)>,
}

impl Variant {
    /// Suffix that asks for the adjoint image.
    pub const ADJOINT_SUFFIX: &'static str = "+adjoint";
    /// Suffix that asks for equiangular MIS on the walk's rays.
    pub const EQUIANGULAR_SUFFIX: &'static str = "+equiangular";

    /// Parses `NAME`, `NAME+adjoint`, `path+equiangular` or `NAME(key=value, ...)`;
    /// `adjoint` holds the settings of the image.
    pub fn parse(
        s: &str,
        adjoint: crate::enlightened::AdjointSettings,
    ) -> Result<Self, ConvergenceError> {
        if let Some((base, list)) = s.split_once('(') {
            let list = list
                .strip_suffix(')')
                .ok_or_else(|| ConvergenceError::Options(s.into(), "no closing `)`".into()))?;
            let options =
                parse_options(list).map_err(|e| ConvergenceError::Options(s.into(), e))?;
            return Ok(Variant {
                kind: IntegratorKind::parse(base.trim())?,
                adjoint: None,
                equiangular: false,
                options: Some((options, s.split_whitespace().collect())),
            });
        }
        if let Some(base) = s.strip_suffix(Self::EQUIANGULAR_SUFFIX) {
            let kind = IntegratorKind::parse(base)?;
            if !kind
                .facts()
                .takes(crate::integrator::OwnOption::EquiangularDistance)
            {
                return Err(ConvergenceError::NoEquiangular(s.into(), base.into()));
            }
            return Ok(Variant {
                kind,
                adjoint: None,
                equiangular: true,
                options: None,
            });
        }
        match s.strip_suffix(Self::ADJOINT_SUFFIX) {
            Some(base) => {
                let kind = IntegratorKind::parse(base)?;
                if !kind.samples_light_starts() {
                    return Err(ConvergenceError::NoAdjoint(s.into(), base.into()));
                }
                Ok(Variant {
                    kind,
                    adjoint: Some(adjoint),
                    equiangular: false,
                    options: None,
                })
            }
            None => Ok(Variant {
                kind: IntegratorKind::parse(s)?,
                adjoint: None,
                equiangular: false,
                options: None,
            }),
        }
    }

    /// The line's settings: `base` (the scene's) with its options over them, checked (a
    /// message names the key), and the adjoint image's settings when the line asks for it.
    pub fn settings(
        &self,
        base: &RenderSettings,
    ) -> Result<(RenderSettings, Option<crate::enlightened::AdjointSettings>), ConvergenceError>
    {
        let mut s = base.clone();
        if self.equiangular {
            s.distance = crate::integrator::path::DistanceSampling::EquiangularMis;
        }
        let Some((o, name)) = &self.options else {
            return Ok((s, self.adjoint));
        };
        let refused = |why: String| ConvergenceError::Options(name.clone(), why);
        s.apply(o, Spelling::Key).map_err(|e| {
            let key = [e.table, e.key.unwrap_or("")].join(".");
            refused(format!("{}: {}", key.trim_matches('.'), e.message))
        })?;
        let starts = self.kind.samples_light_starts();
        if o.guide.any() && !self.kind.takes_guide() {
            let takers = IntegratorKind::names_where(|f| f.takes_guide());
            return Err(refused(format!(
                "guiding applies to {takers}, not `{}`",
                self.kind.name()
            )));
        }
        let adjoint = (s.adjoint_image && starts).then_some(s.adjoint);
        Ok((s, adjoint))
    }

    /// The study's line: its settings over `base` with the adjoint image it asks for (and no
    /// other), and the guide only when its options set guide keys.
    pub fn line(&self, base: &RenderSettings) -> Result<Line, ConvergenceError> {
        let (mut settings, adjoint) = self.settings(base)?;
        settings.adjoint_image = adjoint.is_some();
        if let Some(a) = adjoint {
            settings.adjoint = a;
        }
        if !self.options.as_ref().is_some_and(|(o, _)| o.guide.any()) {
            settings.guide.kind = crate::enlightened::GuideKind::Off;
        }
        Ok(Line {
            label: self.name(),
            kind: self.kind,
            settings,
        })
    }

    /// The label of its rows.
    pub fn name(&self) -> String {
        if let Some((_, name)) = &self.options {
            return name.clone();
        }
        match (self.adjoint, self.equiangular) {
            (Some(_), _) => format!("{}{}", self.kind.name(), Self::ADJOINT_SUFFIX),
            (None, true) => format!("{}{}", self.kind.name(), Self::EQUIANGULAR_SUFFIX),
            (None, false) => self.kind.name().to_string(),
        }
    }
}

/// The options of `KIND(key=value, ...)`: each pair a `[render]` key (a nested table's dotted,
/// `guide.map`), its value read as in the scene file (a bare word is a string); the study's
/// own (`integrator`, `spp`, `seed`) refused.
pub fn parse_options(list: &str) -> Result<RenderOptions, String> {
    let mut table = String::new();
    for pair in list.split(',').filter(|p| !p.trim().is_empty()) {
        let (k, v) = pair
            .split_once('=')
            .ok_or_else(|| format!("`{}` is not key=value", pair.trim()))?;
        let (k, v) = (k.trim(), v.trim());
        if ["integrator", "spp", "seed"].contains(&k) {
            return Err(format!(
                "`{k}` is the study's (the line's name, --budget, --seed)"
            ));
        }
        let value = match toml::from_str::<toml::Table>(&format!("v = {v}")) {
            Ok(_) => v.to_string(),
            Err(_) => toml::Value::String(v.to_string()).to_string(),
        };
        table.push_str(&format!("{k} = {value}\n"));
    }
    toml::from_str::<RenderOptions>(&table).map_err(|e| e.message().to_string())
}

/// Writes the rows as `convergence.csv` (header `CSV_HEADER`).
pub fn write_csv(path: &Path, rows: &[CheckpointRow]) -> Result<(), ConvergenceError> {
    let mut text = format!("{CSV_HEADER}\n");
    for r in rows {
        let _ = writeln!(
            text,
            "{},{},{},{:.9},{},{:.9e},{:.9e},{:.9e}",
            r.integrator, r.run, r.checkpoint, r.seconds, r.samples, r.rmse, r.relmse, r.efficiency
        );
    }
    // through a temporary file: a full disk leaves an earlier study's rows whole
    Ok(image_io::write_file_replacing(path, text.as_bytes())?)
}

/// Images of another renderer as one more line: every `*.exr` in `dir`, its time from a
/// `seconds` attribute or else from its name (`12.5.exr`), its spp from an `spp` attribute
/// (0 when absent). The rows are in time order, run 0, checkpoint = rank.
pub fn external_rows(
    name: &str,
    dir: &Path,
    reference: &Image,
) -> Result<Vec<CheckpointRow>, ConvergenceError> {
    let entries = std::fs::read_dir(dir)
        .map_err(|e| ConvergenceError::ExternalDir(name.into(), dir.display().to_string(), e))?;
    let mut found = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|e| ConvergenceError::Io(dir.display().to_string(), e))?
            .path();
        if path.extension().and_then(|e| e.to_str()) != Some("exr") {
            continue;
        }
        let (image, meta) = image_io::read_exr(&path)?;
        let seconds = match meta.get("seconds") {
            Some(s) => s.trim().parse::<f64>().ok(),
            None => path
                .file_stem()
                .and_then(|s| s.to_str())
                .and_then(|s| s.parse::<f64>().ok()),
        }
        .filter(|s| *s > 0.0 && s.is_finite())
        .ok_or_else(|| ConvergenceError::NoRenderTime(path.display().to_string()))?;
        let samples = meta
            .get("spp")
            .and_then(|s| s.trim().parse::<u64>().ok())
            .unwrap_or(0);
        let m = metrics::compare(&image, reference)
            .map_err(|e| ConvergenceError::ExternalImage(path.display().to_string(), e))?;
        found.push((seconds, samples, m));
    }
    if found.is_empty() {
        return Err(ConvergenceError::NoExternalImages(
            name.into(),
            dir.display().to_string(),
        ));
    }
    found.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(found
        .into_iter()
        .enumerate()
        .map(|(k, (seconds, samples, m))| CheckpointRow {
            integrator: name.to_string(),
            run: 0,
            checkpoint: k,
            seconds,
            samples,
            rmse: m.rmse,
            relmse: m.relmse,
            efficiency: efficiency(m.relmse, seconds),
        })
        .collect())
}

/// One checkpoint of one integrator, over its runs.
#[derive(Clone, Debug, PartialEq)]
pub struct CurvePoint {
    pub checkpoint: usize,
    /// How many runs reached this checkpoint.
    pub runs: usize,
    pub seconds: MeanStderr,
    pub samples: MeanStderr,
    pub rmse: MeanStderr,
    pub relmse: MeanStderr,
    pub efficiency: MeanStderr,
}

/// An integrator's convergence curve and its fitted orders.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    pub integrator: String,
    pub points: Vec<CurvePoint>,
    /// log relMSE against log seconds (-1 for unbiased Monte Carlo), mean over runs with the
    /// standard error over runs (one run: the regression's); None below two points.
    pub relmse_vs_time: Option<PowerLawFit>,
    /// log RMSE against log samples (-1/2 for unbiased Monte Carlo), as above; None when the
    /// samples are unknown (0) or fewer than two points.
    pub rmse_vs_samples: Option<PowerLawFit>,
}

impl Curve {
    /// The last checkpoint (the end of the budget).
    pub fn last(&self) -> Option<&CurvePoint> {
        self.points.last()
    }
}

// ANCHOR: summarize
/// Groups the rows by integrator (in order of appearance) and checkpoint and takes the mean and
/// standard error over runs; fits the slopes run by run and combines them over runs
/// (`stats::combine_fits`), whose spread is an honest standard error where the regression error
/// of one run, with its correlated checkpoints, is not.
pub fn summarize(rows: &[CheckpointRow]) -> Vec<Curve> {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.integrator.as_str()) {
            names.push(&r.integrator);
        }
    }
    names
        .into_iter()
        .map(|name| {
            let mine: Vec<&CheckpointRow> = rows.iter().filter(|r| r.integrator == name).collect();
            let mut ks: Vec<usize> = mine.iter().map(|r| r.checkpoint).collect();
            ks.sort_unstable();
            ks.dedup();
            let points: Vec<CurvePoint> = ks
                .into_iter()
                .map(|k| {
                    let at: Vec<&&CheckpointRow> =
                        mine.iter().filter(|r| r.checkpoint == k).collect();
                    let col = |f: &dyn Fn(&CheckpointRow) -> f64| -> MeanStderr {
                        stats::mean_stderr(&at.iter().map(|r| f(r)).collect::<Vec<f64>>())
                    };
                    CurvePoint {
                        checkpoint: k,
                        runs: at.len(),
                        seconds: col(&|r| r.seconds),
                        samples: col(&|r| r.samples as f64),
                        rmse: col(&|r| r.rmse),
                        relmse: col(&|r| r.relmse),
                        efficiency: col(&|r| r.efficiency),
                    }
                })
                .collect();
            let runs: Vec<usize> = {
                let mut r: Vec<usize> = mine.iter().map(|r| r.run).collect();
                r.sort_unstable();
                r.dedup();
                r
            };
            // one fit per run, combined over runs; a single run falls back on its regression error
            let fit = |x: &dyn Fn(&CheckpointRow) -> f64, y: &dyn Fn(&CheckpointRow) -> f64| {
                let fits: Vec<PowerLawFit> = runs
                    .iter()
                    .filter_map(|&run| {
                        let at: Vec<&&CheckpointRow> =
                            mine.iter().filter(|r| r.run == run).collect();
                        let xs: Vec<f64> = at.iter().map(|r| x(r)).collect();
                        let ys: Vec<f64> = at.iter().map(|r| y(r)).collect();
                        stats::fit_power_law(&xs, &ys).ok()
                    })
                    .collect();
                match fits.len() {
                    0 => None,
                    1 => Some(fits[0]),
                    _ => stats::combine_fits(&fits).ok(),
                }
            };
            Curve {
                integrator: name.to_string(),
                relmse_vs_time: fit(&|r| r.seconds, &|r| r.relmse),
                rmse_vs_samples: fit(&|r| r.samples as f64, &|r| r.rmse),
                points,
            }
        })
        .collect()
}
// ANCHOR_END: summarize
