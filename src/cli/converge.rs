//! `pathspace converge SCENE --reference REF.exr --integrators path,... --budget SECONDS
//! [--checkpoints K] [--runs R] [--seed S] [--threads N] [-o DIR] [--external NAME=DIR]...`:
//! an equal-time convergence study, written as `DIR/convergence.csv`, `DIR/error-vs-time.{svg,png}`
//! and `DIR/efficiency.{svg,png}`.

use clap::Args;
use std::path::PathBuf;

use super::CliError;
use crate::conventions::OptionValue as _;
use crate::enlightened::GuideKind;
use crate::image_io;
use crate::integrator::settings::{GuideOptions, Spelling};
use crate::integrator::smc::OptionError;
use crate::integrator::IntegratorKind;
use crate::measure::chart;
use crate::measure::convergence::{self, ConvergeConfig, Curve, Line, Variant};
use crate::measure::study::Study;

#[derive(Args, Debug, Clone)]
pub struct ConvergeArgs {
    /// Scene file (TOML, or Mitsuba 3 XML by its `.xml` extension).
    pub scene: PathBuf,
    /// The reference EXR (from `pathspace reference`).
    #[arg(long)]
    pub reference: PathBuf,
    /// Integrators to compare, comma-separated; `bdpt+adjoint`, `light+adjoint`, `mlt+adjoint`
    /// use the adjoint image (its pre-pass time counts in the budget; settings from the
    /// scene's `[render.adjoint]`); `bdpt+guide`, `light+guide`, `mlt+guide` and
    /// `KIND+guide(key=value,...)` (any `[render.guide]` key) or the short
    /// `KIND+guide:VERTICES:COLSxROWS:K` render with guided local sampling (over the `--guide*`
    /// options; vertices default to `surface`), the preprocessing counted in the budget;
    /// `path+equiangular` is the path tracer with `distance = "equiangular-mis"`;
    /// `KIND(key=value,...)` sets any `[render]` options for the line (a nested table's key
    /// dotted, e.g. `path(distance=equiangular-mis)`, `smc(smc.variant=is0_cv0)`,
    /// `mlt(guide.vertices=volume,guide.map=16x8)`, `bdpt(adjoint_image=true)`).
    #[arg(long, value_delimiter = ',', default_value = "path")]
    pub integrators: Vec<String>,
    /// Wall-clock seconds of rendering per integrator and run.
    #[arg(long, allow_negative_numbers = true)]
    pub budget: f64,
    /// Checkpoints, spaced geometrically from budget/100 to the budget.
    #[arg(long, default_value_t = 8)]
    pub checkpoints: usize,
    /// Independent runs per integrator (mean and standard error over them).
    #[arg(long, default_value_t = 1)]
    pub runs: usize,
    /// Base seed (default: the scene's `[render] seed`); run r uses a seed derived from it.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Render only the I-th of N parts of the runs (runs (I-1)R/N .. IR/N, each with its seed
    /// in the whole study), for N processes or machines; `pathspace merge DIR... -o DIR` puts
    /// the shards' directories back together. `--external` images are read by shard 1.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Output directory.
    #[arg(short = 'o', long = "output", default_value = "convergence")]
    pub output: PathBuf,
    /// Another renderer's images as one more line: NAME=DIR, DIR holding `<seconds>.exr` files
    /// (or EXRs with a `seconds` attribute). Repeatable.
    #[arg(long = "external", value_name = "NAME=DIR")]
    pub external: Vec<String>,
    /// Run every integrator once per propagation strategy of the scene's inhomogeneous media
    /// (comma-separated: equidistant, stratified, random-offset, delta-tracking); the lines are
    /// labelled `integrator/strategy`. The reference stays the same (same scene file).
    #[arg(long, value_delimiter = ',')]
    pub propagation: Vec<String>,
    /// `+adjoint` variants: the adjoint image's pre-pass (default: the scene's
    /// `[render.adjoint]`).
    #[command(flatten)]
    pub adjoint: super::render_args::AdjointTuning,
    /// Guided local sampling of the `+guide` variants.
    #[command(flatten)]
    pub guide: Box<super::render::GuideArgs>,
    /// The memory limit every line's render is checked against before the runs begin.
    #[command(flatten)]
    pub memory: super::render_args::MemoryArgs,
    /// `--resolution WxH` (the reference must have the same).
    #[command(flatten)]
    pub film: super::ResolutionArg,
}

