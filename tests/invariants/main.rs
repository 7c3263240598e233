//! Invariants: properties every render keeps whatever the scene (determinism, bit
//! identity, exact snapshots, unbiasedness, cached densities equal to their recomputation)
//! and the calibration of the suite's own statistics.

#[path = "../common/mod.rs"]
mod common;

mod bdpt_weights;
mod coplanar;
mod determinism;
mod path_verify;
mod smc_determinism;
mod smc_unbiased;
mod snapshots;
mod statistics;
