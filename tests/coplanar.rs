//! Coplanar boundaries: the fog box as shipped has its null medium box exactly in the planes of
//! the walls. It must agree, within error, with a copy whose medium box is grown by 1e-3 behind
//! the walls (so no face is coplanar). Mitsuba 3 loses 28% of the image's energy in exactly the
//! coplanar configuration; pathspace must lose none.

use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

const K_SIGMA: f64 = 4.0;

/// Image mean per channel with its standard error (pixels are independent).
fn render_mean(text: &str, seed: u64) -> ([f64; 3], [f64; 3]) {
    let scene = Scene::load(&SceneSource::embedded("fog-box.toml", text)).unwrap();
    let mut r = Renderer::new(&scene, IntegratorKind::Path, seed, None);
    r.pass(32, &|| {});
    let film = r.film.as_ref().unwrap();
    let (img, var) = (film.image(), film.variance_of_mean());
    let n = img.pixels.len() as f64;
    let mut mean = [0.0; 3];
    let mut se = [0.0; 3];
    for c in 0..3 {
        mean[c] = img.pixels.iter().map(|p| p[c] as f64).sum::<f64>() / n;
        se[c] = var.pixels.iter().map(|v| v[c] as f64).sum::<f64>().sqrt() / n;
    }
    (mean, se)
}

#[test]
fn coplanar_null_boundary_leaks_no_energy() {
    let small = FOG_BOX.replace("resolution = [256, 256]", "resolution = [48, 48]");
    assert_ne!(
        small, FOG_BOX,
        "the fog box's resolution line changed; update this test"
    );
    let grown = small.replace(
        "min = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]",
        "min = [-1.001, -1.001, -1.001]\nmax = [1.001, 1.001, 1.0]",
    );
    assert_ne!(
        grown, small,
        "the fog box's medium box changed; update this test"
    );
    let (a, sa) = render_mean(&small, 1);
    let (b, sb) = render_mean(&grown, 2);
    for c in 0..3 {
        let se = (sa[c] * sa[c] + sb[c] * sb[c]).sqrt();
        assert!(
            (a[c] - b[c]).abs() <= K_SIGMA * se,
            "channel {c}: coplanar {} vs grown {} (+- {se}): the coplanar boundary changes the energy",
            a[c],
            b[c]
        );
    }
}
