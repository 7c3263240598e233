//! Inputs: what the renderer is given and what it writes (scene-file errors, imported
//! scenes, bounded cost for any input, writes that cannot destroy).

#[path = "../common/mod.rs"]
mod common;

mod bounds;
mod error_contract;
mod mitsuba_import;
mod scene_errors;
mod serialized;
mod vdb;
mod writes;
