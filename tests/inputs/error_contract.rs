//! The error contract at its edges: every enumerated value of a scene file and of its
//! `[render]` table is checked at its key (by `info` as well as `render`), fixed-length arrays
//! are read at their exact length, messages escape the control characters they quote, bad
//! UTF-8 is reported with its position, and a scene file's size and its arrays are limited
//! before the parse. Each test checks the exact file, line, key and message.
//! Book: "Scenes and geometry", section "The error contract".

use std::process::Command;

use pathspace::scene::file::{MAX_ARRAY_ELEMENTS, MAX_NESTING, MAX_SCENE_BYTES};
use pathspace::scene::{SceneError, SceneSource};

use crate::common;
use common::scenes::{BASE, BASE_LINES};

fn load(text: &str) -> Result<(), SceneError> {
    let src = SceneSource::embedded("bad.toml", text);
    pathspace::integrator::settings::load(&src).map(|_| ())
}

/// Loads `BASE + extra` and expects exactly `bad.toml:LINE: key `KEY`: MESSAGE` (LINE counted
/// in `extra`, 1-based), as a user reads it.
#[track_caller]
fn expect(extra: &str, line: usize, key: &str, message: &str) {
    let text = format!("{BASE}{extra}");
    let e = load(&text).expect_err(&format!("the scene loaded:\n{text}"));
    let want = format!("bad.toml:{}: key `{key}`: {message}", BASE_LINES + line);
    assert_eq!(e.to_string(), want);
}