/// An integrator named on the command line: a kind and its variant modifiers: `+guide`,
/// `+guide(key=value,...)` with any `[render.guide]` keys (the same schema as the file and the
/// `--guide-*` flags, [`GuideOptions`]), or the short form `+guide:VERTICES:COLSxROWS:K`
/// (vertices, map, regions; trailing fields may be left out), overriding the `--guide*`
/// options for this line, so that one run sweeps the guide's parameters. A guided line's
/// label has the short form.
#[derive(Clone, Debug, PartialEq)]
pub struct GuidedVariant {
    pub kind: IntegratorKind,
    /// `Some` for a guided line: the guide options given in the name.
    pub guide: Option<GuideOverride>,
}

/// The guide options a `+guide(...)` or `+guide:...` name sets, over the `--guide*` flags.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GuideOverride {
    pub options: GuideOptions,
}

impl GuideOverride {
    /// The short form's fields `VERTICES:COLSxROWS:K`.
    fn parse_short(fields: &[&str]) -> Result<Self, CliError> {
        if fields.len() > 3 {
            return Err(CliError::Usage(
                "expected +guide:VERTICES:COLSxROWS:K".into(),
            ));
        }
        let mut o = GuideOptions {
            vertices: match fields.first() {
                Some(v) => Some(GuideKind::parse(v).map_err(|message| {
                    CliError::GuideKey(OptionError {
                        key: "vertices",
                        message,
                    })
                })?),
                None => None,
            },
            map: fields.get(1).map(|m| m.to_string()),
            ..Default::default()
        };
        if let Some(k) = fields.get(2) {
            let k: usize = k.parse().map_err(|_| {
                CliError::Usage(format!("regions `{k}` is not a count in 1..=1048576"))
            })?;
            o.regions = Some(k);
        }
        Self::checked(o)
    }

    /// `key=value,...` of `+guide(...)`: each pair a `[render.guide]` key, its value read as in
    /// the file (a bare word is a string).
    fn parse_keys(list: &str) -> Result<Self, CliError> {
        let mut table = String::new();
        for pair in list.split(',').filter(|p| !p.trim().is_empty()) {
            let (k, v) = pair
                .split_once('=')
                .ok_or_else(|| CliError::Usage(format!("`{pair}` is not key=value")))?;
            let (k, v) = (k.trim(), v.trim());
            let value = match toml::from_str::<toml::Table>(&format!("v = {v}")) {
                Ok(_) => v.to_string(),
                Err(_) => toml::Value::String(v.to_string()).to_string(),
            };
            table.push_str(&format!("{k} = {value}\n"));
        }
        let o: GuideOptions = toml::from_str(&table).map_err(|e| {
            // a value refused by its type (an enumerated one) is named by its key, as `checked` does
            let bad = table.lines().find_map(|line| {
                let k = line.split('=').next().unwrap_or("").trim();
                let e = toml::from_str::<GuideOptions>(line).err()?;
                Some(CliError::Usage(format!("{k}: {}", e.message())))
            });
            bad.unwrap_or(CliError::GuideKeys(e))
        })?;
        Self::checked(o)
    }

    /// The options, each value checked now (every check is of the value alone), so that a bad
    /// name fails before any run.
    fn checked(options: GuideOptions) -> Result<Self, CliError> {
        let probe = crate::enlightened::GuideSettings::for_radius(1.0);
        options
            .apply(probe, Spelling::Key)
            .map_err(CliError::GuideKey)?;
        Ok(GuideOverride { options })
    }

    /// `base` with these options replaced (vertices `surface` when neither sets them).
    pub fn apply(
        &self,
        base: crate::enlightened::GuideSettings,
    ) -> Result<crate::enlightened::GuideSettings, CliError> {
        let mut g = self
            .options
            .apply(base, Spelling::Key)
            .map_err(CliError::GuideKey)?;
        if g.kind == crate::enlightened::GuideKind::Off {
            g.kind = crate::enlightened::GuideKind::Surface;
        }
        Ok(g)
    }
}

