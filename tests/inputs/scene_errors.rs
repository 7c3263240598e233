//! The scene-file error contract, executable: every error names the file, the line and the key
//! and says what is wrong, and no input makes `Scene::load` panic.
//!
//! Each test writes a small bad scene as a string and checks the exact line, the key path and
//! the gist of the message. Book: "Scenes and geometry", section "The error contract".

use std::path::PathBuf;
use std::process::Command;

use pathspace::scene::{Scene, SceneError, SceneSource, FOG_BOX};

use crate::common;
use common::scenes::{BASE, BASE_LINES};

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn load(name: &str, text: &str) -> Result<Scene, SceneError> {
    let mut src = SceneSource::embedded(name, text);
    src.base_dir = fixtures();
    // the scene and its `[render]` settings, each checked
    pathspace::integrator::settings::load(&src).map(|(scene, _)| scene)
}

/// Loads `BASE + extra`, expects an error at line `BASE_LINES + line` (of `extra`, 1-based)
/// on `key` whose message contains every one of `words`.
#[track_caller]
fn expect_error(extra: &str, line: usize, key: &str, words: &[&str]) -> SceneError {
    let text = format!("{BASE}{extra}");
    let e = match load("bad.toml", &text) {
        Ok(_) => panic!("the scene loaded, but it should not have:\n{text}"),
        Err(e) => e,
    };
    assert_eq!(e.file, "bad.toml");
    assert_eq!(
        (e.line, e.key.as_str()),
        (Some(BASE_LINES + line), key),
        "{e}"
    );
    for w in words {
        assert!(e.message.contains(w), "message of `{e}` lacks `{w}`");
    }
    // the display form a user sees: file:line: key `k`: message
    assert!(
        e.to_string()
            .starts_with(&format!("bad.toml:{}: key `{key}`: ", BASE_LINES + line)),
        "{e}"
    );
    e
}

#[test]
fn base_scene_is_valid() {
    assert_eq!(BASE.lines().count(), BASE_LINES);
    load("base.toml", BASE).unwrap();
}

// ---- unknown keys ----

#[test]
fn unknown_key_in_a_medium() {
    let e = expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.1\nsigma_x = 3.0\n",
        6,
        "media.smoke.sigma_x",
        &["unknown field `sigma_x`", "sigma_a"],
    );
    assert!(e.message.contains("expected one of"), "{e}");
}

#[test]
fn typo_in_render() {
    expect_error(
        "\n[render]\nspp = 4\nsed = 3\n",
        4,
        "render.sed",
        &["unknown field `sed`", "seed"],
    );
}

#[test]
fn unknown_key_in_the_second_shape() {
    // the tagged enums only give serde the span of the whole array of tables: the error must
    // still name the right element and line
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"white\"\n\
         \n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\nmaterail = \"white\"\n",
        12,
        "shapes[1].materail",
        &["unknown field `materail`", "material"],
    );
}

#[test]
fn unknown_key_in_an_inline_phase_table() {
    expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.1\nphase = { type = \"hg\", g = 0.5, k = 0.1 }\n",
        6,
        "media.smoke.phase.k",
        &["unknown field `k`"],
    );
}

#[test]
fn unknown_top_level_table() {
    expect_error(
        "\n[rendr]\nspp = 4\n",
        2,
        "rendr",
        &["unknown field `rendr`", "render"],
    );
}

// ---- references ----

#[test]
fn unknown_material_on_a_shape() {
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"whte\"\n",
        6,
        "shapes[0].material",
        &["unknown material `whte`", "white"],
    );
}

#[test]
fn unknown_medium_on_a_shape() {
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1.0\nmaterial = \"null\"\ninterior = \"fgo\"\n",
        7,
        "shapes[0].interior",
        &["unknown medium `fgo`", "fog"],
    );
}

// ---- physics ----

#[test]
fn negative_sigma_a_scalar() {
    expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = -0.1\nsigma_s = 0.1\n",
        4,
        "media.smoke.sigma_a",
        &["sigma_a", ">= 0", "-0.1"],
    );
}

#[test]
fn negative_sigma_s_rgb() {
    expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = [0.5, -0.2, 0.5]\n",
        5,
        "media.smoke.sigma_s",
        &["sigma_s", ">= 0", "[0.5, -0.2, 0.5]"],
    );
}

