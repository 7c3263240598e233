//! Golden renders: low-spp renders compared with stored golden statistics, each golden number
//! with its own standard error, by Welch's t test (`tests/common/stats.rs`), never bitwise and
//! never rounded. A change of behaviour larger than the two renders' combined noise fails; one
//! within it passes, on every platform.
//!
//! The goldens, in `golden/`:
//! - `fog-box-32-blocks.json`: the means and standard errors of the 4 x 4 blocks of the fog box
//!   at 32 x 32 pixels, 16384 samples per pixel (seed 1001), written by
//!   `PATHSPACE_WRITE_GOLDEN=1 cargo test --release --test oracles -- --ignored golden::write_fog_box_golden`;
//! - `slab-meters.json`: the slab's meters at 512 spp, written by
//!   `pathspace render scenes/slab.toml --spp 512 --seed 2024 --json > golden/slab-meters.json`;
//! - `fog-box-32.exr` and `.png`: the picture of the fog box golden, written by
//!   `pathspace render scenes/fog-box.toml --resolution 32x32 --spp 16384 --seed 1001 -o golden/fog-box-32.exr --png golden/fog-box-32.png`.
//!
//! After a deliberate change of behaviour, rerun the commands and commit the new goldens with
//! the change: the diff of the JSON shows which numbers moved.

use crate::common;

use common::stats::Family;
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

/// Blocks per side of the image summary.
const BLOCKS: u32 = 4;
/// Samples per pixel of the checked render: the image mean's standard error is then 0.4%, so
/// a change of 2.5% fails (a 5% brighter light moved it by 5 standard errors at 256 spp, short
/// of the family's level); and the standard errors estimated from the samples are reliable in
/// the darker corners (at 64 spp they are not).
const SPP: u32 = 1024;
/// Samples per pixel per pass (the golden was rendered in passes of this size).
const PASS: u32 = 256;
/// The golden render: samples per pixel, in passes of [`PASS`], and its seed.
const GOLDEN_SPP: u32 = 16384;
const GOLDEN_SEED: u64 = 1001;
const RESOLUTION: u32 = 32;

fn root() -> &'static std::path::Path {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn fog_box() -> Scene {
    let res = format!("resolution = [{RESOLUTION}, {RESOLUTION}]");
    let text = FOG_BOX.replace("resolution = [256, 256]", &res);
    assert_ne!(text, FOG_BOX, "the fog box's resolution line changed");
    Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap()
}

/// One block of the summary: per channel mean, standard error, and the samples behind it.
#[derive(Clone, Debug)]
struct Block {
    mean: [f64; 3],
    stderr: [f64; 3],
    samples: u64,
}

/// The 4 x 4 block means of a path-traced fog box of `spp` samples per pixel (in passes of
/// [`PASS`]), with standard errors from the pixels' own sample variances (pixels are
/// independent, so a block's variance of the mean is the sum of its pixels' over n^2).
fn fog_box_blocks(spp: u32, seed: u64) -> Vec<Block> {
    let scene = fog_box();
    let mut r = Renderer::new(&scene, IntegratorKind::Path, seed, None);
    let mut left = spp;
    while left > 0 {
        let pass = left.min(PASS);
        r.pass(pass, &|| {});
        left -= pass;
    }
    assert_eq!(r.nan_count, 0);
    let film = r.film.as_ref().unwrap();
    let (img, var) = (film.image(), film.variance_of_mean());
    let bs = img.width / BLOCKS;
    let mut out = Vec::new();
    for by in 0..BLOCKS {
        for bx in 0..BLOCKS {
            let mut m = [0.0f64; 3];
            let mut v = [0.0f64; 3];
            for y in by * bs..(by + 1) * bs {
                for x in bx * bs..(bx + 1) * bs {
                    let i = (y * img.width + x) as usize;
                    for c in 0..3 {
                        m[c] += img.pixels[i][c] as f64;
                        v[c] += var.pixels[i][c] as f64;
                    }
                }
            }
            let n = (bs * bs) as f64;
            out.push(Block {
                mean: m.map(|s| s / n),
                stderr: v.map(|s| s.sqrt() / n),
                samples: (bs * bs) as u64 * film.spp,
            });
        }
    }
    out
}

/// The mean of equal blocks with its standard error.
fn image_mean(blocks: &[Block]) -> Block {
    let k = blocks.len() as f64;
    let mut out = Block {
        mean: [0.0; 3],
        stderr: [0.0; 3],
        samples: blocks.iter().map(|b| b.samples).sum(),
    };
    for c in 0..3 {
        out.mean[c] = blocks.iter().map(|b| b.mean[c]).sum::<f64>() / k;
        out.stderr[c] = blocks
            .iter()
            .map(|b| b.stderr[c].powi(2))
            .sum::<f64>()
            .sqrt()
            / k;
    }
    out
}