impl GuidedVariant {
    /// Parses `KIND`, `KIND+guide`, `KIND+guide(key=value,...)` or
    /// `KIND+guide:VERTICES:COLSxROWS:K`.
    pub fn parse(s: &str) -> Result<Self, CliError> {
        let (kind, rest) = s.trim().split_once('+').unwrap_or((s.trim(), ""));
        let kind = IntegratorKind::parse(kind)?;
        let mut v = GuidedVariant { kind, guide: None };
        if rest.is_empty() {
            return Ok(v);
        }
        let over = if let Some(list) = rest.strip_prefix("guide(") {
            let list = list
                .strip_suffix(')')
                .ok_or_else(|| CliError::Usage(format!("`{s}`: `+guide(` without its `)`")))?;
            GuideOverride::parse_keys(list)
        } else if rest == "guide" || rest.starts_with("guide:") {
            let fields: Vec<&str> = rest.split(':').skip(1).collect();
            GuideOverride::parse_short(&fields)
        } else {
            return Err(CliError::Usage(format!(
                "`{s}`: unknown variant `+{rest}` (available: +guide)"
            )));
        };
        if !super::render::guides(kind) {
            return Err(CliError::Usage(format!(
                "`{s}`: +guide applies to {}, not `{}`",
                crate::render::run::guide_takers(),
                kind.name()
            )));
        }
        v.guide = Some(over.map_err(|e| CliError::GuideLine(s.into(), Box::new(e)))?);
        Ok(v)
    }
}

/// The names of `--integrators`, its comma-split items joined again inside `+guide(...)`.
fn integrator_names(items: &[String]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    let mut open = false;
    for item in items {
        match names.last_mut() {
            Some(last) if open => {
                last.push(',');
                last.push_str(item);
            }
            _ => names.push(item.clone()),
        }
        let last = names.last().expect("pushed");
        open = last.contains('(') && !last.ends_with(')');
    }
    names
}

/// The label of a guided line: `KIND+guide:VERTICES:COLSxROWS:K`, with `:indirect` (or
/// `:depthD`) when `--guide-min-depth` keeps shallow particles out of the maps.
fn guided_label(kind: IntegratorKind, g: &crate::enlightened::GuideSettings) -> String {
    let depth = match g.min_depth {
        1 => String::new(),
        2 => ":indirect".into(),
        d => format!(":depth{d}"),
    };
    let sampler = match g.sampler {
        crate::enlightened::guide::ParticleSampler::Classical => "",
        crate::enlightened::guide::ParticleSampler::Bidirectional => ":bidir",
        crate::enlightened::guide::ParticleSampler::Metropolis => ":metro",
    };
    format!(
        "{}+guide:{}:{}x{}:{}{depth}{sampler}",
        kind.name(),
        g.kind.name(),
        g.cols,
        g.rows,
        g.regions.regions
    )
}

/// The line of a guided variant: the scene's settings with the guide its name sets over the
/// `--guide*` options (its preprocessing, built with each run's seed, counted in the run's
/// time).
fn guided_line(
    args: &ConvergeArgs,
    settings: &crate::integrator::RenderSettings,
    kind: IntegratorKind,
    over: &GuideOverride,
) -> Result<Line, CliError> {
    let mut line = Line::plain(kind, settings);
    let flags = args.guide.apply_flags(settings.guide);
    let g = over.apply(flags.map_err(|e| CliError::Usage(e.message))?)?;
    line.settings.guide = g;
    line.label = guided_label(kind, &g);
    Ok(line)
}

/// One line of the summary printed at the end.
pub fn summary_line(c: &Curve) -> String {
    let mut s = c.integrator.to_string();
    if let Some(p) = c.last() {
        // one run has no spread to show: "± 0" would claim an exact figure
        let error_bar = if p.runs > 1 {
            format!(" ± {:.1e}", p.relmse.stderr)
        } else {
            " (one run: no error bar, --runs 2 gives one)".to_string()
        };
        s += &format!(
            ": at {:.2} s {:.0} spp, relMSE {:.3e}{error_bar}, RMSE {:.3e}, efficiency {:.3e} /s",
            p.seconds.mean, p.samples.mean, p.relmse.mean, p.rmse.mean, p.efficiency.mean
        );
    }
    if let Some(f) = c.relmse_vs_time {
        s += &format!(
            "; relMSE-vs-time slope {:.3} ± {:.3}",
            f.slope, f.slope_stderr
        );
    }
    if let Some(f) = c.rmse_vs_samples {
        s += &format!(
            "; RMSE-vs-samples slope {:.3} ± {:.3}",
            f.slope, f.slope_stderr
        );
    }
    s
}

/// The share of a measured relMSE that the reference's own noise may be before the study says
/// so: E[(a - b)^2] = var(a) + var(b), so the curves flatten at the reference's relMSE, and
/// below a tenth of the error that floor bends them by less than 10% (book, "The reference").
pub const REFERENCE_NOISE_SHARE: f64 = 0.1;

