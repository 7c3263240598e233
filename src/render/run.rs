//! A render as one call ([`Render::run`]): the outputs checked, the memory estimated and
//! refused above its limit, the preprocessing stages, the passes from a checkpoint or from the
//! start, checkpoints and a stop by a signal after the pass in flight, the image written through
//! the front end and the render's state kept or removed. A front end (the command line's
//! `render` and `reference`, a binding, a test) says what is its own through [`Frontend`]:
//! its threads, what it reports, how it writes the image, its live views and its stop signal.
//! Book: "Measuring a renderer".

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;
use std::time::Instant;

use super::checkpoint::{Checkpoint, CheckpointError, Identity, Recipe};
use super::memory::{self, MemoryEstimate};
use super::provenance::{format_inputs, format_streams};
use super::session::{self, Control, Ended, Job, Preprocessed, RenderResult};
use super::shard::{self, Shard, ShardPlan};
use super::RenderError;
use crate::conventions::OptionValue as _;
use crate::enlightened::{AdjointSettings, GuideKind};
use crate::image_io::{self, ImageMeta};
use crate::integrator::{Case, IntegratorError, IntegratorKind, RenderSettings, Setup};
use crate::scene::{Scene, SceneSource};

/// A shard of a render: the shard, its part, and the whole render's spp and seed.
pub struct ShardOf {
    pub shard: Shard,
    pub part: ShardPlan,
    pub total_spp: u32,
    pub seed: u64,
}

impl ShardOf {
    /// Narrows the settings of a whole render to shard `s` of it (its spp, and for MLT its
    /// seed and chains); the shard's record.
    fn narrow(
        s: Shard,
        kind: IntegratorKind,
        settings: &mut RenderSettings,
    ) -> Result<ShardOf, RenderError> {
        let (total_spp, seed) = (settings.spp, settings.seed);
        let chains = kind.facts().chains();
        let count = chains.map(|c| (c.flag, (c.get)(settings)));
        let part = shard::plan(s, kind, total_spp, seed, count)?;
        settings.spp = part.spp;
        settings.seed = part.seed;
        if let (Some(c), Some(n)) = (chains, part.chains) {
            (c.set)(settings, n);
        }
        Ok(ShardOf {
            shard: s,
            part,
            total_spp,
            seed,
        })
    }
}

/// Whether integrator `kind` samples with the guide ([`crate::integrator::Facts::takes_guide`]).
pub fn guides(kind: IntegratorKind) -> bool {
    kind.takes_guide()
}

/// The integrators that take the guide, for a message (`path, light, ... or mmlt`).
pub fn guide_takers() -> String {
    IntegratorKind::names_where(|f| f.takes_guide())
}

/// A render checked before any work: the scene, the integrator and its settings (a shard's
/// when `shard` is given), and how long to render.
pub struct Render<'a> {
    pub scene: &'a Scene,
    pub source: &'a SceneSource,
    pub kind: IntegratorKind,
    pub settings: RenderSettings,
    /// The adjoint image's settings, when the image is wanted.
    pub adjoint: Option<AdjointSettings>,
    /// Which shard, what it renders, and the whole render's spp and seed (the settings above
    /// are the shard's).
    pub shard: Option<ShardOf>,
    /// Seconds to render instead of a fixed spp (the preprocessing counts).
    pub time: Option<f64>,
    /// Progress, stages and notes on stderr (off for a front end that prints JSON).
    pub show: bool,
}

impl<'a> Render<'a> {
    /// Checks `settings` for integrator `kind` on `scene` (a shard's part, MLT's scene, SMC's
    /// march length, the guide) and warns once of the light paths `kind` cannot sample.
    pub fn new(
        scene: &'a Scene,
        source: &'a SceneSource,
        kind: IntegratorKind,
        mut settings: RenderSettings,
        shard: Option<Shard>,
    ) -> Result<Self, RenderError> {
        let shard = match shard {
            Some(s) => {
                let filtered = scene.camera.as_ref().is_some_and(|c| !c.filter.is_box());
                if filtered && kind.facts().chains().is_none() {
                    return Err(shard::ShardError::Filtered.into());
                }
                Some(ShardOf::narrow(s, kind, &mut settings)?)
            }
            None => None,
        };
        // the guide and the adjoint image do not represent light paths starting in a medium
        let guide = settings.guide.kind != GuideKind::Off && guides(kind);
        let adjoint = settings.adjoint_image && kind.samples_light_starts();
        if let Some(why) =
            crate::enlightened::technique::emitting_media_refusal(scene, guide, adjoint)
        {
            return Err(IntegratorError::Refused(why).into());
        }
        // refused before the memory it would need (MLT's scene, SMC's march length)
        crate::integrator::check_emitting_media(kind, scene)?;
        kind.facts().check(&Case {
            scene,
            settings: &settings,
        })?;
        warn_unreachable(scene, kind, &settings);
        if settings.guide.kind != GuideKind::Off && !guides(kind) {
            return Err(IntegratorError::Refused(format!(
                "guiding (--guide or [render.guide] vertices) applies to {}, not `{}`",
                guide_takers(),
                kind.name()
            ))
            .into());
        }
        refuse_unused_guide_options(&settings)?;
        // the scene's key is a default for the integrators it applies to
        let adjoint =
            (settings.adjoint_image && kind.samples_light_starts()).then_some(settings.adjoint);
        Ok(Render {
            scene,
            source,
            kind,
            settings,
            adjoint,
            shard,
            time: None,
            show: true,
        })
    }