#[test]
fn nan_coefficient() {
    expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = nan\nsigma_s = 0.1\n",
        4,
        "media.smoke.sigma_a",
        &["finite", "NaN"],
    );
}

#[test]
fn negative_emission() {
    expect_error(
        "\n[media.glow]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.1\nemission = [1.0, -0.5, 1.0]\n",
        6,
        "media.glow.emission",
        &["emission", ">= 0", "[1, -0.5, 1]"],
    );
}

#[test]
fn infinite_emission_on_a_procedural_medium() {
    expect_error(
        "\n[media.glow]\ntype = \"procedural\"\ndensity = \"constant\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nsigma_a = 0.1\nsigma_s = 0.1\nemission = inf\n",
        9,
        "media.glow.emission",
        &["emission", "finite"],
    );
}

#[test]
fn emission_without_extinction() {
    expect_error(
        "\n[media.glow]\ntype = \"homogeneous\"\nsigma_a = 0.0\nsigma_s = 0.0\nemission = 1.0\n",
        6,
        "media.glow.emission",
        &["emission", "sigma_a + sigma_s = 0"],
    );
}

#[test]
fn hg_with_g_of_one() {
    for g in ["1.0", "-1.0", "1.5"] {
        expect_error(
            &format!("\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.1\n\n[media.smoke.phase]\ntype = \"hg\"\ng = {g}\n"),
            9,
            "media.smoke.phase.g",
            &["|g| >= 1"],
        );
    }
}

#[test]
fn albedo_above_one() {
    expect_error(
        "\n[materials.hot]\ntype = \"lambert\"\nalbedo = [0.5, 1.2, 0.5]\n",
        4,
        "materials.hot.albedo",
        &["above 1"],
    );
}

#[test]
fn glossy_roughness_outside_its_range() {
    // below the floor the smooth material is the model to use, and the message says which
    expect_error(
        "\n[materials.steel]\ntype = \"rough_conductor\"\nalpha = 0.0001\n",
        4,
        "materials.steel.alpha",
        &["below 0.001", "type = \"conductor\""],
    );
    expect_error(
        "\n[materials.frost]\ntype = \"rough_dielectric\"\nior = 1.5\nalpha = 0\n",
        5,
        "materials.frost.alpha",
        &["below 0.001", "type = \"dielectric\""],
    );
    expect_error(
        "\n[materials.frost]\ntype = \"rough_dielectric\"\nior = 1.5\nalpha = 1.5\n",
        5,
        "materials.frost.alpha",
        &["above 1", "energy"],
    );
}

#[test]
fn glossy_fresnel_and_index_contradictions() {
    expect_error(
        "\n[materials.steel]\ntype = \"rough_conductor\"\nalpha = 0.2\nreflectance = 0.9\neta = 1.5\nk = 3.0\n",
        6,
        "materials.steel.eta",
        &["either `reflectance`", "not both"],
    );
    expect_error(
        "\n[materials.steel]\ntype = \"rough_conductor\"\nalpha = 0.2\neta = [0.2, 0.9, 1.1]\n",
        5,
        "materials.steel.eta",
        &["both `eta` and `k`"],
    );
    expect_error(
        "\n[materials.steel]\ntype = \"rough_conductor\"\nalpha = 0.2\nreflectance = 1.2\n",
        5,
        "materials.steel.reflectance",
        &["above 1"],
    );
    expect_error(
        "\n[materials.frost]\ntype = \"rough_dielectric\"\nior = 1.001\nalpha = 0.2\n",
        4,
        "materials.frost.ior",
        &["within 1% of 1", "null"],
    );
}

// ---- the axes a shape's (u, v) are measured in ----

#[test]
fn sphere_axes_that_are_not_perpendicular() {
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nx_axis = [1, 0, 0.1]\nmaterial = \"white\"\n",
        6,
        "shapes[0].x_axis",
        &["perpendicular to z_axis"],
    );
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nz_axis = [0, 0, 0]\nmaterial = \"white\"\n",
        6,
        "shapes[0].z_axis",
        &["z_axis must be a direction"],
    );
}

