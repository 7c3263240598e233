//! `hide_emitters` ([`Scene::min_depth`]): every path with no scattering vertex is left out of
//! the measurement, whatever null boundaries and media its one edge crosses (Mitsuba 3.9.1's
//! `volpath` counts only scattering in its depth), and only those: light arriving after a
//! mirror is kept.

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
