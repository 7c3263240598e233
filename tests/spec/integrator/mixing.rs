//! The MCMC integrators' mixing report (`integrator::mixing`):
//!
//! (a) the block grid and the batches: blocks of 8 pixels (larger on large images, at most
//!     16 a side), named by their pixels; a chain keeps at most `MAX_BATCHES` batches whatever
//!     its length (memory bounded), and chains stuck in different blocks are infinitely apart;
//! (b) on the slow-mixing scene (`scenes/mlt-haze-sphere.toml`: haze inside a rough glass
//!     sphere in a glossy room) the warning fires after a short run of MLT (64 mutations per
//!     pixel), names the worst block, and is silent after a long one (4096); it is silent on the
//!     fog box after 256 (the fog box mixes in a few times fewer steps);
//! (c) the report is the same on one thread or three, and reaches `render --json`, the EXR
//!     header and stderr.

use crate::common;

use glam::Vec2;
use pathspace::film::Film;
use pathspace::integrator::mixing::{BlockGrid, ChainTrace, Mixing, MAX_BATCHES, RHAT_THRESHOLD};
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::Rgb;

use common::cli::{pathspace, scratch, stderr};

// ------------------------------------------------------------------------------------------
// (a) blocks and batches

#[test]
fn blocks_are_eight_pixels_and_at_most_sixteen_a_side() {
    let g = BlockGrid::new(32, 32);
    assert_eq!((g.size, g.cols, g.rows, g.len()), (8, 4, 4, 16));
    let g = BlockGrid::new(20, 12);
    assert_eq!((g.size, g.cols, g.rows), (8, 3, 2));
    assert_eq!(g.name(5), "x 16-19, y 8-11");
    assert_eq!(g.block(Vec2::new(19.9, 11.5)), Some(5));
    assert_eq!(g.block(Vec2::new(20.0, 1.0)), None);
    assert_eq!(g.block(Vec2::new(-0.1, 1.0)), None);
    let g = BlockGrid::new(512, 300);
    assert_eq!((g.size, g.cols, g.rows), (32, 16, 10));
}

#[test]
fn a_chain_keeps_a_bounded_number_of_batches() {
    let grid = BlockGrid::new(16, 8);
    let mut traces = vec![ChainTrace::default(), ChainTrace::default()];
    for i in 0..100_000u32 {
        for (c, t) in traces.iter_mut().enumerate() {
            // chain 0 stays in block 0, chain 1 in block 1
            let p = Vec2::new(0.5 + 8.0 * c as f32, (i % 8) as f32);
            t.step(&grid, &[(p, Rgb::ONE)]);
            assert!(t.count() <= MAX_BATCHES);
        }
    }
    let m = Mixing::of(grid, &traces);
    assert!(
        m.batches >= MAX_BATCHES / 2 && m.batches <= MAX_BATCHES,
        "{}",
        m.batches
    );
    assert!(m.batch_steps.is_power_of_two());
    assert!(m.batches as u64 * m.batch_steps <= 100_000);
    assert!(m.batches as u64 * m.batch_steps * 2 > 100_000);
    // stuck apart: infinitely far
    assert_eq!(m.blocks[0].rhat, Some(f64::INFINITY));
    assert_eq!(m.unmixed_blocks(), vec![0, 1]);
    assert!(m.warning("mlt").unwrap().contains("x 0-7, y 0-7"));
}

// ------------------------------------------------------------------------------------------
// (b) the slow-mixing scene

fn scene(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("scene file");
    let text = text.replace("resolution = [256, 256]", "resolution = [16, 16]");
    Scene::load(&SceneSource::embedded(name, &text)).expect("valid scene")
}

/// MLT's mixing report after `spp` mutations per pixel (one pass) of four chains (the haze
/// sphere's `[render.mlt]`), with the scene's depth limit.
fn mlt_mixing(scene: &Scene, spp: u64, seed: u64, max_depth: Option<u32>) -> Mixing {
    let settings = MltSettings {
        bootstrap: 4096,
        chains: 4,
        ..MltSettings::default()
    };
    let mut m = Mlt::new(scene, &pathspace::path::PLAIN, settings, seed, max_depth).unwrap();
    let cam = scene.camera.as_ref().unwrap();
    let mut film = Film::new(cam.width, cam.height);
    m.run(scene, &mut film, cam.width as u64 * cam.height as u64 * spp);
    m.mixing.mixing().unwrap()
}

/// The haze sphere's depth limit (`[render] max_depth`).
const HAZE_DEPTH: Option<u32> = Some(8);
/// Mutations per pixel of the short run (4096 steps per chain on 16 x 16 pixels), of the long
/// one (262144 steps per chain) and of the fog box (16384 steps per chain).
const SHORT: u64 = 64;
const LONG: u64 = 4096;
const FOG: u64 = 256;

#[test]
fn the_warning_fires_on_the_haze_sphere_after_a_short_run_only() {
    let s = scene("mlt-haze-sphere.toml");
    assert_eq!(s.camera.as_ref().map(|c| c.width), Some(16));
    let short = mlt_mixing(&s, SHORT, 1, HAZE_DEPTH);
    let w = short.warning("mlt");
    assert!(
        w.is_some(),
        "no warning after {SHORT} mutations per pixel: {}",
        short.line()
    );
    let (worst, r) = short.worst_rhat().unwrap();
    assert!(r > RHAT_THRESHOLD, "{}", short.line());
    assert!(w.unwrap().contains(&short.grid.name(worst)));
    let long = mlt_mixing(&s, LONG, 1, HAZE_DEPTH);
    assert_eq!(long.warning("mlt"), None, "{}", long.line());
}

#[test]
fn the_warning_is_silent_on_the_fog_box() {
    let fog = mlt_mixing(&scene("fog-box.toml"), FOG, 1, None);
    assert_eq!(fog.warning("mlt"), None, "{}", fog.line());
}

// ------------------------------------------------------------------------------------------
// (c) determinism and the outputs

#[test]
fn the_report_does_not_depend_on_the_threads() {
    let s = scene("mlt-haze-sphere.toml");
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| mlt_mixing(&s, 8, 3, HAZE_DEPTH))
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn render_reports_the_mixing_in_json_the_header_and_stderr() {
    let dir = scratch("mixing", "render");
    let exr = dir.join("haze.exr");
    let scene = format!("{}/scenes/mlt-haze-sphere.toml", env!("CARGO_MANIFEST_DIR"));
    let spp = SHORT.to_string();
    for integrator in ["mlt", "pssmlt", "mmlt"] {
        let out = pathspace(&[
            "render",
            &scene,
            "--integrator",
            integrator,
            "--spp",
            &spp,
            "--json",
            "--threads",
            "2",
            "-o",
            exr.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let mixing = &j[integrator]["mixing"];
        assert_eq!(mixing["blocks"], serde_json::json!([2, 2]), "{j}");
        assert!(
            mixing["rhat"].as_array().is_some_and(|r| r.len() == 2),
            "{mixing}"
        );
        let (_, meta) = pathspace::image_io::read_exr(&exr).unwrap();
        assert!(
            meta.get("mixing_rhat_max").is_some(),
            "{:?}",
            meta.attributes
        );
        assert!(meta.get("mixing_rhat").is_some());
        if integrator == "mlt" {
            let e = stderr(&out);
            assert!(e.contains("warning: mlt: the chains have not mixed"), "{e}");
            assert!(!mixing["unmixed"].as_array().unwrap().is_empty());
        }
    }
}