    /// The memory this render needs on `threads` threads.
    pub fn memory(&self, threads: usize) -> MemoryEstimate {
        memory::estimate(self.scene, self.kind, &self.settings, threads)
    }

    /// Runs the preprocessing stages (adjoint image, guide); their seconds.
    pub fn preprocess(&self) -> Result<(Preprocessed, f64), RenderError> {
        let t0 = Instant::now();
        let s = &self.settings;
        let pre = session::preprocess(
            self.scene,
            self.adjoint.as_ref(),
            &s.guide,
            s.seed,
            s.max_depth,
            self.show,
        )?;
        Ok((pre, t0.elapsed().as_secs_f64()))
    }

    /// The integrators' view of this render with the technique the preprocessing built.
    pub fn setup<'s>(&'s self, pre: &'s Preprocessed) -> Setup<'s, 's> {
        Setup {
            scene: self.scene,
            technique: &pre.technique,
            settings: &self.settings,
            seed: self.settings.seed,
            max_depth: self.settings.max_depth,
        }
    }

    /// The passes: `--time` counts the preprocessing, the passes get what it left (at least
    /// one pass).
    pub fn job<'s>(&'s self, pre: &'s Preprocessed, preprocessing: f64) -> Job<'s> {
        Job {
            kind: self.kind,
            setup: self.setup(pre),
            spp: self.settings.spp,
            time: self.time.map(|t| t - preprocessing),
            first_pass: self.shard.as_ref().map_or(0, |s| s.part.first_pass),
            progress: self.show,
        }
    }

    /// What a checkpoint of this render must match to be resumed.
    pub fn identity(&self) -> Identity {
        let mut options = self.settings.given.to_json();
        if let Some(o) = options.as_object_mut() {
            o.remove("spp");
            if let Some(s) = &self.shard {
                let whole = format!("{} of {} spp", s.shard, s.total_spp);
                o.insert("shard".into(), whole.into());
            }
        }
        Identity {
            scene_hash: self.source.hash(),
            inputs: self.source.inputs(),
            integrator: self.kind.name().to_string(),
            options: options.to_string(),
            seed: self.settings.seed,
            film: self.scene.camera.as_ref().map(|c| (c.width, c.height)),
            meters: self.scene.sensors.len(),
        }
    }

    /// The checkpoint at `path`, if it is one of this render (`id`).
    pub fn resume_from(&self, path: &Path, id: &Identity) -> Result<Checkpoint, RenderError> {
        let c = Checkpoint::read(path)?;
        c.check_identity(id, &path.display().to_string())?;
        eprintln!(
            "resuming {}: {} of {} spp done, next pass {}",
            path.display(),
            c.progress.spp,
            self.settings.spp,
            c.progress.passes
        );
        Ok(c)
    }

    /// The render's record in its image's header: what was rendered, from which scene and
    /// inputs, with which options and sample streams, how far, in how long.
    pub fn record(&self, result: &RenderResult, pre: &Preprocessed) -> ImageMeta {
        let (s, source) = (&self.settings, self.source);
        let mut meta = ImageMeta::default();
        meta.set("integrator", &result.integrator)
            .set("spp", result.spp)
            .set("spp_target", s.spp)
            .set("complete", result.complete)
            .set("seed", s.seed)
            .set("seconds", format!("{:.3}", result.seconds))
            .set("scene", &source.name)
            .set("scene_hash", format!("{:016x}", source.hash()))
            .set("nan_count", result.nan_count)
            .set("negative_pixels", result.negative_pixels)
            .set("render_options", s.given.to_toml())
            .set("streams", format_streams(&result.streams));
        // the integrator's own record (the MCMC chains' mixing)
        for (key, value) in &result.statistics.header {
            meta.set(key, value);
        }
        let inputs = source.inputs();
        if !inputs.is_empty() {
            meta.set("scene_inputs", format_inputs(&inputs));
        }
        if let Some(sh) = &self.shard {
            meta.set("shard", sh.shard)
                .set("shard_spp", sh.total_spp)
                .set("shard_seed", sh.seed);
        }
        if let Some(g) = &pre.guide {
            let gs = s.guide;
            let guide = format!(
                "{} map {}x{} regions {} particles {} weight {}",
                gs.kind.name(),
                gs.cols,
                gs.rows,
                gs.regions.regions,
                gs.particles,
                gs.c_guide,
            );
            meta.set("guide", guide)
                .set("guide_seconds", format!("{:.3}", g.seconds()));
        }
        meta
    }
}

