//! `pathspace converge SCENE --reference REF.exr --integrators path,... --budget SECONDS
//! [--checkpoints K] [--runs R] [--seed S] [--threads N] [-o DIR] [--external NAME=DIR]...`:
//! an equal-time convergence study, written as `DIR/convergence.csv`, `DIR/error-vs-time.{svg,png}`
//! and `DIR/efficiency.{svg,png}`.

use clap::Args;
use std::path::PathBuf;

use crate::image_io;
use crate::integrator::IntegratorKind;
use crate::measure::chart;
use crate::measure::convergence::{self, ConvergeConfig, Curve, Variant};

#[derive(Args, Debug, Clone)]
pub struct ConvergeArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// The reference EXR (from `pathspace reference`).
    #[arg(long)]
    pub reference: PathBuf,
    /// Integrators to compare, comma-separated; `bdpt+adjoint`, `light+adjoint`, `mlt+adjoint`
    /// use the adjoint image (its pre-pass time counts in the budget; settings from the
    /// scene's `[render.adjoint]`).
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
    /// Output directory.
    #[arg(short = 'o', long = "output", default_value = "convergence")]
    pub output: PathBuf,
    /// Another renderer's images as one more line: NAME=DIR, DIR holding `<seconds>.exr` files
    /// (or EXRs with a `seconds` attribute). Repeatable.
    #[arg(long = "external", value_name = "NAME=DIR")]
    pub external: Vec<String>,
    /// `+adjoint` variants: adjoint grid COLSxROWS (default: the scene's `[render.adjoint]`).
    #[arg(long, value_parser = super::render::parse_resolution)]
    pub adjoint_resolution: Option<(u32, u32)>,
    /// `+adjoint` variants: pre-pass samples per cell (default: `[render.adjoint]`, or 8).
    #[arg(long)]
    pub adjoint_samples: Option<u32>,
    /// `+adjoint` variants: the floor as a fraction of the mean cell (default 0.5).
    #[arg(long)]
    pub adjoint_epsilon: Option<f32>,
    /// Run every integrator once per propagation strategy of the scene's inhomogeneous media
    /// (comma-separated: equidistant, stratified, random-offset, delta-tracking); the lines are
    /// labelled `integrator/strategy`. The reference stays the same (same scene file).
    #[arg(long, value_delimiter = ',')]
    pub propagation: Vec<String>,
}

/// One line of the summary printed at the end.
fn summary_line(c: &Curve) -> String {
    let mut s = c.integrator.to_string();
    if let Some(p) = c.last() {
        s += &format!(
            ": at {:.2} s {:.0} spp, relMSE {:.3e} ± {:.1e}, RMSE {:.3e}, efficiency {:.3e} /s",
            p.seconds.mean,
            p.samples.mean,
            p.relmse.mean,
            p.relmse.stderr,
            p.rmse.mean,
            p.efficiency.mean
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

pub fn run(args: ConvergeArgs) -> Result<(), String> {
    let (mut scene, source) = super::load_scene(Some(&args.scene))?;
    let mut adjoint = scene.render.adjoint;
    if let Some(r) = args.adjoint_resolution {
        adjoint.resolution = r;
    }
    if let Some(n) = args.adjoint_samples {
        adjoint.samples_per_cell = n;
    }
    if let Some(e) = args.adjoint_epsilon {
        adjoint.epsilon = e;
    }
    adjoint
        .validate()
        .map_err(|e| format!("--adjoint-*: {e}"))?;
    let variants = args
        .integrators
        .iter()
        .map(|s| Variant::parse(s.trim(), adjoint))
        .collect::<Result<Vec<_>, _>>()?;
    let kinds: Vec<IntegratorKind> = variants.iter().map(|v| v.kind).collect();
    if !args.propagation.is_empty() && variants.iter().any(|v| v.adjoint.is_some()) {
        return Err("--propagation compares plain integrators; drop the `+adjoint` ones".into());
    }
    let externals = args
        .external
        .iter()
        .map(|e| {
            e.split_once('=')
                .filter(|(n, d)| !n.is_empty() && !d.is_empty())
                .map(|(n, d)| (n.to_string(), PathBuf::from(d)))
                .ok_or_else(|| format!("--external {e}: expected NAME=DIR"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (reference, meta) = image_io::read_exr(&args.reference).map_err(|e| e.to_string())?;
    let hash = super::reference::hash_hex(source.hash());
    match meta.get("scene_hash") {
        Some(h) if h != hash => {
            return Err(format!(
                "{} is a reference of another scene ({}, scene_hash {h}), not of {} (scene_hash {hash})",
                args.reference.display(),
                meta.get("scene").unwrap_or("unnamed"),
                source.name
            ))
        }
        Some(_) => {}
        None => eprintln!(
            "warning: {} has no scene_hash attribute; trusting that it shows {}",
            args.reference.display(),
            source.name
        ),
    }
    let config = ConvergeConfig {
        budget: args.budget,
        checkpoints: args.checkpoints,
        runs: args.runs,
        seed: args.seed.unwrap_or(scene.render.seed),
        max_depth: scene.render.max_depth,
    };
    // fail on bad numbers before spending the budget
    convergence::checkpoint_times(config.budget, config.checkpoints)
        .map_err(|e| format!("--budget/--checkpoints: {e}"))?;
    if config.runs == 0 {
        return Err("--runs must be at least 1".into());
    }
    std::fs::create_dir_all(&args.output).map_err(|e| format!("{}: {e}", args.output.display()))?;
    let mut external_rows = Vec::new();
    for (name, dir) in &externals {
        external_rows.extend(convergence::external_rows(name, dir, &reference)?);
    }

    let pool = super::reference::thread_pool(args.threads)?;
    let mut report = |rows: &[convergence::CheckpointRow]| {
        if let Some(last) = rows.last() {
            eprintln!(
                "{} run {}: {} spp in {:.2} s, relMSE {:.3e}",
                last.integrator, last.run, last.samples, last.seconds, last.relmse
            );
        }
    };
    let mut rows = Vec::new();
    if args.propagation.is_empty() {
        rows = pool.install(|| {
            convergence::converge_variants(&mut scene, &reference, &variants, &config, &mut report)
        })?;
    } else {
        for name in &args.propagation {
            let li = crate::medium::heterogeneous::LineIntegral::parse(name.trim())?;
            let (mut variant, _) = super::load_scene(Some(&args.scene))?;
            if variant.set_line_integral(li) == 0 {
                return Err(format!(
                    "--propagation: {} has no inhomogeneous medium",
                    source.name
                ));
            }
            let mut part = pool.install(|| {
                convergence::converge(&variant, &reference, &kinds, &config, &mut report)
            })?;
            for r in &mut part {
                r.integrator = format!("{}/{}", r.integrator, li.name());
            }
            rows.extend(part);
        }
    }
    rows.extend(external_rows);

    let csv = args.output.join("convergence.csv");
    convergence::write_csv(&csv, &rows)?;
    let curves = convergence::summarize(&rows);
    let mut written = vec![csv];
    let reference_relmse = meta
        .get("estimated_relmse")
        .and_then(|s| s.parse::<f64>().ok());
    written.extend(chart::write_charts(
        &args.output,
        &curves,
        reference_relmse,
    )?);
    for c in &curves {
        println!("{}", summary_line(c));
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