#[test]
fn cylinder_x_axis_along_its_axis() {
    expect_error(
        "\n[[shapes]]\ntype = \"cylinder\"\np0 = [0, 0, 0]\np1 = [0, 1, 0]\nradius = 1\nx_axis = [0.1, 1, 0]\nmaterial = \"white\"\n",
        7,
        "shapes[0].x_axis",
        &["perpendicular to p1 - p0"],
    );
}

// ---- media need closed shapes ----

#[test]
fn quad_carrying_a_medium() {
    expect_error(
        "\n[[shapes]]\ntype = \"quad\"\norigin = [0, 0, 0]\nu = [1, 0, 0]\nv = [0, 1, 0]\nmaterial = \"null\"\ninterior = \"fog\"\n",
        8,
        "shapes[0].interior",
        &["quad is not a closed shape"],
    );
}

/// A light half inside a fog would start the light paths of its other half in the fog too
/// (light tracing and BDPT would differ from path tracing), so it is refused at its shape.
#[test]
fn area_light_across_a_medium_boundary() {
    let fog_box = "\n[[shapes]]\ntype = \"box\"\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\nmaterial = \"null\"\ninterior = \"fog\"\n";
    let lamp = |x: f32| {
        format!("\n[[shapes]]\ntype = \"quad\"\norigin = [{x}, 0.9, -0.2]\nu = [0, 0, 0.4]\nv = [0.4, 0, 0]\nmaterial = \"white\"\nemission = 5.0\n")
    };
    let e = expect_error(
        &format!("{fog_box}{}", lamp(0.8)),
        9,
        "shapes[1]",
        &[
            "more than one medium",
            "medium `fog`",
            "no medium",
            "split the shape",
        ],
    );
    assert!(e.message.contains("area light"), "{e}");
    // wholly inside or wholly outside, the lamp loads
    for x in [0.2, 1.5] {
        load("ok.toml", &format!("{BASE}{fog_box}{}", lamp(x))).unwrap();
    }
}

#[test]
fn open_mesh_carrying_a_medium() {
    expect_error(
        "\n[[shapes]]\ntype = \"mesh\"\nobj = \"open-cube.obj\"\nmaterial = \"null\"\ninterior = \"fog\"\n",
        6,
        "shapes[0].interior",
        &["the mesh `open-cube.obj` is not a closed shape"],
    );
}

#[test]
fn inside_out_mesh_carrying_a_medium() {
    expect_error(
        "\n[[shapes]]\ntype = \"mesh\"\nobj = \"inside-out-cube.obj\"\nmaterial = \"null\"\ninterior = \"fog\"\n",
        4,
        "shapes[0].obj",
        &["inside out"],
    );
}

/// A closed mesh wound outwards turned inwards by `flip_normals` holds its medium outside:
/// refused, naming the flip (the same cube wound inside out and flipped holds it).
#[test]
fn flipped_mesh_carrying_a_medium_outside() {
    expect_error(
        "\n[[shapes]]\ntype = \"mesh\"\nobj = \"cube.obj\"\nflip_normals = true\nmaterial = \"null\"\ninterior = \"fog\"\n",
        4,
        "shapes[0].obj",
        &["inside out", "flip_normals"],
    );
}

// ---- syntax and types ----

#[test]
fn toml_syntax_error() {
    // an unclosed array: the parser stops on the next line, and says where the value began
    let e = expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0,\nradius = 1.0\n",
        5,
        "shapes[0].center",
        &["which begins on line 20"],
    );
    assert_eq!(BASE_LINES + 4, 20, "{e}");
}

#[test]
fn unclosed_string() {
    expect_error(
        "\n[render]\nintegrator = \"path\nspp = 4\n",
        3,
        "render.integrator",
        &["string"],
    );
}

#[test]
fn string_for_a_number() {
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = \"big\"\nmaterial = \"white\"\n",
        5,
        "shapes[0].radius",
        &["invalid type: string \"big\"", "f32"],
    );
}

#[test]
fn string_for_a_colour() {
    expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = \"lots\"\nsigma_s = 0.1\n",
        4,
        "media.smoke.sigma_a",
        &["a number or an array of three numbers", "\"lots\""],
    );
}

