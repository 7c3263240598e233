//! The arguments of `pathspace render` (and of `reference`, which takes the same): the render
//! options of the schema and the command's own, apart from the command that runs them, so that
//! `resume` and `reference` read them without reaching into the command.

use super::display::TevAddress;
use super::CliError;
use crate::integrator::path::DistanceSampling;
use crate::integrator::settings::{AdjointOptions, RenderOptions};
use crate::integrator::{IntegratorKind, OwnOption, RenderSettings};
use crate::render::memory;
use crate::render::shard::{Shard, ShardError};
use clap::Args;
use std::path::PathBuf;

/// The help heading of `render`'s own options (the schema's are grouped by integrator).
const OUTPUTS: &str = "Image, outputs and previews";

/// `pathspace render`: the render options of the schema ([`RenderOptions`], each overriding
/// its key of the scene's `[render]` table) and the options of the command itself.
#[derive(Args, Debug, Default, Clone)]
pub struct RenderArgs {
    /// Scene file (TOML, or Mitsuba 3 XML by its `.xml` extension); without it, the embedded fog box.
    pub scene: Option<PathBuf>,
    /// The render options, each overriding its `[render]` key (boxed: most are rarely given).
    #[command(flatten)]
    pub options: Box<RenderOptions>,
    /// Mutations per pixel for `--integrator mlt`, `pssmlt` or `mmlt` (the same count as --spp).
    #[arg(long, conflicts_with = "time", help_heading = OUTPUTS)]
    pub mutations_per_pixel: Option<u32>,
    /// PNG preview (default: next to the EXR).
    #[arg(long, help_heading = OUTPUTS)]
    pub png: Option<PathBuf>,
    /// bdpt only: also write each (s, t) strategy's MIS-weighted image to this directory, as
    /// `s{S}-t{T}.exr` and `.png`, for paths of up to `--strategy-depth` scattering vertices.
    #[arg(long, help_heading = OUTPUTS)]
    pub strategy_images: Option<PathBuf>,
    /// Deepest strategies written by `--strategy-images` (default 3).
    #[arg(long, default_value_t = 3, help_heading = OUTPUTS)]
    pub strategy_depth: u32,
    /// Print one JSON object with the results on stdout instead of the summary line.
    #[arg(long, help_heading = OUTPUTS)]
    pub json: bool,
    /// Also write the adjoint image's cells as this EXR (and a PNG next to it).
    #[arg(long, help_heading = OUTPUTS)]
    pub adjoint_output: Option<PathBuf>,
    /// The session's options, shared with `reference`.
    #[command(flatten)]
    pub session: SessionArgs,
    /// Set by `reference`: record `reference = true` and the estimated relMSE, print the
    /// reference's summary line.
    #[arg(skip)]
    pub reference: bool,
}

/// The options of a render session, declared once for `render` and `reference`: its length,
/// threads, output, memory limit, checkpoints and resumption.
#[derive(Args, Debug, Default, Clone)]
#[command(next_help_heading = "Session: length, threads, output, checkpoints")]
pub struct SessionArgs {
    /// Render for this many seconds instead of a fixed spp.
    #[arg(long)]
    pub time: Option<f64>,
    /// `--resolution WxH`.
    #[command(flatten)]
    pub film: super::ResolutionArg,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output EXR (default: the scene's name with .exr, `reference`: with -ref.exr, in the
    /// current directory).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Every SECONDS (after the pass that passes them), write the image so far and the render's
    /// state beside it (`OUT.checkpoint`), so that a crash loses at most that much.
    #[arg(long, value_name = "SECONDS")]
    pub checkpoint: Option<f64>,
    /// The memory limit.
    #[command(flatten)]
    pub memory: MemoryArgs,
    /// Continue the render saved in this checkpoint (`OUT.checkpoint`, or the `OUT.exr` beside
    /// it), with the same scene, options and seed; `--spp` may ask for more samples.
    #[arg(long, value_name = "FILE")]
    pub resume: Option<PathBuf>,
    /// Render only shard I of N (1 <= I <= N) of the samples: for path, light and bdpt a
    /// contiguous range of the passes of --spp, for mlt 1/N of the chains and mutations as an
    /// independent run; `merge` joins the N files and checks that none is missing.
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// Leave the timings (`seconds`, `guide_seconds`) out of the EXR header, so that the same
    /// scene, seed and settings give the same bytes at any thread count (`cmp` checks it);
    /// the timings still go to stderr and `--json`.
    #[arg(long)]
    pub reproducible: bool,
    /// After every pass, send the image so far to the tev viewer listening at HOST:PORT (tev
    /// listens on 127.0.0.1:14158 by default); a viewer that cannot be reached is a warning,
    /// and the render goes on.
    #[arg(long, value_name = "HOST:PORT", value_parser = super::display::parse_address)]
    pub display: Option<TevAddress>,
    /// Every SECONDS during the render, rewrite the PNG (`--png`, or beside the EXR) with the
    /// image so far: a preview for machines without a screen.
    #[arg(long, value_name = "SECONDS")]
    pub preview: Option<f64>,
    /// Also write these layers as channels of the EXR, separated by commas: variance,
    /// relative-variance, albedo, normal, depth, position, spp (or all); see the book's
    /// "Measuring a renderer" for their definitions.
    #[arg(long, value_name = "LIST", help_heading = OUTPUTS)]
    pub aovs: Option<crate::aov::AovList>,
}

impl SessionArgs {
    /// Refuses values no session can take (zero threads, a negative time or memory limit).
    fn check(&self) -> Result<(), CliError> {
        if self.threads == Some(0) {
            return Err(CliError::Usage("--threads must be at least 1".into()));
        }
        if let Some(t) = self.time {
            if !(t > 0.0 && t.is_finite()) {
                return Err(CliError::Usage(format!(
                    "--time {} must be a positive number of seconds",
                    super::number(t)
                )));
            }
        }
        self.memory.check()?;
        if self.shard.is_some() && self.time.is_some() {
            return Err(ShardError::Timed.into());
        }
        if let Some(t) = self.preview {
            if !(t >= 0.0 && t.is_finite()) {
                return Err(CliError::Usage(format!(
                    "--preview {t} must be a number of seconds (0: after every pass)"
                )));
            }
        }
        if let Some(t) = self.checkpoint {
            if !(t >= 0.0 && t.is_finite()) {
                return Err(CliError::Usage(format!(
                    "--checkpoint {} must be a number of seconds (0: after every pass)",
                    super::number(t)
                )));
            }
        }
        Ok(())
    }
}

/// `--shard I/N` as clap reads it (the refusal's own words).
fn parse_shard(text: &str) -> Result<Shard, String> {
    Shard::parse(text).map_err(|e| e.to_string())
}

/// `--max-memory`, declared once for `render`, `reference` and `converge`.
#[derive(Args, Debug, Default, Clone)]
pub struct MemoryArgs {
    /// Refuse a render whose estimated memory exceeds this many GiB (default: 75% of the
    /// machine's memory, 8 GiB where /proc/meminfo is missing); `info` prints the estimate.
    #[arg(long, value_name = "GIB", help_heading = "Memory")]
    pub max_memory: Option<f64>,
}

impl MemoryArgs {
    /// Refuses a limit that is no positive number.
    pub(super) fn check(&self) -> Result<(), CliError> {
        match self.max_memory {
            Some(m) if !(m > 0.0 && m.is_finite()) => Err(CliError::Usage(format!(
                "--max-memory {} must be a positive number of GiB",
                super::number(m)
            ))),
            _ => Ok(()),
        }
    }

