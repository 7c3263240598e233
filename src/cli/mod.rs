//! The command line: one file per subcommand. Progress goes to stderr, results to stdout.

pub mod converge;
pub mod diff;
pub mod display;
pub mod info;
pub mod interrupt;
pub mod merge;
pub mod reference;
pub mod render;
pub mod render_args;
pub mod resume;
pub mod rooms;

/// `pathspace assignment` lives with the course it serves (the workspace member `course/`).
pub use pathspace_course::assignment;

use clap::{Parser, Subcommand};

use crate::image_io::ImageError;
use crate::integrator::smc::OptionError;
use crate::integrator::IntegratorError;
use crate::measure::chart::ChartError;
use crate::measure::convergence::ConvergenceError;
use crate::measure::MeasureError;
use crate::medium::heterogeneous::UnknownPropagation;
use crate::scene::SceneError;
use pathspace_course::assignment::AssignmentError;

/// pathspace: light transport in participating media, executable.
#[derive(Parser, Debug)]
#[command(name = "pathspace", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene (default: the embedded fog box).
    Render(render_args::RenderArgs),
    /// Compare two EXR images: RMSE, relMSE, means, max abs difference, error heatmap.
    Diff(diff::DiffArgs),
    /// Render a high-sample reference image with the most robust integrator.
    Reference(reference::ReferenceArgs),
    /// Equal-time convergence study of integrators against a reference: CSV and charts.
    Converge(converge::ConvergeArgs),
    /// Validate a scene and print what it contains.
    Info(info::InfoArgs),
    /// Write the N x N rooms scene of Pauly et al. Fig. 8 (many lights, one medium).
    Rooms(rooms::RoomsArgs),
    /// Average renders of the same scene, weighted by their sample counts (EXR `spp`).
    Merge(merge::MergeArgs),
    /// The book as a course: list assignments, make a student copy, grade a copy.
    Assignment(assignment::AssignmentArgs),
}