/// `pathspace info FILE` on `bytes`: exit code and stderr.
fn info(name: &str, bytes: &[u8]) -> (i32, String) {
    let dir = std::env::temp_dir().join(format!("pathspace-contract-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join(name);
    std::fs::write(&file, bytes).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .arg("info")
        .arg(&file)
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&file);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    // the path as the binary prints it, so the messages read as in the other tests
    let stderr = stderr.replace(&dir.join("").display().to_string(), "");
    (out.status.code().unwrap_or(-1), stderr)
}

// ---- enumerated values, at their key ----

/// The integrators the messages list: the registry's, in its order.
fn integrators() -> String {
    let names: Vec<&str> = pathspace::integrator::IntegratorKind::ALL
        .iter()
        .map(|k| k.name())
        .collect();
    names.join(", ")
}

#[test]
fn integrator_typo_is_reported_at_its_key() {
    expect(
        "\n[render]\nintegrator = \"bpdt\"\n",
        3,
        "render.integrator",
        &format!("unknown integrator `bpdt` (available: {})", integrators()),
    );
}

#[test]
fn info_refuses_an_integrator_typo() {
    let text = format!("{BASE}\n[render]\nspp = 4\nintegrator = \"bpdt\"\n");
    let (code, stderr) = info("typo.toml", text.as_bytes());
    assert_eq!(code, 1, "{stderr}");
    let want = format!(
        "typo.toml:20: key `render.integrator`: unknown integrator `bpdt` (available: {})",
        integrators()
    );
    assert!(stderr.contains(&want), "{stderr}");
}

#[test]
fn every_enumerated_render_value_is_checked_at_its_key() {
    let cases = [
        (
            "\n[render]\ndistance = \"equiangular\"\n",
            3,
            "render.distance",
            "unknown distance sampling `equiangular` (available: free-flight, equiangular-mis)",
        ),
        (
            "\n[render]\nlight_selection = \"uniform\"\n",
            3,
            "render.light_selection",
            "unknown light selection `uniform` (available: power, tree)",
        ),
        (
            "\n[render.smc]\nvariant = \"is2_cv2\"\n",
            3,
            "render.smc.variant",
            "unknown SMC variant `is2_cv2` (available: is0_cv0, is0_cv1, is0_cv2, is1_cv0, is1_cv1, is1_cv2)",
        ),
        (
            "\n[render.smc]\nestimator = \"walk\"\n",
            3,
            "render.smc.estimator",
            "unknown SMC estimator `walk` (available: distance, march)",
        ),
        (
            "\n[render.guide]\nvertices = \"all\"\n",
            3,
            "render.guide.vertices",
            "unknown guide `all` (available: off, surface, volume, both)",
        ),
        (
            "\n[render.guide]\nsampler = \"gibbs\"\n",
            3,
            "render.guide.sampler",
            "unknown particle sampler `gibbs` (available: classical, bidirectional, metropolis)",
        ),
        (
            "\n[render.adjoint]\nestimator = \"path\"\n",
            3,
            "render.adjoint.estimator",
            "unknown adjoint estimator `path` (available: bdpt, metropolis)",
        ),
        (
            "\n[render.mlt]\nmutation_weights = \"lens=1\"\n",
            3,
            "render.mlt.mutation_weights",
            "unknown mutation `lens` (available: bidirectional, sensor, light, propagation, multichain)",
        ),
    ];
    for (extra, line, key, message) in cases {
        expect(extra, line, key, message);
    }
}

/// A procedural medium with one key replaced.
fn procedural(key: &str, value: &str) -> String {
    let mut lines = vec![
        "type = \"procedural\"".to_string(),
        "sigma_a = 0.1".into(),
        "sigma_s = 0.4".into(),
        "density = \"linear\"".into(),
        "axis = \"y\"".into(),
        "from = 0.0".into(),
        "to = 1.0".into(),
        "min = [0, 0, 0]".into(),
        "max = [1, 1, 1]".into(),
        "propagation = \"stratified\"".into(),
    ];
    for l in &mut lines {
        if l.starts_with(&format!("{key} =")) {
            *l = format!("{key} = {value}");
        }
    }
    format!("\n[media.cloud]\n{}\n", lines.join("\n"))
}

#[test]
fn every_enumerated_scene_value_is_checked_at_its_key() {
    let cases = [
        (
            procedural("propagation", "\"ratio-tracking\""),
            12,
            "media.cloud.propagation",
            "unknown variant `ratio-tracking`, expected one of `equidistant`, `stratified`, `random-offset`, `delta-tracking`",
        ),
        (
            procedural("density", "\"smoke\""),
            6,
            "media.cloud.density",
            "unknown variant `smoke`, expected one of `constant`, `linear`, `cloud`, `plume`",
        ),
        (
            procedural("axis", "\"w\""),
            7,
            "media.cloud.axis",
            "unknown variant `w`, expected one of `x`, `y`, `z`",
        ),
        (
            procedural("type", "\"fluid\""),
            3,
            "media.cloud.type",
            "unknown variant `fluid`, expected one of `homogeneous`, `grid`, `vdb`, `procedural`",
        ),
        (
            "\n[materials.shiny]\ntype = \"velvet\"\n".into(),
            3,
            "materials.shiny.type",
            "unknown variant `velvet`, expected one of `lambert`, `mirror`, `dielectric`, `thin_dielectric`, `conductor`, `rough_conductor`, `rough_dielectric`, `rough_plastic`, `plastic`, `null`",
        ),
        (
            "\n[media.haze]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.1\nphase = { type = \"rayleigh\" }\n".into(),
            6,
            "media.haze.phase.type",
            "unknown variant `rayleigh`, expected one of `isotropic`, `hg`, `schlick`, `mix`",
        ),
        (
            "\n[[lights]]\ntype = \"area\"\n".into(),
            3,
            "lights[0].type",
            "unknown variant `area`, expected one of `directional`, `point`, `spot`, `environment`",
        ),
        (
            "\n[[sensors]]\ntype = \"radiance_meter\"\n".into(),
            3,
            "sensors[0].type",
            "unknown variant `radiance_meter`, expected `irradiance_meter`",
        ),
    ];
    for (extra, line, key, message) in cases {
        expect(&extra, line, key, message);
    }
}

#[test]
fn camera_type_is_checked_at_its_key() {
    let text = BASE.replace("type = \"pinhole\"", "type = \"orthographic\"");
    let e = load(&text).unwrap_err();
    assert_eq!(
        e.to_string(),
        "bad.toml:3: key `camera.type`: unknown variant `orthographic`, expected `pinhole`"
    );
}

// ---- fixed-length arrays ----

#[test]
fn render_arrays_of_the_wrong_length_are_refused() {
    let cases = [
        (
            "\n[render.mlt]\nsensor_offset = [0.1, 25.0, 3.0]\n",
            "render.mlt.sensor_offset",
            3,
        ),
        (
            "\n[render.mlt]\nlight_angle = [0.1]\n",
            "render.mlt.light_angle",
            1,
        ),
        (
            "\n[render.mlt]\npropagation_distance = [1e-4, 0.1, 0.5, 0.7]\n",
            "render.mlt.propagation_distance",
            4,
        ),
        (
            "\n[render.adjoint]\nresolution = [64, 64, 1]\n",
            "render.adjoint.resolution",
            3,
        ),
    ];
    for (extra, key, n) in cases {
        let message = format!("invalid length {n}, expected an array of 2 numbers");
        expect(extra, 3, key, &message);
    }
}

#[test]
fn scene_arrays_of_the_wrong_length_are_refused() {
    let sphere = |center: &str| {
        format!("\n[[shapes]]\ntype = \"sphere\"\ncenter = {center}\nradius = 1.0\nmaterial = \"white\"\n")
    };
    let three = "expected an array of 3 numbers";
    expect(
        &sphere("[0, 0, 0, 1]"),
        4,
        "shapes[0].center",
        &format!("invalid length 4, {three}"),
    );
    expect(
        &sphere("[0, 0]"),
        4,
        "shapes[0].center",
        &format!("invalid length 2, {three}"),
    );
    let light = "\n[[lights]]\ntype = \"point\"\nposition = [0, 1, 0, 0]\nintensity = 1.0\n";
    expect(
        light,
        4,
        "lights[0].position",
        &format!("invalid length 4, {three}"),
    );
    let text = BASE.replace("resolution = [8, 8]", "resolution = [8, 8, 3]");
    assert_eq!(
        load(&text).unwrap_err().to_string(),
        "bad.toml:7: key `camera.resolution`: invalid length 3, expected an array of 2 numbers"
    );
    let text = BASE.replace("eye = [0.0, 0.0, 3.0]", "eye = [0.0, 0.0, 3.0, 9.0]");
    assert_eq!(
        load(&text).unwrap_err().to_string(),
        "bad.toml:4: key `camera.eye`: invalid length 4, expected an array of 3 numbers"
    );
}

#[test]
fn arrays_of_the_right_length_still_load() {
    let extra = "\n[render.mlt]\nsensor_offset = [0.1, 25.0]\n\n[render.adjoint]\nresolution = [32, 16]\n\
                 \n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"white\"\n";
    load(&format!("{BASE}{extra}")).unwrap();
}

// ---- control characters ----

#[test]
fn messages_escape_the_control_characters_they_quote() {
    // a quoted key holding ESC, BEL and NUL (TOML escapes), and a value holding ESC and CR
    expect(
        "\n[render]\n\"sp\\u001b[2Jp\\u0007\\u0000\" = 4\n",
        3,
        "render.sp\\u{1b}[2Jp\\u{7}\\u{0}",
        "unknown field `sp\\u{1b}[2Jp\\u{7}\\u{0}`, expected one of `integrator`, `spp`, `seed`, `max_depth`, `meter_samples`, `distance`, `light_selection`, `light_point`, `halo_cone`, `pixel_samples`, `mis_heuristic`, `volume_next_event`, `transmittance`, `adjoint_image`, `mlt`, `pssmlt`, `smc`, `guide`, `adjoint`",
    );
    expect(
        "\n[render]\nintegrator = \"pa\\u001b]0;owned\\u0007th\\r\"\n",
        3,
        "render.integrator",
        &format!(
            "unknown integrator `pa\\u{{1b}}]0;owned\\u{{7}}th\\r` (available: {})",
            integrators()
        ),
    );
}

#[test]
fn binary_prints_no_raw_control_bytes() {
    // raw bytes in the file: a bare key with ESC (a syntax error that quotes the statement),
    // and a value with a bidirectional override
    let cases: [&[u8]; 2] = [
        b"[render]\nsp\x1b[31mp = 4\n",
        "[render]\nintegrator = \"pa\u{202e}th\"\n".as_bytes(),
    ];
    for bytes in cases {
        let mut text = BASE.as_bytes().to_vec();
        text.extend_from_slice(bytes);
        let (code, stderr) = info("ctl.toml", &text);
        assert_eq!(code, 1, "{stderr}");
        assert!(
            stderr.starts_with("error: ctl.toml:18: key `render."),
            "{stderr}"
        );
        assert!(
            !stderr.contains(['\u{1b}', '\u{202e}', '\0', '\r']),
            "raw control bytes in {stderr:?}"
        );
        assert!(
            stderr.contains("\\u{1b}") || stderr.contains("\\u{202e}"),
            "{stderr}"
        );
    }
}

// ---- bad UTF-8 ----

#[test]
fn bad_utf8_is_reported_with_its_position() {
    let mut text = format!("{BASE}\n[render]\nintegrator = \"pé").into_bytes();
    let offset = text.len();
    text.extend_from_slice(b"\xff\xfeth\"\n");
    let (code, stderr) = info("utf8.toml", &text);
    assert_eq!(code, 1, "{stderr}");
    let want = format!(
        "utf8.toml:19: key `render.integrator`: invalid UTF-8 at byte offset {offset} (line 19, column 17): byte 0xff"
    );
    assert!(stderr.contains(&want), "{stderr}");
}

// ---- limits before the parse ----

/// `[render.mlt]` with an array of `n` elements (the value matters not: the scan refuses it
/// before anything is read).
fn long_array(n: usize) -> String {
    let mut s = String::with_capacity(2 * n + 64);
    s.push_str("\n[render.mlt]\nsensor_offset = [");
    for i in 0..n {
        s.push_str(if i == 0 { "0" } else { ",0" });
    }
    s.push_str("]\n");
    s
}

#[test]
fn a_two_million_element_array_is_refused_before_the_parse() {
    let message =
        format!("an array of more than {MAX_ARRAY_ELEMENTS} elements (the limit of a scene file)");
    expect(
        &long_array(2_000_000),
        3,
        "render.mlt.sensor_offset",
        &message,
    );
    // one more element than the limit is refused; the limit itself goes on to the schema
    expect(
        &long_array(MAX_ARRAY_ELEMENTS + 1),
        3,
        "render.mlt.sensor_offset",
        &message,
    );
    expect(
        &long_array(MAX_ARRAY_ELEMENTS),
        3,
        "render.mlt.sensor_offset",
        &format!("invalid length {MAX_ARRAY_ELEMENTS}, expected an array of 2 numbers"),
    );
}

#[test]
fn an_inline_table_with_too_many_entries_is_refused() {
    let entries: Vec<String> = (0..=MAX_ARRAY_ELEMENTS)
        .map(|i| format!("k{i} = 1"))
        .collect();
    let extra = format!("\n[render]\nmlt = {{ {} }}\n", entries.join(", "));
    let message = format!(
        "an inline table of more than {MAX_ARRAY_ELEMENTS} entries (the limit of a scene file)"
    );
    expect(&extra, 3, "render.mlt", &message);
}

#[test]
fn deep_nesting_is_refused_before_the_parse() {
    let depth = 100_000;
    let extra = format!("\nx = {}{}\n", "[".repeat(depth), "]".repeat(depth));
    let message = format!(
        "inline arrays and tables nested more than {MAX_NESTING} deep (the limit of a scene file)"
    );
    expect(&extra, 2, "media.fog.x", &message);
}

#[test]
fn brackets_in_strings_and_comments_are_not_counted() {
    let commas = ",".repeat(2 * MAX_ARRAY_ELEMENTS);
    let brackets = "[".repeat(2 * MAX_NESTING);
    let extra = format!(
        "\n[render] # [{commas} {brackets}\nintegrator = \"path\" # {brackets}\n\
         \n[materials.m]\ntype = \"lambert\" # \"[{commas}\nalbedo = [0.1, 0.2, 0.3]\n\
         \n[[sensors]]\ntype = \"irradiance_meter\"\nname = '''[{commas}{brackets}'''\norigin = [0, 0, 0]\nu = [1, 0, 0]\nv = [0, 1, 0]\n"
    );
    load(&format!("{BASE}{extra}")).unwrap();
}

#[test]
fn a_file_over_the_size_limit_is_refused_unread() {
    let mut text = BASE.as_bytes().to_vec();
    text.resize(MAX_SCENE_BYTES + 1, b'\n');
    let (code, stderr) = info("big.toml", &text);
    assert_eq!(code, 1, "{stderr}");
    let want = format!(
        "big.toml: the scene file has more than {MAX_SCENE_BYTES} bytes (the limit of a scene file)"
    );
    assert!(stderr.contains(&want), "{stderr}");
    // at the limit it is read (and valid: the rest is blank lines)
    text.truncate(MAX_SCENE_BYTES);
    let (code, stderr) = info("limit.toml", &text);
    assert_eq!(code, 0, "{stderr}");
}

#[test]
fn scene_source_read_applies_the_same_checks() {
    let dir = std::env::temp_dir().join(format!("pathspace-contract-read-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.toml");
    std::fs::write(&file, b"[render]\nintegrator = \"\xc3\"\n").unwrap();
    let e = SceneSource::read(&file).unwrap_err();
    let _ = std::fs::remove_file(&file);
    assert_eq!(
        (e.line, e.key.as_str(), e.message.as_str()),
        (
            Some(2),
            "render.integrator",
            "invalid UTF-8 at byte offset 23 (line 2, column 15): byte 0xc3"
        )
    );
}

#[test]
fn locating_an_error_among_many_shapes_costs_log_n_trials() {
    let shape = |radius: &str| {
        format!("\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = {radius}\nmaterial = \"white\"\n")
    };
    let n = 2000;
    let mut extra: String = (1..n).map(|_| shape("0.1")).collect();
    extra.push_str(&shape("\"x\""));
    let before = pathspace::scene::file::narrow_trials();
    expect(
        &extra,
        6 * n - 1,
        &format!("shapes[{}].radius", n - 1),
        "invalid type: string \"x\", expected f32",
    );
    // deleting one shape at a time took n deserializations of the whole file (13 s for 4000
    // shapes); halving takes about log2(n) for the array and a few for the shape's keys
    let trials = pathspace::scene::file::narrow_trials() - before;
    assert!(
        trials <= 40,
        "{trials} deserializations to locate one error among {n} shapes"
    );
}

// ---- other renderers' formats ----

/// A Mitsuba XML or pbrt scene is named for what it is, not parsed as broken TOML (XML is
/// imported from a file named `.xml`); a TOML key that happens to be a pbrt directive's name is
/// still TOML.
#[test]
fn a_mitsuba_or_pbrt_scene_is_named_for_what_it_is() {
    let says = "pathspace reads its own TOML scene files";
    let xml = b"<?xml version=\"1.0\"?>\n<scene version=\"3.0.0\">\n</scene>\n";
    let (code, e) = info("fog.toml", xml);
    assert_eq!(code, 1, "{e}");
    assert!(
        e.starts_with("error: fog.toml: this file is XML (a Mitsuba scene?)")
            && e.contains(says)
            && e.contains("`.xml`"),
        "{e}"
    );
    let (code, e) = info("fog.xml", xml);
    assert_eq!(code, 1, "{e}");
    assert!(
        e.starts_with("error: fog.xml:2: key `<scene>`: the scene has no <sensor>"),
        "{e}"
    );
    let (code, e) = info(
        "fog.pbrt",
        b"# a pbrt scene\nLookAt 0 0 5  0 0 0  0 1 0\nWorldBegin\n",
    );
    assert_eq!(code, 1, "{e}");
    assert!(
        e.starts_with("error: fog.pbrt: this file is a pbrt scene") && e.contains(says),
        "{e}"
    );
    let e = load("Camera = 1\n").unwrap_err().to_string();
    assert!(!e.contains("pbrt"), "{e}");
}
