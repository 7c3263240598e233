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
