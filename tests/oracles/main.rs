//! Oracles: renders and estimators against answers known without the renderer (closed
//! forms, an independent slab solver, unbiased references, stored golden statistics).

#[path = "../common/mod.rs"]
mod common;

mod agreement;
mod emission;
mod golden;
mod lens;
mod mlt_failures;
mod primer;
mod slab;
mod transport;
