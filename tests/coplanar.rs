//! Coplanar boundaries: the fog box as shipped has its null medium box exactly in the planes of
//! the walls. It must agree, within error, with a copy whose medium box is grown by 1e-3 behind
//! the walls (so no face is coplanar). Mitsuba 3 loses 28% of the image's energy in exactly the
//! coplanar configuration; pathspace must lose none.

mod common;

use common::stats::Family;
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

/// Image mean per channel with its standard error and degrees of freedom (pixels are
/// independent).
fn render_mean(text: &str, seed: u64) -> [(f64, f64, f64); 3] {
    let scene = Scene::load(&SceneSource::embedded("fog-box.toml", text)).unwrap();
    let mut r = Renderer::new(&scene, IntegratorKind::Path, seed, None);
    r.pass(32, &|| {});
    let film = r.film.as_ref().unwrap();
    std::array::from_fn(|c| common::film_mean(film, c))
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
    let a = render_mean(&small, 1);
    let b = render_mean(&grown, 2);
    let mut fam = Family::new("coplanar: null boundary in the walls' planes");
    for c in 0..3 {
        fam.means_agree(&format!("channel {c}: coplanar vs grown"), a[c], b[c]);
    }
    fam.finish();
}
