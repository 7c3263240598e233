//! `pathspace reference SCENE [--spp N | --time SECONDS] [-o REF.exr] [--seed S] [--threads N]`:
//! a high-sample render with the most robust integrator, the yardstick of `converge` and `diff`.
//! The EXR records its integrator, spp, seed, seconds and scene hash; an existing reference of a
//! different scene is never overwritten.

use clap::Args;
use std::path::{Path, PathBuf};

use super::CliError;
use crate::image_io::{self, ImageMeta};
use crate::measure;

/// Samples per pixel of a reference when neither --spp nor --time is given.
pub const DEFAULT_REFERENCE_SPP: u32 = 4096;

#[derive(Args, Debug, Clone)]
pub struct ReferenceArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Samples per pixel (default 4096).
    #[arg(long, conflicts_with = "time")]
    pub spp: Option<u32>,
    /// Render for this many seconds instead of a fixed spp.
    #[arg(long)]
    pub time: Option<f64>,
    /// Output EXR (default: the scene's name with -ref.exr, in the current directory).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Random seed (default: the scene's `[render] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Override the integrator (default: the most robust one for the scene, see
    /// `measure::reference_integrator`), e.g. `bdpt` where light arrives through long chains.
    #[arg(long)]
    pub integrator: Option<String>,
}

/// A rayon pool of `threads` workers (all cores when None).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, CliError> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        if t == 0 {
            return Err(CliError::Usage("--threads must be at least 1".into()));
        }
        pool = pool.num_threads(t);
    }
    pool.build().map_err(CliError::Threads)
}

/// The scene hash as written in EXR attributes: 16 hex digits.
pub fn hash_hex(hash: u64) -> String {
    format!("{hash:016x}")
}

// ANCHOR: refuse_overwrite
/// Refuses to replace `output` unless it is a reference of the same scene file (same
/// `scene_hash`): a reference can take hours, and overwriting one with a render of another
/// scene would silently invalidate every study measured against it.
pub fn check_overwrite(output: &Path, scene_name: &str, scene_hash: &str) -> Result<(), CliError> {
    if !output.exists() {
        return Ok(());
    }
    let meta = match image_io::read_exr(output) {
        Ok((_, meta)) => meta,
        Err(e) => {
            return Err(CliError::OverwriteUnreadable(
                output.display().to_string(),
                e,
            ))
        }
    };
    match meta.get("scene_hash") {
        Some(h) if h == scene_hash => Ok(()),
        Some(h) => Err(CliError::OverwriteOtherScene {
            output: output.display().to_string(),
            its_scene: meta.get("scene").unwrap_or("unnamed").to_string(),
            its_hash: h.to_string(),
            scene: scene_name.to_string(),
            hash: scene_hash.to_string(),
        }),
        None => Err(CliError::OverwriteNotReference(
            output.display().to_string(),
            scene_name.to_string(),
        )),
    }
}
// ANCHOR_END: refuse_overwrite

pub fn run(args: ReferenceArgs) -> Result<(), CliError> {
    let (scene, settings, source) = super::load_scene(Some(&args.scene))?;
    if scene.camera.is_none() {
        return Err(CliError::NoCamera(source.name));
    }
    let spp = args.spp.unwrap_or(DEFAULT_REFERENCE_SPP);
    if spp == 0 {
        return Err(CliError::Usage("--spp must be at least 1".into()));
    }
    if let Some(t) = args.time {
        if !(t > 0.0 && t.is_finite()) {
            return Err(CliError::Usage(format!(
                "--time {t} must be a positive number of seconds"
            )));
        }
    }
    let stem = args
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "scene".into());
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{stem}-ref.exr")));
    let hash = hash_hex(source.hash());
    check_overwrite(&output, &source.name, &hash)?;

    let kind = match &args.integrator {
        Some(name) => crate::integrator::IntegratorKind::parse(name)?,
        None => measure::reference_integrator(&scene),
    };
    let seed = args.seed.unwrap_or(settings.seed);
    let job = crate::integrator::session::Job {
        kind,
        setup: crate::integrator::Setup {
            scene: &scene,
            technique: &crate::path::PLAIN,
            settings: &settings,
            seed,
            max_depth: settings.max_depth,
        },
        spp,
        time: args.time,
        progress: true,
    };
    let pool = thread_pool(args.threads)?;
    let result = pool.install(|| crate::integrator::session::render(&job))?;
    let estimated = super::render::estimated_relmse(&result);
    let image = result.image.as_ref().ok_or(CliError::NoImage)?;
    let mut meta = ImageMeta::default();
    meta.set("integrator", &result.integrator)
        .set("spp", result.spp)
        .set("seed", seed)
        .set("seconds", format!("{:.3}", result.seconds))
        .set("scene", &source.name)
        .set("scene_hash", &hash)
        .set("nan_count", result.nan_count)
        .set(
            "streams",
            crate::integrator::provenance::format_streams(&result.streams),
        )
        .set("reference", "true");
    if let Some(e) = estimated {
        meta.set("estimated_relmse", format!("{e:.6e}"));
    }
    image_io::write_exr(&output, image, &meta)?;
    println!(
        "reference of {} with {}: {} spp in {:.1} s, estimated relMSE {} -> {}",
        source.name,
        result.integrator,
        result.spp,
        result.seconds,
        estimated.map_or("n/a".to_string(), |e| format!("{e:.3e}")),
        output.display()
    );
    Ok(())
}