#[test]
fn string_for_spp() {
    expect_error(
        "\n[render]\nspp = \"many\"\n",
        3,
        "render.spp",
        &["invalid type", "u32"],
    );
}

#[test]
fn missing_required_key() {
    // a missing key points at the table that lacks it
    expect_error(
        "\n[[shapes]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nmaterial = \"white\"\n",
        2,
        "shapes[0].radius",
        &["missing field `radius`"],
    );
}

#[test]
fn missing_key_in_a_nested_table() {
    expect_error(
        "\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.1\nphase = { type = \"hg\" }\n",
        6,
        "media.smoke.phase.g",
        &["missing field `g`"],
    );
}

#[test]
fn unknown_shape_type() {
    expect_error(
        "\n[[shapes]]\ntype = \"cone\"\nmaterial = \"white\"\n",
        3,
        "shapes[0].type",
        &["unknown variant `cone`", "sphere"],
    );
}

// ---- geometry ----

#[test]
fn zero_area_quad() {
    expect_error(
        "\n[[shapes]]\ntype = \"quad\"\norigin = [0, 0, 0]\nu = [1, 0, 0]\nv = [2, 0, 0]\nmaterial = \"white\"\n",
        5,
        "shapes[0].u",
        &["parallel", "no area"],
    );
}

#[test]
fn box_with_max_not_above_min() {
    expect_error(
        "\n[[shapes]]\ntype = \"box\"\nmin = [0, 0, 0]\nmax = [1, 0, 1]\nmaterial = \"white\"\n",
        5,
        "shapes[0].max",
        &["must exceed min"],
    );
}

#[test]
fn camera_with_zero_fov() {
    let text = BASE.replace("fov_deg = 40.0", "fov_deg = 0.0");
    let e = load("cam.toml", &text).err().unwrap();
    assert_eq!((e.line, e.key.as_str()), (Some(6), "camera.fov_deg"), "{e}");
    assert!(e.message.contains("(0, 180)"), "{e}");
}

#[test]
fn camera_looking_at_its_eye() {
    let text = BASE.replace("look_at = [0.0, 0.0, 0.0]", "look_at = [0.0, 0.0, 3.0]");
    let e = load("cam.toml", &text).err().unwrap();
    assert_eq!((e.line, e.key.as_str()), (Some(5), "camera.look_at"), "{e}");
    assert!(e.message.contains("look_at equals eye"), "{e}");
}

#[test]
fn camera_up_along_the_view() {
    let text = BASE.replace(
        "look_at = [0.0, 0.0, 0.0]",
        "look_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, 1.0]",
    );
    let e = load("cam.toml", &text).err().unwrap();
    assert_eq!((e.line, e.key.as_str()), (Some(6), "camera.up"), "{e}");
}

// ---- meshes ----

#[test]
fn missing_obj_file() {
    expect_error(
        "\n[[shapes]]\ntype = \"mesh\"\nobj = \"no-such-file.obj\"\nmaterial = \"white\"\n",
        4,
        "shapes[0].obj",
        &["cannot read", "no-such-file.obj"],
    );
}

#[test]
fn obj_face_index_out_of_range() {
    expect_error(
        "\n[[shapes]]\ntype = \"mesh\"\nobj = \"bad-index.obj\"\nmaterial = \"white\"\n",
        4,
        "shapes[0].obj",
        &["bad-index.obj", "line 6", "face index 9 is out of range"],
    );
}

#[test]
fn closed_mesh_loads_and_carries_a_medium() {
    let text = format!(
        "{BASE}\n[[shapes]]\ntype = \"mesh\"\nobj = \"cube.obj\"\nmaterial = \"null\"\ninterior = \"fog\"\n"
    );
    let scene = load("cube.toml", &text).unwrap();
    assert_eq!(scene.prims.len(), 12, "six quads, two triangles each");
    assert_eq!(scene.shapes[0].interior, Some(0));
    // the medium is found inside the cube and not outside it
    assert_eq!(scene.medium_at(glam::Vec3::new(0.1, 0.2, 0.3)), Some(0));
    assert_eq!(scene.medium_at(glam::Vec3::new(0.1, 0.2, 1.5)), None);
}

