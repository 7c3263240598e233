//! Golden images: low-spp renders pinned two ways (never bitwise across platforms):
//! an insta snapshot of a quantized summary (4x4 block means, rounded), which flags any change
//! of behaviour, and a tolerance comparison against a high-spp golden EXR in `golden/`, with the
//! tolerance derived from the render's own standard errors.
//!
//! Regenerate the golden image with
//! `pathspace render scenes/fog-box.toml --resolution 32x32 --spp 16384 --seed 1001 -o golden/fog-box-32.exr --png golden/fog-box-32.png`.

use pathspace::image_io::read_exr;
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

const K_SIGMA: f64 = 4.0;
const BLOCKS: u32 = 4;
/// Samples per pixel of the checked render: enough that the standard error estimated from the
/// samples is itself reliable in the darker corners (at 64 spp it is not).
const SPP: u32 = 256;

#[test]
fn fog_box_matches_golden() {
    let text = FOG_BOX.replace("resolution = [256, 256]", "resolution = [32, 32]");
    let scene = Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap();
    let mut r = Renderer::new(&scene, IntegratorKind::Path, 1, None);
    r.pass(SPP, &|| {});
    let film = r.film.as_ref().unwrap();
    let (img, var) = (film.image(), film.variance_of_mean());
    let golden_path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("golden/fog-box-32.exr");
    let (golden, meta) = read_exr(&golden_path).unwrap();
    assert_eq!(meta.get("spp"), Some("16384"));
    let golden_spp = 16384.0f64;
    let bs = img.width / BLOCKS;
    let mut summary = Vec::new();
    for by in 0..BLOCKS {
        for bx in 0..BLOCKS {
            let mut m = [0.0f64; 3];
            let mut g = [0.0f64; 3];
            let mut v = [0.0f64; 3];
            for y in by * bs..(by + 1) * bs {
                for x in bx * bs..(bx + 1) * bs {
                    let i = (y * img.width + x) as usize;
                    for c in 0..3 {
                        m[c] += img.pixels[i][c] as f64;
                        g[c] += golden.pixels[i][c] as f64;
                        // the golden image has 16384/SPP times less variance: add it scaled
                        v[c] += var.pixels[i][c] as f64 * (1.0 + SPP as f64 / golden_spp);
                    }
                }
            }
            let n = (bs * bs) as f64;
            for c in 0..3 {
                let (mean, gold, se) = (m[c] / n, g[c] / n, v[c].sqrt() / n);
                assert!(
                    (mean - gold).abs() <= K_SIGMA * se,
                    "block ({bx}, {by}) channel {c}: {mean} vs golden {gold} +- {se}"
                );
            }
            summary.push(format!("{:.2} {:.2} {:.2}", m[0] / n, m[1] / n, m[2] / n));
        }
    }
    assert_eq!(r.nan_count, 0);
    insta::with_settings!({snapshot_path => "../golden", prepend_module_to_snapshot => false}, {
        insta::assert_yaml_snapshot!("fog_box_32_blocks", summary);
    });
}

/// The slab's meters at 16 spp against golden values from a 512-spp run
/// (`pathspace render scenes/slab.toml --spp 512 --seed 2024 --json > golden/slab-meters.json`),
/// within 4 standard errors of both; the rounded values are pinned by an insta snapshot.
#[test]
fn slab_meters_match_golden() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let source = SceneSource::read(&root.join("scenes/slab.toml")).unwrap();
    let scene = Scene::load(&source).unwrap();
    let golden: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("golden/slab-meters.json")).unwrap(),
    )
    .unwrap();
    let mut r = Renderer::new(&scene, IntegratorKind::Path, 1, None);
    r.pass(16, &|| {});
    let mut summary = Vec::new();
    for m in r.meter_estimates() {
        let g = golden["sensors"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == m.name.as_str())
            .unwrap();
        let gv = g["value"][0].as_f64().unwrap();
        let gs = g["stderr"][0].as_f64().unwrap();
        let se = ((m.stderr.x as f64).powi(2) + gs * gs).sqrt();
        assert!(
            ((m.value.x as f64) - gv).abs() <= K_SIGMA * se,
            "meter {}: {} vs golden {gv} (+- {se})",
            m.name,
            m.value.x
        );
        summary.push(format!("{} {:.2}", m.name, m.value.x));
    }
    assert_eq!(r.nan_count, 0);
    insta::with_settings!({snapshot_path => "../golden", prepend_module_to_snapshot => false}, {
        insta::assert_yaml_snapshot!("slab_meters", summary);
    });
}
