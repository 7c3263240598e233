//! A render around the integrators: its session (preprocessing stages, passes, progress),
//! checkpoints, provenance, shards and memory estimate.
//! Book: "Measuring a renderer".

pub mod checkpoint;
pub mod memory;
pub mod plan;
pub mod provenance;
pub mod run;
pub mod session;
pub mod shard;

pub use run::{Frontend, Outputs, Render, Rendered};

use crate::integrator::IntegratorError;
use checkpoint::CheckpointError;

/// Why a render cannot run: the integrator refuses, or a checkpoint cannot be read, resumed
/// from or written (the messages the command line prints).
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Integrator(#[from] IntegratorError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// A shard that cannot be rendered as asked.
    #[error(transparent)]
    Shard(#[from] shard::ShardError),
    /// An output that cannot be written.
    #[error(transparent)]
    Output(#[from] crate::image_io::ImageError),
    /// More memory than the limit allows.
    #[error(transparent)]
    Memory(#[from] memory::MemoryError),
}
