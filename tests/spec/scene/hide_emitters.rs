//! `hide_emitters` ([`Scene::min_depth`]): every path with no scattering vertex is left out of
//! the measurement, whatever null boundaries and media its one edge crosses (Mitsuba 3.9.1's
//! `volpath` counts only scattering in its depth), and only those: light arriving after a
//! mirror is kept. Emitter shapes are transparent to the camera's rays until they first
//! scatter (Mitsuba's `skip_area_emitters`): a hidden panel shows what is behind it, never its
//! own face, and lights the scene as before.

use pathspace::integrator::IntegratorKind;
use pathspace::scene::{Scene, SceneSource};

const CAMERA: &str = r#"[render]
spp = 4
[camera]
type = "pinhole"
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [4, 4]
[[lights]]
type = "environment"
radiance = 1.0
"#;

/// A sky seen through a purely absorbing haze behind a null boundary, filling the view: no
/// path of the image has a scattering vertex.
const HAZE: &str = r#"[media.ink]
type = "homogeneous"
sigma_a = 0.4
sigma_s = 0.0
[[shapes]]
type = "box"
min = [-3.0, -3.0, -1.0]
max = [3.0, 3.0, 1.0]
material = "null"
interior = "ink"
"#;

/// A mirror filling the view, the sky behind the camera: every path scatters there once.
const MIRROR: &str = r#"[materials.mirror]
type = "mirror"
[[shapes]]
type = "quad"
origin = [-5.0, -5.0, 0.0]
u = [10.0, 0.0, 0.0]
v = [0.0, 10.0, 0.0]
material = "mirror"
"#;

/// A wall filling the view behind a panel that fills it too and lights the wall: the camera
/// sees only the panel's back, which neither emits nor reflects (no material).
const PANEL_BEFORE_WALL: &str = r#"[materials.white]
type = "lambert"
albedo = 0.8
[[shapes]]
type = "quad"
origin = [-5.0, -5.0, -1.0]
u = [10.0, 0.0, 0.0]
v = [0.0, 10.0, 0.0]
material = "white"
[[shapes]]
type = "quad"
origin = [-4.0, -4.0, 0.5]
u = [0.0, 8.0, 0.0]
v = [8.0, 0.0, 0.0]
emission = 2.0
"#;

/// A white panel filling the view and facing the camera, lit by its own emission's camera
/// side and by a point light beside the camera; nothing behind it.
const WHITE_PANEL: &str = r#"[materials.white]
type = "lambert"
albedo = 0.8
[[shapes]]
type = "quad"
origin = [-4.0, -4.0, 0.0]
u = [8.0, 0.0, 0.0]
v = [0.0, 8.0, 0.0]
material = "white"
emission = 2.0
[[lights]]
type = "point"
position = [1.0, 1.0, 3.0]
intensity = 5.0
"#;

/// A wall in view lit by a panel behind the camera, which no camera ray meets.
const PANEL_BEHIND_CAMERA: &str = r#"[materials.white]
type = "lambert"
albedo = 0.8
[[shapes]]
type = "quad"
origin = [-5.0, -5.0, 0.0]
u = [10.0, 0.0, 0.0]
v = [0.0, 10.0, 0.0]
material = "white"
[[shapes]]
type = "quad"
origin = [-2.0, -2.0, 5.0]
u = [0.0, 4.0, 0.0]
v = [4.0, 0.0, 0.0]
emission = 3.0
"#;

/// The scene without the sky of `CAMERA`.
fn load_dark(hide: bool, body: &str) -> Scene {
    let camera = CAMERA.split("[[lights]]").next().unwrap();
    let text = format!("hide_emitters = {hide}\n{camera}{body}");
    Scene::load(&SceneSource::embedded("hide.toml", &text)).unwrap_or_else(|e| panic!("{e}"))
}

fn lit(bits: &[u64]) -> bool {
    bits.iter().all(|&x| f64::from_bits(x) >= 0.0) && bits.iter().any(|&x| f64::from_bits(x) > 0.0)
}

fn dark(bits: &[u64]) -> bool {
    bits.iter().all(|&x| f64::from_bits(x) == 0.0)
}

/// Shown, the panel's dark back is all the camera sees; hidden, every integrator sees the wall
/// it lights through it (the camera's rays and light tracing's connections pass it).
#[test]
fn a_hidden_panel_shows_the_wall_behind_it_in_every_integrator() {
    let (shown, hidden) = (
        load_dark(false, PANEL_BEFORE_WALL),
        load_dark(true, PANEL_BEFORE_WALL),
    );
    for &kind in IntegratorKind::ALL {
        assert!(
            dark(&render_bits(&shown, kind)),
            "{kind:?}: the panel's back is seen lit"
        );
        assert!(
            lit(&render_bits(&hidden, kind)),
            "{kind:?}: the wall behind a hidden panel is dark"
        );
    }
}