/// Refuses guide options given without guiding: `--guide-particles 1000` alone would
/// otherwise render unguided, and the user would believe the guide was tuned.
fn refuse_unused_guide_options(settings: &RenderSettings) -> Result<(), RenderError> {
    let unused = settings.given.guide.without_guiding();
    if unused.is_empty() {
        return Ok(());
    }
    let named: Vec<String> = unused
        .iter()
        .map(|k| format!("--guide-{} ([render.guide] {k})", k.replace('_', "-")))
        .collect();
    Err(IntegratorError::Refused(format!(
        "{} given without guiding: add --guide surface, volume or both (or [render.guide] vertices)",
        named.join(", ")
    ))
    .into())
}

/// Warns once, before the work, of the light paths integrator `kind` cannot sample on `scene`
/// (and the integrator's own warnings, e.g. SMC's anisotropy).
fn warn_unreachable(scene: &Scene, kind: IntegratorKind, settings: &RenderSettings) {
    if let Some(w) = crate::integrator::reach::unreachable_paths(scene, kind) {
        eprintln!("warning: {w}");
    }
    for w in kind.facts().warnings(&Case { scene, settings }) {
        eprintln!("warning: {w}");
    }
}

/// Where a render writes: the files it will write with their formats, the directories, the
/// checkpoint beside the image, and the checkpoint it continues.
#[derive(Clone, Debug, Default)]
pub struct Outputs {
    /// Files and their formats (`exr`, `png`), checked before any work.
    pub files: Vec<(PathBuf, &'static str)>,
    /// Directories written into, checked before any work.
    pub dirs: Vec<PathBuf>,
    /// The checkpoint beside the image (empty: none, for a front end that keeps a stopped
    /// render's result itself, as a binding does).
    pub checkpoint: PathBuf,
    /// Seconds between checkpoints.
    pub every: Option<f64>,
    /// The checkpoint to continue from.
    pub resume: Option<PathBuf>,
    /// The memory limit in bytes and where it comes from ([`memory::Limit`]).
    pub max_memory: memory::Limit,
}

impl Outputs {
    /// Refuses, before any work, outputs that cannot be written (a missing directory, a name
    /// that does not say the format): a typo must not cost a whole render.
    pub fn check(&self) -> Result<(), RenderError> {
        for (file, format) in &self.files {
            image_io::check_output(file, format)?;
        }
        for dir in &self.dirs {
            image_io::check_output_dir(dir)?;
        }
        Ok(())
    }

    /// Whether this render writes (or resumed from) the checkpoint beside its image, which it
    /// then removes when it is complete; a checkpoint of another render is left alone.
    fn owns_state(&self) -> bool {
        self.every.is_some() || self.resume.is_some()
    }
}

/// The live view of a render: called after every pass with how far it is and the image so
/// far on demand ([`session::PassView`]), its time left out of the render's.
pub type LiveView<'f> = Box<dyn FnMut(&session::PassView) + Send + 'f>;

/// What a front end adds to a render: its threads, what it does around the preprocessing,
/// how it writes the image, its live views, its stop signal and its recipe.
pub trait Frontend {
    /// The front end's errors, which the render's own become.
    type Error: From<RenderError> + std::fmt::Display;

    /// The worker threads (asked for once the outputs are checked).
    fn pool(&mut self) -> Result<rayon::ThreadPool, Self::Error>;

    /// Work of the front end's own before the preprocessing (feature layers).
    fn before(&mut self, _render: &Render, _pool: &rayon::ThreadPool) -> Result<(), Self::Error> {
        Ok(())
    }

