//! The command line: one file per subcommand. Progress goes to stderr, results to stdout.

pub mod converge;
pub mod diff;
pub mod info;
pub mod merge;
pub mod reference;
pub mod render;
pub mod rooms;

/// `pathspace assignment` lives with the course it serves.
pub use crate::course::assignment;

use clap::{Parser, Subcommand};

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
    Render(render::RenderArgs),
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

/// Runs the command line; returns the process exit code.
pub fn run(cli: Cli) -> Result<(), String> {
    run_with_source(cli, &[])
}

/// Runs the command line with the crate's source tree embedded by `build.rs` (the binary passes
/// it; `assignment make` writes student copies from it).
pub fn run_with_source(cli: Cli, source_tree: &[(&str, &[u8])]) -> Result<(), String> {
    match cli.command {
        None => render::run(render::RenderArgs::default()),
        Some(Command::Render(a)) => render::run(a),
        Some(Command::Diff(a)) => diff::run(a),
        Some(Command::Reference(a)) => reference::run(a),
        Some(Command::Converge(a)) => converge::run(a),
        Some(Command::Info(a)) => info::run(a),
        Some(Command::Rooms(a)) => rooms::run(a),
        Some(Command::Merge(a)) => merge::run(a),
        Some(Command::Assignment(a)) => assignment::run(a, source_tree),
    }
}

/// Loads the named scene, or the embedded fog box when `None`.
pub fn load_scene(
    path: Option<&std::path::Path>,
) -> Result<(crate::scene::Scene, crate::scene::SceneSource), String> {
    let source = match path {
        Some(p) => crate::scene::SceneSource::read(p).map_err(|e| e.to_string())?,
        None => {
            crate::scene::SceneSource::embedded("fog-box.toml (embedded)", crate::scene::FOG_BOX)
        }
    };
    let scene = crate::scene::Scene::load(&source).map_err(|e| e.to_string())?;
    Ok((scene, source))
}