/// Hidden, a panel facing the camera shows neither its emission nor the light it reflects:
/// the camera sees through it into the dark, in every integrator (a light subpath that
/// reaches the panel does not connect to the camera from it).
#[test]
fn a_hidden_panel_shows_neither_its_emission_nor_its_reflection() {
    let (shown, hidden) = (load_dark(false, WHITE_PANEL), load_dark(true, WHITE_PANEL));
    for &kind in IntegratorKind::ALL {
        assert!(
            lit(&render_bits(&shown, kind)),
            "{kind:?}: the shown panel is dark"
        );
        assert!(
            dark(&render_bits(&hidden, kind)),
            "{kind:?}: a hidden panel is seen"
        );
    }
}

/// The transparency ends at the first scattering vertex: a panel no camera ray meets lights
/// the wall the same, bit for bit, hidden or not, in the integrators whose samples are walks
/// from the camera (the bidirectional ones skip the numbers of strategies left unmeasured, so
/// their images differ by noise: the agreement matrix compares them).
#[test]
fn a_hidden_panel_lights_the_scene_as_a_shown_one() {
    let (shown, hidden) = (
        load_dark(false, PANEL_BEHIND_CAMERA),
        load_dark(true, PANEL_BEHIND_CAMERA),
    );
    for kind in [IntegratorKind::Path, IntegratorKind::Smc] {
        let a = render_bits(&shown, kind);
        assert!(lit(&a), "{kind:?}: the wall is dark");
        assert_eq!(a, render_bits(&hidden, kind), "{kind:?}");
    }
}

fn load(hide: bool, body: &str) -> Scene {
    let text = format!("hide_emitters = {hide}\n{CAMERA}{body}");
    Scene::load(&SceneSource::embedded("hide.toml", &text)).unwrap_or_else(|e| panic!("{e}"))
}

fn render_bits(scene: &Scene, kind: IntegratorKind) -> Vec<u64> {
    crate::common::film_bits(scene, kind, 3)
}

#[test]
fn the_sky_seen_through_a_null_boundary_and_a_medium_is_hidden_in_every_integrator() {
    let (shown, hidden) = (load(false, HAZE), load(true, HAZE));
    assert_eq!((shown.min_depth(), hidden.min_depth()), (0, 1));
    for &kind in IntegratorKind::ALL {
        let lit = render_bits(&shown, kind);
        assert!(
            lit.iter().any(|&x| f64::from_bits(x) > 0.0),
            "{kind:?}: the shown sky is black"
        );
        let dark = render_bits(&hidden, kind);
        assert!(
            dark.iter().all(|&x| f64::from_bits(x) == 0.0),
            "{kind:?}: a hidden sky is seen"
        );
    }
}

#[test]
fn the_sky_seen_in_a_mirror_is_kept() {
    let (shown, hidden) = (load(false, MIRROR), load(true, MIRROR));
    let a = render_bits(&shown, IntegratorKind::Path);
    assert!(a.iter().any(|&x| f64::from_bits(x) > 0.0));
    assert_eq!(a, render_bits(&hidden, IntegratorKind::Path));
}

#[test]
fn hide_emitters_is_refused_with_meters_and_emitting_media() {
    let meter = r#"[[sensors]]
type = "irradiance_meter"
name = "T"
origin = [-0.5, -0.5, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
"#;
    let text = format!("hide_emitters = true\n{CAMERA}{meter}");
    let e = Scene::load(&SceneSource::embedded("m.toml", &text))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("hide_emitters") && e.contains("[[sensors]]") && e.contains("m.toml"),
        "{e}"
    );
}

/// A hidden emitter the camera sees through cannot bound a medium: the camera's medium
/// behind it would be unknown.
#[test]
fn hide_emitters_is_refused_with_an_area_light_on_a_medium_boundary() {
    let body = r#"[media.fog]
type = "homogeneous"
sigma_a = 0.1
sigma_s = 0.1
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
emission = 1.0
interior = "fog"
"#;
    let text = format!("hide_emitters = true\n{CAMERA}{body}");
    let e = Scene::load(&SceneSource::embedded("b.toml", &text))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("hide_emitters") && e.contains("medium boundary") && e.contains("b.toml"),
        "{e}"
    );
    let shown = text.replace("hide_emitters = true", "hide_emitters = false");
    Scene::load(&SceneSource::embedded("b.toml", &shown)).unwrap_or_else(|e| panic!("{e}"));
}

/// `info` says that a scene hides its emitters, and says nothing of it otherwise.
#[test]
fn info_states_hide_emitters() {
    let dir = crate::common::cli::scratch("hide-emitters", "info");
    for hide in [false, true] {
        let path = dir.join(format!("hide-{hide}.toml"));
        std::fs::write(&path, format!("hide_emitters = {hide}\n{CAMERA}{MIRROR}")).unwrap();
        let out = crate::common::cli::pathspace(&["info", path.to_str().unwrap()]);
        assert!(out.status.success(), "{}", crate::common::cli::stderr(&out));
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert_eq!(text.contains("hide_emitters:"), hide, "{text}");
    }
}