/// A warning when the reference's estimated relMSE `reference` is more than
/// [`REFERENCE_NOISE_SHARE`] of the smallest error a curve reached at its last checkpoint.
pub fn noisy_reference_warning(reference: f64, curves: &[Curve]) -> Option<String> {
    let (line, least) = curves
        .iter()
        .filter_map(|c| c.last().map(|p| (c.integrator.as_str(), p.relmse.mean)))
        .filter(|(_, m)| *m > 0.0)
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let share = reference / least;
    (share > REFERENCE_NOISE_SHARE).then(|| {
        format!(
            "the reference's own noise (estimated relMSE {reference:.3e}) is {:.0}% of the \
             error {line} reached (relMSE {least:.3e}): the curves flatten at the reference's \
             floor; a reference with about {:.0} times its samples keeps the floor below {:.0}%",
            100.0 * share,
            (share / REFERENCE_NOISE_SHARE).ceil(),
            100.0 * REFERENCE_NOISE_SHARE
        )
    })
}

/// The `+guide` lines: each kind with the guide parameters its name sets.
type GuidedLines = Vec<(IntegratorKind, GuideOverride)>;

/// The lines `--integrators` names: plain and `+adjoint` variants, and `+guide` lines with
/// their overrides; checked against the other options.
fn parse_lines(
    args: &ConvergeArgs,
    adjoint: crate::enlightened::AdjointSettings,
) -> Result<(Vec<Variant>, GuidedLines), CliError> {
    // `+guide` lines are parsed here, the others by `Variant`
    let mut variants = Vec::new();
    let mut guided: GuidedLines = Vec::new();
    for s in &integrator_names(&args.integrators) {
        if s.contains("+guide") {
            let g = GuidedVariant::parse(s)?;
            if let Some(o) = g.guide {
                guided.push((g.kind, o));
            }
        } else {
            variants.push(Variant::parse(s.trim(), adjoint)?);
        }
    }
    if !args.propagation.is_empty() && variants.iter().any(|v| v.adjoint.is_some()) {
        return Err(CliError::Usage(
            "--propagation compares plain integrators; drop the `+adjoint` ones".into(),
        ));
    }
    if args.guide.any() && guided.is_empty() {
        return Err(CliError::Usage(
            "--guide* options apply to `+guide` integrators (e.g. mlt+guide)".into(),
        ));
    }
    if !guided.is_empty() && !args.propagation.is_empty() {
        return Err(CliError::Usage(
            "`+guide` integrators cannot be combined with --propagation".into(),
        ));
    }
    Ok((variants, guided))
}

/// The study's lines: the plain, `+adjoint` and `KIND(...)` ones, then the `+guide` ones.
fn lines_of(
    args: &ConvergeArgs,
    settings: &crate::integrator::RenderSettings,
    (variants, guided): (&[Variant], &[(IntegratorKind, GuideOverride)]),
) -> Result<Vec<Line>, CliError> {
    let mut lines = variants
        .iter()
        .map(|v| v.line(settings))
        .collect::<Result<Vec<_>, _>>()?;
    for (kind, over) in guided {
        lines.push(guided_line(args, settings, *kind, over)?);
    }
    Ok(lines)
}

/// Refuses, before the runs begin, lines whose render would need more memory than
/// `--max-memory` allows (the estimate of `render`, at the scene's resolution).
fn check_memory(
    args: &ConvergeArgs,
    scene: &crate::scene::Scene,
    lines: &[Line],
) -> Result<(), CliError> {
    args.memory.check()?;
    let threads = super::thread_pool(args.threads)?.current_num_threads();
    for line in lines {
        let estimate = crate::render::memory::estimate(scene, line.kind, &line.settings, threads);
        args.memory.refuse_above(&estimate)?;
    }
    Ok(())
}

/// `--external NAME=DIR`, parsed.
fn parse_externals(args: &ConvergeArgs) -> Result<Vec<(String, PathBuf)>, CliError> {
    args.external
        .iter()
        .map(|e| {
            e.split_once('=')
                .filter(|(n, d)| !n.is_empty() && !d.is_empty())
                .map(|(n, d)| (n.to_string(), PathBuf::from(d)))
                .ok_or_else(|| CliError::Usage(format!("--external {e}: expected NAME=DIR")))
        })
        .collect()
}