/// Why a `pathspace` command stops: the refusals of the command line itself and the errors of
/// the layers below, wrapped; the messages are what `main` prints after `error: `.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The command line asks for something the command refuses: a value out of its range,
    /// options that do not go together, a name or form not understood (the reason, as
    /// printed).
    #[error("{0}")]
    Usage(String),
    /// A scene file that cannot be read or loaded (its file, line and key).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// An integrator that is none or refuses the scene or its settings.
    #[error(transparent)]
    Integrator(#[from] IntegratorError),
    /// A render that cannot run: its integrator refuses, or a checkpoint cannot be read,
    /// resumed from or written.
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
    /// An image that cannot be read or written (its path, the cause).
    #[error(transparent)]
    Image(#[from] ImageError),
    /// Images that cannot be compared (`diff`).
    #[error(transparent)]
    Measure(#[from] MeasureError),
    /// A convergence study that cannot start or stops (`converge`).
    #[error(transparent)]
    Convergence(#[from] ConvergenceError),
    /// A chart of `converge` that cannot be drawn or written.
    #[error(transparent)]
    Chart(#[from] ChartError),
    /// Adjoint-image options that are refused (`--adjoint-*`, `converge`'s `+adjoint` lines).
    #[error(transparent)]
    Adjoint(#[from] crate::enlightened::AdjointError),
    /// A `--propagation` name that is no propagation strategy.
    #[error(transparent)]
    Propagation(#[from] UnknownPropagation),
    /// `pathspace assignment make` or `check` stops.
    #[error(transparent)]
    Assignment(#[from] AssignmentError),
    /// A signal stopped a render after the pass in flight; what was written is in the message
    /// (`main` exits with 128 + the signal's number).
    #[error("{what}")]
    Interrupted { signal: i32, what: String },
    /// The signal handlers cannot be installed.
    #[error("cannot handle SIGINT/SIGTERM/SIGHUP: {0}")]
    Signals(#[source] std::io::Error),
    /// A render that needs more memory than `--max-memory` allows (the estimate described,
    /// the limit, where the limit comes from).
    #[error(transparent)]
    Memory(#[from] crate::render::memory::MemoryError),
    /// The worker threads cannot be started.
    #[error("cannot start worker threads: {0}")]
    Threads(#[source] rayon::ThreadPoolBuildError),
    /// A file that cannot be written (its path, the cause).
    #[error("cannot write {0}: {1}")]
    Write(String, #[source] std::io::Error),
    /// An output directory that cannot be created (its path, the cause).
    #[error("{0}: {1}")]
    CreateDir(String, #[source] std::io::Error),
    /// `converge`: `--budget` and `--checkpoints` give no checkpoint times (the study's
    /// reason).
    #[error("--budget/--checkpoints: {0}")]
    Checkpoints(#[source] ConvergenceError),
    /// `converge`: a `+guide` key or its value refused (the key, the guide's reason).
    #[error("{}: {}", .0.key, .0.message)]
    GuideKey(#[source] OptionError),
    /// `converge`: a `+guide(...)` list that does not read as `[render.guide]` keys (the TOML
    /// parser's message).
    #[error("{}", .0.message())]
    GuideKeys(#[source] toml::de::Error),
    /// `converge`: a `+guide` line of `--integrators` refused (its name, the reason).
    #[error("`{0}`: {1}")]
    GuideLine(String, #[source] Box<CliError>),
    /// `converge`: the reference shows another scene (the reference's path, its scene and
    /// `scene_hash`, this scene's name and hash).
    #[error(
        "{reference} is a reference of another scene ({its_scene}, scene_hash {its_hash}), \
         not of {scene} (scene_hash {hash})"
    )]
    OtherScene {
        reference: String,
        its_scene: String,
        its_hash: String,
        scene: String,
        hash: String,
    },
    /// `reference`: a scene without a camera (its name): no image to render.
    #[error("{0}: the scene has no camera, so there is no image to render")]
    NoCamera(String),
    /// `reference`: the render returned no image.
    #[error("the render produced no image")]
    NoImage,
    /// `reference`: the output exists and is no readable EXR (its path, the image error).
    #[error(
        "refusing to overwrite {0}: it exists and is not a readable EXR ({1}); remove it or \
         choose another -o"
    )]
    OverwriteUnreadable(String, #[source] ImageError),
    /// `reference`: the output is a reference of another scene (its path, its scene and
    /// `scene_hash`, this scene's name and hash).
    #[error(
        "refusing to overwrite {output}: it is a reference of another scene ({its_scene}, \
         scene_hash {its_hash}), not of {scene} (scene_hash {hash}); remove it or choose \
         another -o"
    )]
    OverwriteOtherScene {
        output: String,
        its_scene: String,
        its_hash: String,
        scene: String,
        hash: String,
    },
    /// `reference`: the output has no `scene_hash`, so it is no reference (its path, this
    /// scene's name).
    #[error(
        "refusing to overwrite {0}: it has no scene_hash attribute, so it is not a pathspace \
         reference of {1}; remove it or choose another -o"
    )]
    OverwriteNotReference(String, String),
    /// `merge`: no input.
    #[error("nothing to merge")]
    NothingToMerge,
    /// `merge`: an input of another size than the first (its name, its width and height, the
    /// first's).
    #[error("{0} is {1}x{2} but the first input is {3}x{4}")]
    MergeSize(String, u32, u32, u32, u32),
    /// `merge`: an input without a positive `spp` attribute (its name).
    #[error("{0} has no positive `spp` attribute to weight it by")]
    NoSpp(String),
    /// `render`/`reference --shard`: a shard refused (the reason).
    #[error(transparent)]
    Shard(#[from] crate::render::shard::ShardError),
    /// `merge` of `converge --shard` directories: not the shards of one study, each once.
    #[error(transparent)]
    Study(#[from] crate::measure::study::StudyError),
    /// `merge`: inputs that are no independent estimates of one image, or an unreadable record.
    #[error(transparent)]
    Provenance(#[from] crate::render::provenance::ProvenanceError),
}

/// The refusals of commands that report them as text (`render`).
impl From<String> for CliError {
    fn from(reason: String) -> Self {
        CliError::Usage(reason)
    }
}

/// What `pathspace` alone prints: the two commands most people want first, and where the rest is.
pub const USAGE: &str = "\
pathspace: light transport in participating media (a renderer, its tests and a book)

  pathspace render                     render the built-in fog box to fog-box.exr and .png
  pathspace render SCENE.toml --spp 64 render a scene (TOML, or Mitsuba 3 XML)

  pathspace info SCENE.toml            check a scene and list what it holds
  pathspace --help                     every command; `pathspace render --help` every option";

/// A number as a message shows it: as written when that is short, else in scientific notation
/// (`--time 1e-300` is not echoed as 300 digits).
pub fn number(x: f64) -> String {
    let plain = x.to_string();
    if plain.len() <= 12 {
        plain
    } else {
        format!("{x:e}")
    }
}

/// The longest line of a message printed whole; a longer one keeps its start and end.
pub const MAX_PRINTED_LINE: usize = 2000;

/// `text` as it may reach a terminal: control characters other than newlines and tabs escaped
/// (a scene, an EXR attribute or a checkpoint may hold escape sequences that would retitle the
/// window or rewrite the screen), and each line longer than [`MAX_PRINTED_LINE`] characters cut
/// in its middle, saying how much was left out (an error may quote a value of megabytes).
pub fn printable(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(1 << 16));
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push('\n');
        }
        let escaped: String = line
            .chars()
            .flat_map(|c| match c {
                '\t' => vec![c],
                c if c.is_control() => c.escape_default().collect(),
                c => vec![c],
            })
            .collect();
        let n = escaped.chars().count();
        if n <= MAX_PRINTED_LINE {
            out.push_str(&escaped);
        } else {
            let keep = MAX_PRINTED_LINE / 2;
            let head: String = escaped.chars().take(keep).collect();
            let tail: String = escaped.chars().skip(n - keep / 2).collect();
            out.push_str(&format!(
                "{head} [... {} characters left out ...] {tail}",
                n - keep - keep / 2
            ));
        }
    }
    out
}

/// Runs the command line; returns the process exit code.
pub fn run(cli: Cli) -> Result<(), CliError> {
    run_with_source(cli, &[])
}

/// Runs the command line with the crate's source tree embedded by `build.rs` (the binary passes
/// it; `assignment make` writes student copies from it).
pub fn run_with_source(cli: Cli, source_tree: &[(&str, &[u8])]) -> Result<(), CliError> {
    match cli.command {
        None => {
            println!("{USAGE}");
            Ok(())
        }
        Some(Command::Render(a)) => render::run(a),
        Some(Command::Diff(a)) => diff::run(a),
        Some(Command::Reference(a)) => reference::run(a),
        Some(Command::Converge(a)) => converge::run(a),
        Some(Command::Info(a)) => info::run(a),
        Some(Command::Rooms(a)) => rooms::run(a),
        Some(Command::Merge(a)) => merge::run(a),
        Some(Command::Assignment(a)) => Ok(assignment::run(
            a,
            source_tree,
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
        )?),
    }
}

/// A loaded scene: the scene, its `[render]` settings and its source.
pub type Loaded = (
    crate::scene::Scene,
    crate::integrator::RenderSettings,
    crate::scene::SceneSource,
);

/// Loads the named scene, or the embedded fog box when `None`: the scene, its `[render]`
/// settings and its source.
pub fn load_scene(path: Option<&std::path::Path>) -> Result<Loaded, CliError> {
    let source = match path {
        Some(p) => crate::scene::SceneSource::read(p)?,
        None => {
            crate::scene::SceneSource::embedded("fog-box.toml (embedded)", crate::scene::FOG_BOX)
        }
    };
    let (scene, settings) = crate::integrator::settings::load(&source)?;
    Ok((scene, settings, source))
}

/// `--resolution WxH`, declared once for every command that renders a scene.
#[derive(clap::Args, Debug, Default, Clone, PartialEq)]
pub struct ResolutionArg {
    /// Override the camera resolution, e.g. `64x64` (quick previews, golden images; the
    /// vertical field of view is kept).
    #[arg(long, value_name = "WxH", value_parser = render::parse_resolution)]
    pub resolution: Option<(u32, u32)>,
}

impl ResolutionArg {
    /// The scene with its camera at this resolution (unchanged without the flag).
    pub fn apply(&self, scene: &mut crate::scene::Scene) -> Result<(), CliError> {
        let Some((w, h)) = self.resolution else {
            return Ok(());
        };
        let cam = scene
            .camera
            .as_ref()
            .ok_or_else(|| CliError::Usage("--resolution needs a scene with a camera".into()))?;
        scene.camera = cam.with_resolution(w, h);
        Ok(())
    }
}

/// [`load_scene`] with `--resolution` applied.
pub fn load_scene_at(
    path: Option<&std::path::Path>,
    resolution: &ResolutionArg,
) -> Result<Loaded, CliError> {
    let (mut scene, settings, source) = load_scene(path)?;
    resolution.apply(&mut scene)?;
    Ok((scene, settings, source))
}

/// The most worker threads a command starts: far above any machine's cores, far below the
/// count whose mere creation costs seconds (100,000 threads take about 13 CPU-s to fail).
pub const MAX_THREADS: usize = 1024;

/// A rayon pool of `threads` workers (all cores when None), at least 1 and at most
/// [`MAX_THREADS`].
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, CliError> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        if t == 0 {
            return Err(CliError::Usage("--threads must be at least 1".into()));
        }
        if t > MAX_THREADS {
            return Err(CliError::Usage(format!(
                "--threads {t}: at most {MAX_THREADS} (this machine has {} cores)",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            )));
        }
        pool = pool.num_threads(t);
    }
    pool.build().map_err(CliError::Threads)
}
