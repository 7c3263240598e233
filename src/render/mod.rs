//! A render around the integrators: its session (preprocessing stages, passes, progress),
//! checkpoints, provenance, shards and memory estimate.
//! Book: "Measuring a renderer".

pub mod checkpoint;
pub mod memory;
pub mod plan;
pub mod provenance;
pub mod session;
pub mod shard;

use crate::integrator::IntegratorError;
use checkpoint::CheckpointError;

/// Why a render cannot run: the integrator refuses, or a checkpoint cannot be read, resumed
/// from or written (the messages the command line prints).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Integrator(#[from] IntegratorError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}
