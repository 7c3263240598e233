//! `benches/peers/to_tungsten.py`, the tungsten side of the peers' harness, offline (tungsten
//! itself is never needed): each quad keeps pathspace's side (tungsten's normal is the frame's
//! z column cross its x column), each emitter and the camera carry the medium they sit in,
//! medium boxes are grown by 1e-3 and nothing else changes size, a rough conductor keeps its
//! alpha and complex index; scenes outside the common subset are refused with the reason. The
//! Mitsuba side is read back through the importer in `inputs::mitsuba_import`.

use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The converter's output for `scene` (a file under `scenes/`), or its exit status and stderr.
fn convert(script: &str, scene: &str, args: &[&str]) -> Result<String, (i32, String)> {
    convert_path(
        script,
        &dir().join("scenes").join(scene).to_string_lossy(),
        args,
    )
}

/// The converter's output for the scene file `path`, or its exit status and stderr.
fn convert_path(script: &str, path: &str, args: &[&str]) -> Result<String, (i32, String)> {
    let out = Command::new("python3")
        .arg(dir().join("benches/peers").join(script))
        .arg(path)
        .args(args)
        .output()
        .expect("python3 runs the converter");
    match out.status.code() {
        Some(0) => Ok(String::from_utf8(out.stdout).unwrap()),
        code => Err((
            code.unwrap_or(-1),
            String::from_utf8_lossy(&out.stderr).into(),
        )),
    }
}