/// Refuses a reference of another scene (by its `scene_hash` attribute).
fn check_reference_hash(
    args: &ConvergeArgs,
    meta: &image_io::ImageMeta,
    source: &crate::scene::SceneSource,
) -> Result<(), CliError> {
    let hash = super::reference::hash_hex(source.hash());
    match meta.get("scene_hash") {
        Some(h) if h != hash => Err(CliError::OtherScene {
            reference: args.reference.display().to_string(),
            its_scene: meta.get("scene").unwrap_or("unnamed").to_string(),
            its_hash: h.to_string(),
            scene: source.name.clone(),
            hash,
        }),
        Some(_) => Ok(()),
        None => {
            eprintln!(
                "warning: {} has no scene_hash attribute; trusting that it shows {}",
                args.reference.display(),
                source.name
            );
            Ok(())
        }
    }
}

/// Runs every line (per propagation strategy with `--propagation`); the rows.
fn run_lines(
    args: &ConvergeArgs,
    (scene, settings, source): (
        &crate::scene::Scene,
        &crate::integrator::RenderSettings,
        &crate::scene::SceneSource,
    ),
    reference: &image_io::Image,
    lines: &[Line],
    config: &ConvergeConfig,
) -> Result<Vec<convergence::CheckpointRow>, CliError> {
    let pool = super::thread_pool(args.threads)?;
    let mut report = |rows: &[convergence::CheckpointRow]| {
        if let Some(last) = rows.last() {
            eprintln!(
                "{} run {}: {} spp in {:.2} s, relMSE {:.3e}",
                last.integrator, last.run, last.samples, last.seconds, last.relmse
            );
        }
    };
    if args.propagation.is_empty() {
        let fresh = || Ok(super::load_scene_at(Some(&args.scene), &args.film)?.0);
        let at = (scene, settings, source);
        return lines_on_scenes(at, &fresh, reference, lines, config, &pool, &mut report);
    }
    let mut rows = Vec::new();
    for name in &args.propagation {
        let li = crate::medium::heterogeneous::LineIntegral::parse(name.trim())?;
        let fresh = || {
            let mut variant = super::load_scene_at(Some(&args.scene), &args.film)?.0;
            match variant.set_line_integral(li) {
                0 => Err(CliError::Usage(format!(
                    "--propagation: {} has no inhomogeneous medium",
                    source.name
                ))),
                _ => Ok(variant),
            }
        };
        let variant = fresh()?;
        let at = (&variant, settings, source);
        let mut part = lines_on_scenes(at, &fresh, reference, lines, config, &pool, &mut report)?;
        for r in &mut part {
            r.integrator = format!("{}/{}", r.integrator, li.name());
        }
        rows.extend(part);
    }
    Ok(rows)
}

/// Runs `lines` on `scene`, line by line; a line whose transmittance estimator is not the
/// scene's (`KIND(transmittance=...)`) runs on a scene of its own from `fresh`, set to it.
fn lines_on_scenes(
    (scene, settings, source): (
        &crate::scene::Scene,
        &crate::integrator::RenderSettings,
        &crate::scene::SceneSource,
    ),
    fresh: &dyn Fn() -> Result<crate::scene::Scene, CliError>,
    reference: &image_io::Image,
    lines: &[Line],
    config: &ConvergeConfig,
    pool: &rayon::ThreadPool,
    report: &mut (dyn FnMut(&[convergence::CheckpointRow]) + Send),
) -> Result<Vec<convergence::CheckpointRow>, CliError> {
    if lines.is_empty() {
        // the study's own error: nothing to measure
        let none = convergence::converge_lines((scene, source), reference, lines, config, report);
        return Ok(none?);
    }
    let mut rows = Vec::new();
    for line in lines {
        let own;
        let at = if line.settings.transmittance == settings.transmittance {
            scene
        } else {
            let mut s = fresh()?;
            line.settings.prepare(&mut s);
            own = s;
            &own
        };
        let one = std::slice::from_ref(line);
        let part = pool.install(|| {
            convergence::converge_lines((at, source), reference, one, config, &mut *report)
        })?;
        rows.extend(part);
    }
    Ok(rows)
}

