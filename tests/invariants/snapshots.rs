//! Snapshots of the exact bytes of small deterministic renders, one per integrator: the fog box
//! at 8 x 8 pixels, 4 samples per pixel, seed 7, on 2 threads, rendered by the binary
//! (`--reproducible`) and read back from its EXR. Any change to sampling (a random number drawn
//! in another order, an operation reordered) changes them, so it shows as a snapshot diff to
//! review; whether such a change is *right* is the statistical goldens' question
//! (`tests/oracles/golden.rs`, `tests/oracles/agreement.rs`), not theirs.
//!
//! Each snapshot (`tests/invariants/snapshots/invariants__snapshots__NAME.snap`) holds the FNV-1a hash of the pixels'
//! f32 bits and, per row, each pixel's red, green and blue f32 bits in hex, so a diff shows
//! which pixels moved. After a deliberate change, review and accept the new snapshots with
//! `cargo insta review` (or rerun with `INSTA_UPDATE=always`) and commit them with the change;
//! a plain `cargo test --release` fails on any mismatch (and writes nothing under `CI=true`).

use crate::common;

use common::cli::{pathspace, scratch, stderr};
use std::fmt::Write;

/// The render behind every snapshot: small enough for the five to take a few seconds.
const ARGS: [&str; 9] = [
    "--resolution",
    "8x8",
    "--spp",
    "4",
    "--seed",
    "7",
    "--threads",
    "2",
    "--reproducible",
];

/// The fog box rendered by `integrator`, as the text its snapshot holds.
fn render(integrator: &str) -> String {
    let dir = scratch("snapshots", integrator);
    let out = dir.join("out.exr");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fog-box.toml");
    let mut args = vec!["render", scene, "--integrator", integrator, "-o"];
    args.push(out.to_str().unwrap());
    args.extend(ARGS);
    let run = pathspace(&args);
    assert!(run.status.success(), "{integrator}: {}", stderr(&run));
    let (image, _) = pathspace::image_io::read_exr(&out).unwrap();
    let bits: Vec<u32> = image
        .pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(f32::to_bits)
        .collect();
    let bytes: Vec<u8> = bits.iter().flat_map(|b| b.to_le_bytes()).collect();
    let mut text = format!(
        "{}x{} pixels, fnv1a {:016x}\n",
        image.width,
        image.height,
        pathspace::conventions::fnv1a(&bytes)
    );
    for row in bits.chunks(3 * image.width as usize) {
        let words: Vec<String> = row.iter().map(|b| format!("{b:08x}")).collect();
        writeln!(text, "{}", words.join(" ")).unwrap();
    }
    text
}

#[test]
fn path_tracer_fog_box() {
    insta::assert_snapshot!("path", render("path"));
}

#[test]
fn light_tracer_fog_box() {
    insta::assert_snapshot!("light", render("light"));
}

#[test]
fn bdpt_fog_box() {
    insta::assert_snapshot!("bdpt", render("bdpt"));
}

#[test]
fn mlt_fog_box() {
    insta::assert_snapshot!("mlt", render("mlt"));
}

#[test]
fn smc_fog_box() {
    insta::assert_snapshot!("smc", render("smc"));
}