    /// Refuses an `estimate` above the limit (by default a share of the machine's memory),
    /// naming both.
    pub(super) fn refuse_above(&self, estimate: &memory::MemoryEstimate) -> Result<(), CliError> {
        let limit = memory::Limit {
            max_gib: self.max_memory,
        };
        Ok(limit.refuse(estimate)?)
    }
}

/// The adjoint image's pre-pass options, shared by `render` and `converge` (`+adjoint` lines):
/// the `[render.adjoint]` schema, each flag overriding its key.
pub type AdjointTuning = AdjointOptions;

impl RenderArgs {
    /// Refuses the flags integrator `kind` does not take (a scene file's keys, in contrast,
    /// are defaults for the integrators they apply to), before any value is applied.
    pub(super) fn refuse_foreign(
        &self,
        kind: IntegratorKind,
        settings: &RenderSettings,
    ) -> Result<(), CliError> {
        let o = &self.options;
        if kind.facts().chains().is_none() && self.mutations_per_pixel.is_some() {
            return Err(CliError::Usage(
                "--mutations-per-pixel needs --integrator mlt, pssmlt or mmlt".into(),
            ));
        }
        let takers = |o: OwnOption| IntegratorKind::names_where(|f| f.takes(o));
        // a flag given to an integrator that does not take its option: the flag, and why not
        let only_for = |given: bool, option: OwnOption, flag: &str, why: &str| {
            if given && !kind.facts().takes(option) {
                return Err(CliError::Usage(format!(
                    "{flag} applies to --integrator {}, not `{}` ({why})",
                    takers(option),
                    kind.name()
                )));
            }
            Ok(())
        };
        if !kind.facts().takes(OwnOption::Smc) && !o.smc.is_empty() {
            return Err(CliError::Usage(format!(
                "--smc-* and --cache-budget apply to --integrator {}, not `{}`",
                takers(OwnOption::Smc),
                kind.name()
            )));
        }
        let wanted = o.adjoint_image.unwrap_or(settings.adjoint_image);
        if !wanted && (o.adjoint.any() || self.adjoint_output.is_some()) {
            return Err(CliError::Usage(
                "--adjoint-* options need --adjoint-image".into(),
            ));
        }
        only_for(
            o.distance == Some(DistanceSampling::EquiangularMis),
            OwnOption::EquiangularDistance,
            "--distance equiangular-mis",
            "it samples distances by free flight only",
        )?;
        if let Some(list) = &self.session.aovs {
            crate::aov::refuse_variance(&list.0, kind).map_err(CliError::Usage)?;
        }
        only_for(
            o.light_selection.is_some(),
            OwnOption::LightSelection,
            "--light-selection",
            "its light subpaths and connections pick lights by power",
        )?;
        only_for(
            o.light_point.is_some(),
            OwnOption::LightPoint,
            "--light-point",
            "it draws its light points by area",
        )?;
        only_for(
            o.halo_cone.is_some(),
            OwnOption::HaloCone,
            "--halo-cone",
            "it draws its scattering directions from the phase functions and BSDFs alone",
        )?;
        only_for(
            o.mis_heuristic.is_some(),
            OwnOption::MisHeuristic,
            "--mis-heuristic",
            "it weights no strategies of one path against each other",
        )?;
        only_for(
            o.pixel_samples.is_some(),
            OwnOption::PixelSamples,
            "--pixel-samples",
            "it draws no film position per pixel and pass",
        )?;
        if o.adjoint_image == Some(true) && !kind.samples_light_starts() {
            return Err(CliError::Usage(format!(
                "--adjoint-image applies to bdpt, light and mlt (they sample light start points), not `{}`",
                kind.name()
            )));
        }
        self.session.check()
    }
}