pub fn run(args: ConvergeArgs) -> Result<(), CliError> {
    let (scene, settings, source) = super::load_scene_at(Some(&args.scene), &args.film)?;
    let adjoint = args.adjoint.apply(settings.adjoint)?;
    let (variants, guided) = parse_lines(&args, adjoint)?;
    let externals = parse_externals(&args)?;
    let (reference, meta) = image_io::read_exr(&args.reference)?;
    check_reference_hash(&args, &meta, &source)?;
    let config = ConvergeConfig {
        budget: args.budget,
        checkpoints: args.checkpoints,
        runs: args.runs,
        seed: args.seed.unwrap_or(settings.seed),
        max_depth: settings.max_depth,
        shard: args.shard.as_deref().map(shard_of_runs).transpose()?,
    };
    // fail on bad numbers before spending the budget
    convergence::checkpoint_times(config.budget, config.checkpoints)
        .map_err(CliError::Checkpoints)?;
    if config.runs == 0 {
        return Err(CliError::Usage("--runs must be at least 1".into()));
    }
    if let Some(s) = config.shard.filter(|s| s.count as usize > config.runs) {
        return Err(CliError::Usage(format!(
            "--shard {}/{}: {} runs cannot give each of {} shards a run; use at most {} shards",
            s.index, s.count, config.runs, s.count, config.runs
        )));
    }
    let lines = lines_of(&args, &settings, (&variants, &guided))?;
    check_memory(&args, &scene, &lines)?;
    check_study_outputs(&args.output)?;
    let mut external_rows = Vec::new();
    let reads_externals = config.shard.is_none_or(|s| s.index == 1);
    for (name, dir) in externals.iter().filter(|_| reads_externals) {
        external_rows.extend(convergence::external_rows(name, dir, &reference)?);
    }
    let mut rows = run_lines(
        &args,
        (&scene, &settings, &source),
        &reference,
        &lines,
        &config,
    )?;
    rows.extend(external_rows);

    let reference_relmse = meta
        .get("estimated_relmse")
        .and_then(|s| s.parse::<f64>().ok());
    let study = Study {
        scene: source.name.clone(),
        scene_hash: format!("{:016x}", source.hash()),
        budget: config.budget,
        checkpoints: config.checkpoints,
        runs: config.runs,
        seed: config.seed,
        lines: study_lines(&args),
        shard: args.shard.clone(),
        reference_relmse,
    };
    write_study(&args.output, &study, &rows)
}

/// The lines a study asked for, as its record names them.
fn study_lines(args: &ConvergeArgs) -> Vec<String> {
    let mut lines = args.integrators.clone();
    lines.extend(args.propagation.iter().map(|p| format!("propagation {p}")));
    lines.extend(args.external.iter().map(|e| format!("external {e}")));
    lines
}

/// `--shard I/N` of a study's runs.
fn shard_of_runs(text: &str) -> Result<crate::render::shard::Shard, CliError> {
    crate::render::shard::Shard::parse(text).map_err(|e| CliError::Usage(e.to_string()))
}

/// Checks, before the runs, that a study can be written into `dir` (created when missing): its
/// rows, record and charts, so that a directory that cannot be written costs no budget.
pub fn check_study_outputs(dir: &std::path::Path) -> Result<(), CliError> {
    image_io::check_output_dir(dir)?;
    let mut files = vec![
        dir.join(CSV_FILE),
        dir.join(crate::measure::study::STUDY_FILE),
    ];
    files.extend(chart::chart_paths(dir));
    for f in &files {
        image_io::check_output_file(f)?;
    }
    Ok(())
}

/// The file of a study's rows.
const CSV_FILE: &str = "convergence.csv";

/// Writes a study's rows (`convergence.csv`), its record (`study.toml`) and its charts into
/// `dir`, and prints its summary: what `converge` ends with, and `merge` of its shards.
pub fn write_study(
    dir: &std::path::Path,
    study: &Study,
    rows: &[convergence::CheckpointRow],
) -> Result<(), CliError> {
    let csv = dir.join(CSV_FILE);
    convergence::write_csv(&csv, rows)?;
    study.write(dir)?;
    let curves = convergence::summarize(rows);
    let reference_relmse = study.reference_relmse;
    let mut written = vec![csv, dir.join(crate::measure::study::STUDY_FILE)];
    written.extend(chart::write_charts(dir, &curves, reference_relmse)?);
    for c in &curves {
        println!("{}", summary_line(c));
    }
    if let Some(w) = reference_relmse.and_then(|r| noisy_reference_warning(r, &curves)) {
        eprintln!("warning: {w}");
    }
    println!(
        "wrote {}",
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