fn read_json(name: &str) -> serde_json::Value {
    let path = root().join("golden").join(name);
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn triple(v: &serde_json::Value) -> [f64; 3] {
    let a = v.as_array().expect("an [r, g, b] array");
    [0, 1, 2].map(|c| a[c].as_f64().unwrap())
}

/// The image mean and every block and channel of a fresh fog box agree with the golden's
/// (Welch).
#[test]
fn fog_box_matches_golden() {
    let golden = read_json("fog-box-32-blocks.json");
    assert_eq!(golden["spp"].as_u64(), Some(GOLDEN_SPP as u64));
    assert_eq!(golden["resolution"].as_u64(), Some(RESOLUTION as u64));
    let gold = golden["blocks"].as_array().unwrap();
    let fresh = fog_box_blocks(SPP, 1);
    assert_eq!(gold.len(), fresh.len());
    let mut fam = Family::new("golden: fog_box_matches_golden");
    // the image mean (the blocks' mean: independent blocks, so variances add), four times as
    // sensitive as one block, then every block
    let golden_blocks: Vec<Block> = gold
        .iter()
        .map(|g| Block {
            mean: triple(&g["mean"]),
            stderr: triple(&g["stderr"]),
            samples: g["samples"].as_u64().unwrap(),
        })
        .collect();
    let (fi, gi) = (image_mean(&fresh), image_mean(&golden_blocks));
    for c in 0..3 {
        eprintln!(
            "image mean channel {c}: {:.6} +- {:.1e} vs golden {:.6} +- {:.1e}: {:+.2} se",
            fi.mean[c],
            fi.stderr[c],
            gi.mean[c],
            gi.stderr[c],
            (fi.mean[c] - gi.mean[c]) / fi.stderr[c].hypot(gi.stderr[c])
        );
        fam.means_agree(
            &format!("image mean channel {c}"),
            (fi.mean[c], fi.stderr[c], (fi.samples - 1) as f64),
            (gi.mean[c], gi.stderr[c], (gi.samples - 1) as f64),
        );
    }
    for (i, (g, f)) in golden_blocks.iter().zip(&fresh).enumerate() {
        for c in 0..3 {
            fam.means_agree(
                &format!(
                    "block ({}, {}) channel {c}",
                    i as u32 % BLOCKS,
                    i as u32 / BLOCKS
                ),
                (f.mean[c], f.stderr[c], (f.samples - 1) as f64),
                (g.mean[c], g.stderr[c], (g.samples - 1) as f64),
            );
        }
    }
    fam.finish();
}

/// The slab's meters at 16 spp agree with the 512-spp golden values (Welch).
#[test]
fn slab_meters_match_golden() {
    let source = SceneSource::read(&root().join("scenes/slab.toml")).unwrap();
    let scene = Scene::load(&source).unwrap();
    let golden = read_json("slab-meters.json");
    assert_eq!(golden["integrator"], "path");
    let mut r = Renderer::new(&scene, IntegratorKind::Path, 1, None);
    r.pass(16, &|| {});
    assert_eq!(r.nan_count, 0);
    let mut fam = Family::new("golden: slab_meters_match_golden");
    let estimates = r.meter_estimates();
    assert_eq!(estimates.len(), golden["sensors"].as_array().unwrap().len());
    for m in estimates {
        let g = golden["sensors"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == m.name.as_str())
            .unwrap_or_else(|| panic!("no golden value for meter {}", m.name));
        let (gv, gs) = (triple(&g["value"]), triple(&g["stderr"]));
        let gn = g["samples"].as_u64().unwrap();
        for c in 0..3 {
            fam.means_agree(
                &format!("meter {} channel {c}", m.name),
                (
                    m.value[c] as f64,
                    m.stderr[c] as f64,
                    (m.samples - 1) as f64,
                ),
                (gv[c], gs[c], (gn - 1) as f64),
            );
        }
    }
    fam.finish();
}

/// Writes `golden/fog-box-32-blocks.json` (about a minute): only with
/// `PATHSPACE_WRITE_GOLDEN=1`, so that `--ignored` runs never overwrite a golden by accident.
#[test]
#[ignore = "regenerates golden/fog-box-32-blocks.json (PATHSPACE_WRITE_GOLDEN=1)"]
fn write_fog_box_golden() {
    assert_eq!(
        std::env::var("PATHSPACE_WRITE_GOLDEN").as_deref(),
        Ok("1"),
        "set PATHSPACE_WRITE_GOLDEN=1 to overwrite golden/fog-box-32-blocks.json"
    );
    let blocks = fog_box_blocks(GOLDEN_SPP, GOLDEN_SEED);
    let json = serde_json::json!({
        "command": "PATHSPACE_WRITE_GOLDEN=1 cargo test --release --test oracles -- --ignored golden::write_fog_box_golden",
        "scene": "scenes/fog-box.toml",
        "integrator": "path",
        "resolution": RESOLUTION,
        "spp": GOLDEN_SPP,
        "seed": GOLDEN_SEED,
        "blocks_per_side": BLOCKS,
        "blocks": blocks.iter().enumerate().map(|(i, b)| serde_json::json!({
            "x": i as u32 % BLOCKS,
            "y": i as u32 / BLOCKS,
            "mean": b.mean,
            "stderr": b.stderr,
            "samples": b.samples,
        })).collect::<Vec<_>>(),
    });
    let text = serde_json::to_string_pretty(&json).unwrap() + "\n";
    std::fs::write(root().join("golden/fog-box-32-blocks.json"), text).unwrap();
}
