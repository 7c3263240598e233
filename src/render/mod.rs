//! A render around the integrators: its session (preprocessing stages, passes, progress),
//! checkpoints, provenance, shards and memory estimate.
//! Book: "Measuring a renderer".

pub mod checkpoint;
pub mod memory;
pub mod provenance;
pub mod session;
pub mod shard;