    /// After the preprocessing (`seconds` long), before the passes: report what it built and
    /// write what it asks for.
    fn preprocessed(
        &mut self,
        _render: &Render,
        _pre: &Preprocessed,
        _seconds: f64,
        _pool: &rayon::ThreadPool,
    ) -> Result<(), Self::Error> {
        Ok(())
    }

    /// Writes the image so far (a checkpoint) or at the end; the paths written.
    fn write(
        &self,
        render: &Render,
        result: &RenderResult,
        pre: &Preprocessed,
    ) -> Result<Vec<String>, Self::Error>;

    /// The live view after every pass, if any (connected now, before the first pass).
    fn live(&self, _size: Option<(u32, u32)>) -> Option<LiveView<'_>> {
        None
    }

    /// The flag a signal sets to stop the render after the pass in flight.
    fn stop(&self) -> Result<Option<&'static AtomicUsize>, Self::Error> {
        Ok(None)
    }

    /// How the render was asked for, kept in its checkpoints.
    fn recipe(&self) -> Option<Recipe> {
        None
    }
}

/// A render's outcome: how it ended, what was built before the passes, its memory estimate
/// and the files written (the image, and the checkpoint of a render that did not finish).
pub struct Rendered {
    pub ended: Ended,
    pub pre: Preprocessed,
    pub memory: MemoryEstimate,
    pub written: Vec<String>,
}

impl Render<'_> {
    /// The whole render: outputs checked, memory estimated and refused above the limit,
    /// preprocessing, passes (resumed, checkpointed, stopped by a signal), the image written
    /// by the front end and the state kept for a render that did not finish.
    pub fn run<F: Frontend + Sync>(&self, out: &Outputs, f: &mut F) -> Result<Rendered, F::Error> {
        out.check()?;
        let pool = f.pool()?;
        let memory = self.memory(pool.current_num_threads());
        out.max_memory.refuse(&memory).map_err(RenderError::from)?;
        f.before(self, &pool)?;
        let (pre, seconds) = pool.install(|| self.preprocess())?;
        f.preprocessed(self, &pre, seconds, &pool)?;
        let job = self.job(&pre, seconds);
        let ended = self.passes(&job, &pre, out, f, &pool)?;
        let mut written = f.write(self, &ended.result, &pre)?;
        written.extend(self.keep_state(&ended, out)?);
        Ok(Rendered {
            ended,
            pre,
            memory,
            written,
        })
    }

    /// Renders the job from `out.resume`'s checkpoint if given, writing the image and the
    /// checkpoint every `out.every` seconds, until done or stopped.
    fn passes<F: Frontend + Sync>(
        &self,
        job: &Job,
        pre: &Preprocessed,
        out: &Outputs,
        f: &F,
        pool: &rayon::ThreadPool,
    ) -> Result<Ended, F::Error> {
        let id = self.identity();
        let resume = match &out.resume {
            Some(path) => Some(self.resume_from(path, &id)?),
            None => None,
        };
        let mut write = |r: &RenderResult, c: &Checkpoint| {
            let to_err = |e: F::Error| CheckpointError::Write(e.to_string());
            f.write(self, r, pre).map_err(to_err)?;
            c.write(&out.checkpoint)
        };
        let size = self.scene.camera.as_ref().map(|c| (c.width, c.height));
        let mut live = f
            .live(size)
            .map(|mut view| move |pass: &session::PassView| view(pass));
        let control = Control {
            stop: f.stop()?,
            every: out.every,
            identity: Some(id),
            recipe: f.recipe(),
            resume,
            on_checkpoint: Some(&mut write),
            on_pass: live.as_mut().map(|v| v as _),
        };
        Ok(pool.install(|| session::render_with(job, control))?)
    }

    /// Writes the checkpoint of a render that stopped or did not finish (the path written),
    /// or removes the one this render wrote or resumed from once it is complete.
    fn keep_state(&self, ended: &Ended, out: &Outputs) -> Result<Option<String>, RenderError> {
        let path = &out.checkpoint;
        if path.as_os_str().is_empty() {
            return Ok(None);
        }
        let keep = ended.stopped_by.is_some() || !ended.result.complete;
        if let (true, Some(c)) = (keep, &ended.checkpoint) {
            c.write(path)?;
            return Ok(Some(path.display().to_string()));
        }
        if out.owns_state() && path.is_file() {
            // a finished render needs no state: its checkpoints (and a resumed one) go
            match std::fs::remove_file(path) {
                Ok(()) if self.show => {
                    eprintln!("removed {} (the render is complete)", path.display())
                }
                Ok(()) => {}
                Err(e) => eprintln!("warning: cannot remove {}: {e}", path.display()),
            }
        }
        Ok(None)
    }
}