fn vec3(v: &Value) -> [f64; 3] {
    std::array::from_fn(|i| v[i].as_f64().unwrap())
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn toml_shapes(scene: &str) -> Vec<toml::Value> {
    let text = std::fs::read_to_string(dir().join("scenes").join(scene)).unwrap();
    let t: toml::Table = toml::from_str(&text).unwrap();
    t["shapes"].as_array().unwrap().clone()
}

fn f(v: &toml::Value) -> [f64; 3] {
    std::array::from_fn(|i| {
        let x = &v.as_array().unwrap()[i];
        x.as_float()
            .unwrap_or_else(|| x.as_integer().unwrap() as f64)
    })
}

#[test]
fn tungsten_scenes_keep_sides_sizes_and_media() {
    for (scene, medium_at_eye) in [("fog-box.toml", None), ("maze-fog.toml", Some("fog"))] {
        let json: Value =
            serde_json::from_str(&convert("to_tungsten.py", scene, &["path_tracer"]).unwrap())
                .unwrap();
        let prims = json["primitives"].as_array().unwrap();
        let shapes = toml_shapes(scene);
        assert_eq!(prims.len(), shapes.len(), "{scene}");
        assert_eq!(json["camera"]["medium"].as_str(), medium_at_eye, "{scene}");
        for (p, s) in prims.iter().zip(&shapes) {
            match s["type"].as_str().unwrap() {
                "quad" => {
                    let m: Vec<f64> = p["transform"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|x| x.as_f64().unwrap())
                        .collect();
                    let (x, z) = ([m[0], m[4], m[8]], [m[2], m[6], m[10]]);
                    let (n, want) = (cross(z, x), cross(f(&s["u"]), f(&s["v"])));
                    for i in 0..3 {
                        assert!((n[i] - want[i]).abs() < 1e-9, "{scene}: {n:?} vs {want:?}");
                    }
                    if s.get("emission").is_some() {
                        // the lights of both scenes hang inside the fog
                        assert_eq!(p["ext_medium"], "fog", "{scene}: {p}");
                    }
                }
                "box" => {
                    let (lo, hi) = (f(&s["min"]), f(&s["max"]));
                    let grow = if s.get("interior").is_some() {
                        2e-3
                    } else {
                        0.0
                    };
                    let size = vec3(&p["transform"]["scale"]);
                    for i in 0..3 {
                        assert!(
                            (size[i] - (hi[i] - lo[i] + grow)).abs() < 1e-9,
                            "{scene}: {p}"
                        );
                    }
                }
                _ => {}
            }
        }
    }
}

#[test]
fn scenes_outside_the_common_subset_are_refused_with_the_reason() {
    for script in ["to_tungsten.py", "to_mitsuba.py"] {
        let args: &[&str] = if script == "to_tungsten.py" {
            &["path_tracer"]
        } else {
            &[]
        };
        let tinted = tinted_glass_scene();
        let schlick = schlick_floor_scene();
        let hidden = glass_scene_variant(
            "hidden",
            ("specular_transmittance = 0.5\n", ""),
            "hide_emitters = true\n",
        );
        let textured_eta = glass_scene_variant(
            "textured-eta",
            (
                "type = \"dielectric\"\nior = 1.5\nspecular_transmittance = 0.5",
                "type = \"rough_conductor\"\nalpha = 0.2\neta = { texture = \"checkerboard\" }",
            ),
            "",
        );
        let textured_emission = std::env::temp_dir().join("pathspace-peers-textured-emission.toml");
        let text = tinted_glass_text()
            .replacen("specular_transmittance = 0.5\n", "", 1)
            .replacen(
                "emission = 1.0",
                "emission = { texture = \"checkerboard\" }",
                1,
            );
        std::fs::write(&textured_emission, text).expect("the temporary directory is writable");
        let variant = |name: &str| variant_scene(name).to_str().unwrap().to_string();
        let mut refused = vec![
            ("door-slit.toml".to_string(), "Schlick"),
            ("cloud.toml".to_string(), "ray-marched"),
            (
                "volume-caustic.toml".to_string(),
                "spot light with a falloff",
            ),
            (tinted.to_str().unwrap().to_string(), "untinted"),
            (schlick.to_str().unwrap().to_string(), "Schlick"),
            (hidden.to_str().unwrap().to_string(), "hide_emitters"),
            (
                textured_emission.to_str().unwrap().to_string(),
                "textured emission",
            ),
        ];
        refused.push((textured_eta.to_str().unwrap().to_string(), "textured `eta`"));
        let anisotropic = glass_scene_variant(
            "anisotropic",
            (
                "type = \"dielectric\"\nior = 1.5\nspecular_transmittance = 0.5",
                "type = \"rough_conductor\"\nalpha_u = 0.2\nalpha_v = 0.05",
            ),
            "",
        );
        refused.push((
            anisotropic.to_str().unwrap().to_string(),
            "anisotropic roughness",
        ));
        if script == "to_tungsten.py" {
            // the variant Mitsuba 3 renders with a spot light, which tungsten has not; and a
            // GGX alpha below the 1e-3 tungsten raises every alpha to
            refused.push((
                variant("volume-caustic-hard-cone"),
                "spot light (tungsten has none)",
            ));
            refused.push((
                rough_metal_scene("mirror-like", "alpha = 0.0005\neta = 1.0\nk = 2.0"),
                "alpha 0.0005 (tungsten raises alpha below 0.001",
            ));
        }
        for (scene, reason) in &refused {
            let scene = scene.as_str();
            let (code, err) = convert(script, scene, args).unwrap_err();
            assert_eq!(code, 2, "{script} {scene}: {err}");
            assert!(err.contains(reason), "{script} {scene}: {err}");
        }
    }
}

/// tungsten's `rough_conductor` for pathspace's: GGX, `roughness` the same alpha (tungsten's
/// `roughnessToAlpha` is the identity for GGX), the same complex index per channel, `specular`
/// as its `albedo`; without an index (pathspace's F = 1) eta 0 and k 1, where tungsten's
/// Fresnel term is exactly 1.
#[test]
fn tungsten_rough_conductor_keeps_alpha_and_the_complex_index() {
    for (name, keys, eta, k, albedo) in [
        (
            "index",
            "alpha = 0.2\neta = [0.2, 0.9, 1.1]\nk = [3.9, 2.45, 2.14]\nspecular = [0.9, 0.8, 0.7]",
            [0.2, 0.9, 1.1],
            [3.9, 2.45, 2.14],
            [0.9, 0.8, 0.7],
        ),
        ("no-index", "alpha = 0.2", [0.0; 3], [1.0; 3], [1.0; 3]),
    ] {
        let path = rough_metal_scene(name, keys);
        let json = convert_path("to_tungsten.py", &path, &["path_tracer"]).unwrap();
        let json: Value = serde_json::from_str(&json).unwrap();
        let bsdf = json["bsdfs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["name"] == "glass")
            .unwrap();
        assert_eq!(bsdf["type"], "rough_conductor", "{bsdf}");
        assert_eq!(bsdf["distribution"], "ggx", "{bsdf}");
        assert_eq!(bsdf["roughness"].as_f64(), Some(0.2), "{bsdf}");
        assert_eq!(vec3(&bsdf["eta"]), eta, "{bsdf}");
        assert_eq!(vec3(&bsdf["k"]), k, "{bsdf}");
        assert_eq!(vec3(&bsdf["albedo"]), albedo, "{bsdf}");
    }
}

/// The tinted glass scene with its ball a rough conductor of the TOML `keys`, written to the
/// temporary directory.
fn rough_metal_scene(name: &str, keys: &str) -> String {
    let path = glass_scene_variant(
        &format!("rough-{name}"),
        (
            "type = \"dielectric\"\nior = 1.5\nspecular_transmittance = 0.5",
            &format!("type = \"rough_conductor\"\n{keys}"),
        ),
        "",
    );
    path.to_str().unwrap().to_string()
}

/// tungsten's grid for the cloud's baked lattice: OpenVDB's index i (where `BoxSampler` puts
/// value i) lands on pathspace's vertex min + i h, the lattice's own index space is kept
/// (`normalize_size` off), and free paths and transmittance integrate the trilinear density
/// (`exact_linear`, not the nearest voxel's). The `.vdb` itself needs python3-openvdb, which
/// CI lacks; `voxel_grid` only names it.
#[test]
fn tungsten_grid_puts_the_lattice_on_pathspaces_vertices() {
    let scene = variant_scene("cloud-tracking");
    let code = format!(
        "import json, sys; sys.path.insert(0, {peers:?}); import scene, to_tungsten; \
         m = scene.Scene({scene:?}).media['cloud']; \
         print(json.dumps([to_tungsten.voxel_grid(m, 'cloud.vdb'), m]))",
        peers = dir().join("benches/peers").to_str().unwrap(),
        scene = scene.to_str().unwrap(),
    );
    let out = Command::new("python3")
        .args(["-c", &code])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let (grid, m) = (&v[0], &v[1]);
    assert_eq!(grid["type"], "vdb");
    assert_eq!(grid["density_name"], "density");
    assert_eq!(grid["normalize_size"], false);
    assert_eq!(grid["integration_method"], "exact_linear");
    assert_eq!(grid["sampling_method"], "exact_linear");
    let t: Vec<f64> = grid["transform"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let n = m["res"][0].as_f64().unwrap();
    // the world point of index (i, j, k): t is row-major 4x4
    let world = |ijk: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|r| (0..3).map(|c| t[4 * r + c] * ijk[c]).sum::<f64>() + t[4 * r + 3])
    };
    let (lo, hi) = (vec3(&m["min"]), vec3(&m["max"]));
    for (ijk, want) in [
        ([0.0; 3], lo),
        ([n - 1.0; 3], hi),
        ([n - 1.0, 0.0, 0.0], [hi[0], lo[1], lo[2]]),
        ([0.0, 0.0, n - 1.0], [lo[0], lo[1], hi[2]]),
    ] {
        let got = world(ijk);
        for i in 0..3 {
            assert!(
                (got[i] - want[i]).abs() < 1e-12,
                "{ijk:?} -> {got:?}, not {want:?}"
            );
        }
    }
    assert_eq!(&t[12..], &[0.0, 0.0, 0.0, 1.0]);
}

/// A side of vacuum has no medium key in tungsten's JSON (tungsten refuses an empty name and
/// reads a missing one as vacuum): the square-lit volume caustic's glass ball, vacuum inside and
/// haze outside, keeps only `ext_medium`, and its light, hung in the haze, has it on both sides.
#[test]
fn tungsten_leaves_a_vacuum_side_without_a_medium() {
    let path = variant_scene("volume-caustic-quad");
    let out = convert_path("to_tungsten.py", path.to_str().unwrap(), &["path_tracer"]).unwrap();
    let json: Value = serde_json::from_str(&out).unwrap();
    let prims = json["primitives"].as_array().unwrap();
    for p in prims {
        for key in ["int_medium", "ext_medium"] {
            assert_ne!(p.get(key).and_then(Value::as_str), Some(""), "{p}");
        }
    }
    let ball = prims.iter().find(|p| p["type"] == "sphere").unwrap();
    assert!(ball.get("int_medium").is_none(), "{ball}");
    assert_eq!(ball["ext_medium"], "haze", "{ball}");
    let light = prims.iter().find(|p| p.get("emission").is_some()).unwrap();
    assert_eq!(
        (&light["int_medium"], &light["ext_medium"]),
        (&Value::from("haze"), &Value::from("haze"))
    );
}

/// The variant `name` of a paper scene (`benches/peers/scene.py NAME`), written to the
/// temporary directory.
fn variant_scene(name: &str) -> PathBuf {
    let out = Command::new("python3")
        .arg(dir().join("benches/peers/scene.py"))
        .arg(name)
        .output()
        .expect("python3 runs benches/peers/scene.py");
    assert!(out.status.success(), "{name}");
    let path = std::env::temp_dir().join(format!("pathspace-peers-{name}.toml"));
    std::fs::write(&path, out.stdout).expect("the temporary directory is writable");
    path
}

/// A rough conductor with pathspace's Schlick `reflectance` under a lamp: Mitsuba 3's
/// roughconductor has only the Fresnel term of a complex index, so both converters refuse it
/// rather than render another metal.
fn schlick_floor_scene() -> PathBuf {
    let path = std::env::temp_dir().join("pathspace-peers-schlick-floor.toml");
    let text = tinted_glass_text().replace(
        "type = \"dielectric\"\nior = 1.5\nspecular_transmittance = 0.5",
        "type = \"rough_conductor\"\nalpha = 0.2\nreflectance = 0.9",
    );
    assert!(text.contains("rough_conductor"));
    std::fs::write(&path, text).expect("the temporary directory is writable");
    path
}

/// The tinted glass scene with `from` replaced by `to` and `head` before it, written to the
/// temporary directory as `pathspace-peers-NAME.toml`: a scene that differs from what the
/// converters translate in one named thing.
fn glass_scene_variant(name: &str, (from, to): (&str, &str), head: &str) -> PathBuf {
    let path = std::env::temp_dir().join(format!("pathspace-peers-{name}.toml"));
    assert!(tinted_glass_text().contains(from));
    let text = format!("{head}{}", tinted_glass_text().replacen(from, to, 1));
    std::fs::write(&path, text).expect("the temporary directory is writable");
    path
}

/// A glass ball with a `specular_transmittance` under a lamp, written to the temporary
/// directory: the peers' converters know only clear glass, so they must refuse it rather than
/// render clear glass in its place.
fn tinted_glass_scene() -> PathBuf {
    let path = std::env::temp_dir().join("pathspace-peers-tinted-glass.toml");
    std::fs::write(&path, tinted_glass_text()).expect("the temporary directory is writable");
    path
}

fn tinted_glass_text() -> &'static str {
    r#"
[camera]
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 40.0
resolution = [8, 8]

[materials.glass]
type = "dielectric"
ior = 1.5
specular_transmittance = 0.5

[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 0.5
material = "glass"

[[shapes]]
type = "quad"
origin = [-1.0, 1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 0.0, 2.0]
emission = 1.0
"#
}
