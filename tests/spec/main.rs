//! The executable specification, laid out like `src/`: the module `a::b` specifies
//! `src/a/b.rs` (or `src/a/b/mod.rs`); `tests/repository/index.rs` checks that every module
//! of `src/` has one here or names the test module that covers it.

#[path = "../common/mod.rs"]
mod common;

mod aov;
mod bsdf;
mod cli;
mod enlightened;
mod film {
    mod filter;
}
mod geometry;
mod integrator {
    mod mixing;
    mod mlt;
    mod mmlt;
    mod path;
    mod pssmlt;
    mod reach;
    mod settings;
    mod smc {
        mod cache;
        mod march;
    }
}
mod math {
    mod mixing;
    mod primary_sample;
    mod sampler;
    mod warp;
}
mod measure;
mod medium {
    mod equiangular;
    mod heterogeneous;
    mod homogeneous;
    mod phase;
    mod vdb;
}
mod path;
mod render {
    mod checkpoint;
    mod provenance;
    mod run;
    mod shard;
}
mod scene;
mod spectrum {
    mod cie;
}
mod texture;
