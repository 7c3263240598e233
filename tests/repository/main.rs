//! The repository's own checks: the book builds and reads, every documented
//! command parses and runs, the layers of the crate, the figures, the build, and the index
//! of the test tree itself.

#[path = "../common/mod.rs"]
mod common;

mod book;
mod book_browser;
mod builds;
mod commands;
mod commands_run;
mod figures;
mod index;
mod layers;
mod peers;
mod ray_sets;