#[test]
fn open_mesh_loads_without_a_medium() {
    let text = format!(
        "{BASE}\n[[shapes]]\ntype = \"mesh\"\nobj = \"open-cube.obj\"\nmaterial = \"white\"\n"
    );
    assert_eq!(load("open.toml", &text).unwrap().prims.len(), 10);
}

// ---- sensors and rendering ----

#[test]
fn duplicate_sensor_names() {
    let meter = |z: f32| {
        format!("\n[[sensors]]\ntype = \"irradiance_meter\"\nname = \"T\"\norigin = [0, 0, {z}]\nu = [1, 0, 0]\nv = [0, 1, 0]\n")
    };
    expect_error(
        &format!("{}{}", meter(0.0), meter(1.0)),
        11,
        "sensors[1].name",
        &["two sensors are called `T`"],
    );
}

#[test]
fn neither_camera_nor_sensor() {
    let text = "[materials.white]\ntype = \"lambert\"\nalbedo = 0.5\n";
    let e = load("empty.toml", text).err().unwrap();
    assert_eq!(e.key, "camera");
    assert!(e.message.contains("neither a camera nor a sensor"), "{e}");
    // no `[camera]` to point at: the error still gives a line, the top of the file
    assert_eq!(e.line, Some(1), "{e}");
}

#[test]
fn zero_spp() {
    expect_error("\n[render]\nspp = 0\n", 3, "render.spp", &["at least 1"]);
}

#[test]
fn negative_spp() {
    expect_error("\n[render]\nspp = -4\n", 3, "render.spp", &["u32"]);
}

// ---- through the binary ----

fn info(name: &str, text: &str) -> (i32, String, String) {
    let dir = std::env::temp_dir().join(format!("pathspace-scene-errors-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .arg("info")
        .arg(&file)
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&file);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn binary_reports_a_semantic_error() {
    let (code, _, stderr) = info(
        "neg.toml",
        &format!("{BASE}\n[media.smoke]\ntype = \"homogeneous\"\nsigma_a = -1\nsigma_s = 0\n"),
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("neg.toml:20: key `media.smoke.sigma_a`:"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn binary_reports_a_syntax_error() {
    let (code, _, stderr) = info("syntax.toml", &format!("{BASE}\n[render\nspp = 4\n"));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("syntax.toml:18: key `render`:"), "{stderr}");
}

#[test]
fn binary_accepts_every_shipped_scene() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut n = 0;
    let entries = std::fs::read_dir(&dir)
        .unwrap()
        .chain(std::fs::read_dir(dir.join("xml")).unwrap());
    for entry in entries {
        let p = entry.unwrap().path();
        // TOML scenes, and the Mitsuba 3 XML test scenes through the importer
        if p.extension().is_some_and(|e| e == "toml" || e == "xml") {
            let out = Command::new(env!("CARGO_BIN_EXE_pathspace"))
                .arg("info")
                .arg(&p)
                .output()
                .unwrap();
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success(),
                "{}: {}",
                p.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(stdout.contains(": valid (hash"), "{stdout}");
            n += 1;
        }
    }
    assert!(n >= 4, "{n} scenes");
}

// ---- no input panics ----

/// xorshift64*: a tiny fixed-seed generator, so the fuzz cases are the same on every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

const NONSENSE: &[&str] = &[
    "-1",
    "0",
    "0.0",
    "-0.0",
    "1e39",
    "-1e39",
    "nan",
    "inf",
    "-inf",
    "1e-45",
    "3e38",
    "99999999999",
    "\"x\"",
    "[]",
    "[1, 2]",
    "[nan, 0, 0]",
    "{}",
    "true",
    "1979-05-27",
    "[[1]]",
];

fn mutate(rng: &mut Rng, text: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for _ in 0..1 + rng.below(3) {
        if lines.is_empty() {
            break;
        }
        let i = rng.below(lines.len());
        match rng.below(6) {
            0 => {
                lines.remove(i);
            }
            1 => {
                let l = lines[i].clone();
                lines.insert(i, l);
            }
            2 | 3 => {
                // replace the value of a `key = value` line, or one number inside it
                if let Some((k, v)) = lines[i].split_once('=') {
                    let bad = NONSENSE[rng.below(NONSENSE.len())];
                    let nums: Vec<(usize, usize)> = number_spans(v);
                    let v2 = if !nums.is_empty() && rng.below(2) == 0 {
                        let (a, b) = nums[rng.below(nums.len())];
                        format!("{}{}{}", &v[..a], bad, &v[b..])
                    } else {
                        format!(" {bad}")
                    };
                    lines[i] = format!("{k}={v2}");
                }
            }
            4 => {
                let j = rng.below(lines.len());
                lines.swap(i, j);
            }
            _ => {
                // truncate the line at a random character
                let cut = rng.below(lines[i].chars().count() + 1);
                lines[i] = lines[i].chars().take(cut).collect();
            }
        }
    }
    let mut out = lines.join("\n");
    if rng.below(8) == 0 {
        // truncate the whole file
        let cut = rng.below(out.chars().count() + 1);
        out = out.chars().take(cut).collect();
    }
    out
}

/// Byte ranges of the numbers in `s`.
fn number_spans(s: &str) -> Vec<(usize, usize)> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() || b[i] == b'-' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_digit() || b"-.eE".contains(&b[i])) {
                i += 1;
            }
            out.push((start, i));
        } else {
            i += 1;
        }
    }
    out
}

