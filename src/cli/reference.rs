//! `pathspace reference SCENE [--spp N | --time SECONDS] [-o REF.exr] [--seed S] [--threads N]
//! [--integrator I] [--checkpoint SECONDS] [--resume FILE] [--max-memory GIB] [--reproducible]`:
//! a high-sample render with the most robust integrator, the yardstick of `converge` and `diff`.
//! It is `render` with other defaults (the integrator of `measure::reference_integrator`, 4096
//! spp, `SCENE-ref.exr`), run by `render`'s steps, so that its checks before the work, its
//! signal handling, checkpoints and records are `render`'s. The EXR records `reference = true`
//! and the estimated relMSE besides; an existing reference of a different scene is never
//! overwritten.

use clap::Args;
use std::path::{Path, PathBuf};

use super::render_args::{RenderArgs, SessionArgs};
use super::CliError;
use crate::image_io;
use crate::integrator::settings::{GuideOptions, RenderOptions};
use crate::measure;

/// Samples per pixel of a reference when neither --spp nor --time is given.
pub const DEFAULT_REFERENCE_SPP: u32 = 4096;

#[derive(Args, Debug, Clone)]
pub struct ReferenceArgs {
    /// Scene file (TOML, or Mitsuba 3 XML by its `.xml` extension).
    pub scene: PathBuf,
    /// Samples per pixel (default 4096).
    #[arg(long, conflicts_with = "time")]
    pub spp: Option<u32>,
    /// Random seed (default: the scene's `[render] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override the integrator (default: the most robust one for the scene, see
    /// `measure::reference_integrator`), e.g. `bdpt` where light arrives through long chains.
    #[arg(long)]
    pub integrator: Option<crate::integrator::IntegratorKind>,
    /// The session's options, declared once with `render`'s.
    #[command(flatten)]
    pub session: SessionArgs,
}

impl ReferenceArgs {
    /// The `render` these arguments ask for on `scene`: its integrator (by default the most
    /// robust one for the scene), spp (default 4096), seed and session options, always with
    /// plain local sampling: a scene's `[render.guide]` and `adjoint_image` are for the methods
    /// a reference judges, and the yardstick must not share their preprocessing.
    fn render_args(&self, scene: &crate::scene::Scene) -> RenderArgs {
        let integrator = self
            .integrator
            .unwrap_or_else(|| measure::reference_integrator(scene));
        let options = RenderOptions {
            integrator: Some(integrator),
            // a resume takes the target from its checkpoint
            spp: match self.session.resume {
                Some(_) => self.spp,
                None => Some(self.spp.unwrap_or(DEFAULT_REFERENCE_SPP)),
            },
            seed: self.seed,
            adjoint_image: Some(false),
            guide: GuideOptions {
                vertices: Some(crate::enlightened::GuideKind::Off),
                ..GuideOptions::default()
            },
            ..RenderOptions::default()
        };
        RenderArgs {
            scene: Some(self.scene.clone()),
            options: Box::new(options),
            session: self.session.clone(),
            reference: true,
            ..RenderArgs::default()
        }
    }
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
    let (mut scene, settings, source) = super::load_scene(Some(&args.scene))?;
    if scene.camera.is_none() {
        return Err(CliError::NoCamera(source.name));
    }
    let mut render = args.render_args(&scene);
    if let Some(file) = render.session.resume.clone() {
        super::resume::complete(&mut render, &super::render::resume_path(&file))?;
    }
    render.session.film.apply(&mut scene)?;
    let (output, _) = super::render::output_paths(&render);
    check_overwrite(&output, &source.name, &hash_hex(source.hash()))?;
    super::render::run_scene(&render, &mut scene, settings, &source)
}
