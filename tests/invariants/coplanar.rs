//! Coplanar boundaries: the fog box as shipped has its null medium box exactly in the planes of
//! the walls. It must agree, within error, with a copy whose medium box is grown by 1e-3 behind
//! the walls (so no face is coplanar). Mitsuba 3 loses 28% of the image's energy in exactly the
//! coplanar configuration; pathspace must lose none.
//!
//! Scene build leaves a null face out of the BVH when one coplanar wall that transmits nothing
//! covers it (`scene::build::hidden`), which is the shipped fog box's case; the copy with the red
//! wall cut in two halves keeps that face, so the BVH's coplanar tie-break is what stops its rays.

use crate::common;

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
    let halves = split_red_wall(&small);
    assert_eq!(
        hidden_faces(&small),
        5,
        "the five walls hide their null faces"
    );
    assert_eq!(
        hidden_faces(&halves),
        4,
        "no half of the red wall covers its face"
    );
    assert_eq!(hidden_faces(&grown), 0);
    let a = render_mean(&small, 1);
    let b = render_mean(&grown, 2);
    let h = render_mean(&halves, 3);
    let mut fam = Family::new("coplanar: null boundary in the walls' planes");
    for c in 0..3 {
        fam.means_agree(&format!("channel {c}: coplanar vs grown"), a[c], b[c]);
        fam.means_agree(&format!("channel {c}: halved wall vs grown"), h[c], b[c]);
    }
    fam.finish();
}

/// The fog box with its red wall (x = -1) written as two quads, each covering half its face.
fn split_red_wall(text: &str) -> String {
    let wall =
        "origin = [-1.0, -1.0, -1.0]\nu = [0.0, 2.0, 0.0]\nv = [0.0, 0.0, 2.0]\nmaterial = \"red\"";
    let halves = "origin = [-1.0, -1.0, -1.0]\nu = [0.0, 1.0, 0.0]\nv = [0.0, 0.0, 2.0]\nmaterial = \"red\"\n\n\
                  [[shapes]]\ntype = \"quad\"\norigin = [-1.0, 0.0, -1.0]\nu = [0.0, 1.0, 0.0]\nv = [0.0, 0.0, 2.0]\nmaterial = \"red\"";
    let out = text.replace(wall, halves);
    assert_ne!(
        out, text,
        "the fog box's red wall changed; update this test"
    );
    out
}

fn hidden_faces(text: &str) -> usize {
    Scene::load(&SceneSource::embedded("fog-box.toml", text))
        .unwrap()
        .hidden_faces
}

#[test]
fn only_walls_that_transmit_nothing_hide_a_null_face() {
    let glass = FOG_BOX.replace(
        "[materials.red]\ntype = \"lambert\"\nalbedo = [0.63, 0.065, 0.05]",
        "[materials.red]\ntype = \"dielectric\"\nior = 1.5",
    );
    assert_ne!(
        glass, FOG_BOX,
        "the fog box's red material changed; update this test"
    );
    // light crosses the glass wall, and with it the boundary: the face must stay
    assert_eq!(hidden_faces(&glass), 4);
    // a wall off the face's plane by 1e-3 hides nothing
    let off = FOG_BOX.replace(
        "origin = [-1.0, -1.0, -1.0]\nu = [0.0, 2.0, 0.0]",
        "origin = [-1.001, -1.0, -1.0]\nu = [0.0, 2.0, 0.0]",
    );
    assert_ne!(off, FOG_BOX);
    assert_eq!(hidden_faces(&off), 4);
}