#[test]
fn mutated_fog_box_never_panics() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut ok, mut errors) = (0, 0);
    for case in 0..400 {
        let text = mutate(&mut rng, FOG_BOX);
        let result = std::panic::catch_unwind(|| load("fuzz.toml", &text));
        match result {
            Err(_) => panic!("case {case}: Scene::load panicked on\n{text}"),
            Ok(Ok(_)) => ok += 1,
            Ok(Err(e)) => {
                // the contract holds for every error, not only the ones written by hand
                assert!(
                    e.line.is_some() && !e.key.is_empty() && !e.message.is_empty(),
                    "case {case}: {e}\n{text}"
                );
                errors += 1;
            }
        }
    }
    // the mutations are neither all harmless nor all fatal
    assert!(ok > 20 && errors > 100, "{ok} loaded, {errors} rejected");
}

#[test]
fn rough_plastic_values_outside_their_range() {
    expect_error(
        "\n[materials.p]\ntype = \"rough_plastic\"\nalpha = 0\n",
        4,
        "materials.p.alpha",
        &["below 0.001"],
    );
    expect_error(
        "\n[materials.p]\ntype = \"rough_plastic\"\nior = 1.0\n",
        4,
        "materials.p.ior",
        &["not 1"],
    );
    expect_error(
        "\n[materials.p]\ntype = \"rough_plastic\"\ndiffuse = [0.5, 1.5, 0.5]\n",
        4,
        "materials.p.diffuse",
        &["above 1"],
    );
    expect_error(
        "\n[materials.p]\ntype = \"rough_plastic\"\nspecular = -1\n",
        4,
        "materials.p.specular",
        &[">= 0"],
    );
    expect_error(
        "\n[materials.p]\ntype = \"rough_plastic\"\ndistribution = \"phong\"\n",
        4,
        "materials.p.distribution",
        &["phong"],
    );
}

#[test]
fn camera_thin_lens_without_focus_or_with_a_bad_aperture() {
    let lens = |keys: &str| {
        BASE.replace(
            "resolution = [8, 8]",
            &format!("resolution = [8, 8]\n{keys}"),
        )
    };
    let e = load("cam.toml", &lens("aperture_radius = 0.1"))
        .err()
        .unwrap();
    assert_eq!(e.key.as_str(), "camera.focus_distance", "{e}");
    assert!(e.message.contains("thin lens"), "{e}");
    let e = load(
        "cam.toml",
        &lens("aperture_radius = -0.1\nfocus_distance = 2.0"),
    )
    .err()
    .unwrap();
    assert_eq!(
        (e.line, e.key.as_str()),
        (Some(8), "camera.aperture_radius"),
        "{e}"
    );
    let e = load(
        "cam.toml",
        &lens("aperture_radius = 0.1\nfocus_distance = -2.0"),
    )
    .err()
    .unwrap();
    assert_eq!(
        (e.line, e.key.as_str()),
        (Some(9), "camera.focus_distance"),
        "{e}"
    );
    assert!(load(
        "cam.toml",
        &lens("aperture_radius = 0.1\nfocus_distance = 2.0")
    )
    .is_ok());
}
