//! Smooth meshes (`smooth_normals`, `scene::build::normals`): a mesh whose vertex normals are
//! its face normals renders bit for bit as the flat mesh, in every mode of transport; without
//! normals in the file, each position gets the angle-weighted normal of the faces around it
//! (Mitsuba 3's `Mesh::compute_normals`), which a triangulated cube tells from an
//! area-weighted one; an emitting smooth mesh is shaded flat when its normals are its face
//! normals, else refused; `flip_normals` negates the geometric and the shading normals as
//! Mitsuba 3 does, hits and (u, v) unchanged.
//! Book: "Scenes and geometry" (the `smooth_normals` key), "Surface scattering" (shading
//! normals).

use glam::Vec3;
use pathspace::geometry::Primitive;
use pathspace::integrator::IntegratorKind;
use pathspace::scene::{Scene, SceneSource};

/// The fixtures' folder (`cube.obj`: per-face `vn`, the face normals).
fn fixtures() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// The cube in haze under an area light, with `mesh_keys` added to its mesh entry.
fn cube_scene(obj: &str, mesh_keys: &str) -> String {
    format!(
        r#"
[camera]
type = "pinhole"
eye = [3.0, 2.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [12, 10]

[materials.white]
type = "lambert"
albedo = 0.7

[materials.plastic]
type = "rough_plastic"
alpha = 0.2

[media.haze]
type = "homogeneous"
sigma_a = 0.05
sigma_s = 0.2

[[shapes]]
type = "mesh"
obj = "{obj}"
material = "plastic"
{mesh_keys}

[[shapes]]
type = "box"
min = [-4.0, -1.0, -4.0]
max = [4.0, 4.0, 6.0]
material = "white"
interior = "haze"

[[shapes]]
type = "quad"
origin = [-1.0, 3.9, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 0.0, 2.0]
emission = 5.0
"#
    )
}

fn load(dir: &std::path::Path, text: &str) -> Scene {
    let mut src = SceneSource::embedded("cube.toml", text);
    src.base_dir = dir.to_path_buf();
    Scene::load(&src).unwrap_or_else(|e| panic!("{e}"))
}

fn render_bits(scene: &Scene, kind: IntegratorKind) -> Vec<u64> {
    crate::common::film_bits(scene, kind, 7)
}

#[test]
fn vertex_normals_equal_to_the_face_normals_render_as_the_flat_mesh() {
    let dir = fixtures();
    let flat = load(&dir, &cube_scene("cube.obj", ""));
    let smooth = load(&dir, &cube_scene("cube.obj", "smooth_normals = true"));
    assert!(smooth.shapes[0].normals.is_some() && flat.shapes[0].normals.is_none());
    for kind in [
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
    ] {
        let (a, b) = (render_bits(&flat, kind), render_bits(&smooth, kind));
        assert!(a.iter().any(|&x| x != 0), "{kind:?}: a black image");
        assert!(a == b, "{kind:?}: the smooth cube's image differs");
    }
}

/// A folder holding `bare.obj`: the fixture cube without its `vn` (faces keep positions only).
fn bare_cube(tag: &str) -> std::path::PathBuf {
    let dir = crate::common::cli::scratch("normals", tag);
    let cube = std::fs::read_to_string(fixtures().join("cube.obj")).unwrap();
    let bare: String = cube
        .lines()
        .filter(|l| !l.starts_with("vn"))
        .map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            if words.first() == Some(&"f") {
                let ids: Vec<&str> = words[1..]
                    .iter()
                    .map(|w| w.split('/').next().unwrap())
                    .collect();
                format!("f {}\n", ids.join(" "))
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(dir.join("bare.obj"), bare).unwrap();
    dir
}

/// The cube without its `vn`: every corner's angle-weighted normal is the diagonal
/// `sign(p) / sqrt(3)` (each of its three faces meets it with a right angle, however the
/// triangulation splits it; area weights would favour the faces split at that corner).
#[test]
fn without_normals_in_the_file_the_corners_get_angle_weighted_normals() {
    let dir = bare_cube("bare");
    let scene = load(&dir, &cube_scene("bare.obj", "smooth_normals = true"));
    let normals = scene.shapes[0].normals.as_ref().expect("a smooth mesh");
    assert_eq!(normals.corners.len(), 12);
    for (k, corners) in normals.corners.iter().enumerate() {
        let Primitive::Triangle(t) = scene.prims[normals.first_prim as usize + k] else {
            panic!("triangle {k} is not a triangle");
        };
        for (p, n) in [t.p0, t.p1, t.p2].iter().zip(corners) {
            let expected = p.signum() / 3f32.sqrt();
            assert!(
                (*n - expected).length() < 1e-6,
                "corner {p}: {n} vs {expected}"
            );
        }
    }
}

/// An emitting smooth mesh whose vertex normals are its face normals (the cube's `vn`) is shaded
/// flat, the flat emitting cube bit for bit; without its `vn` its corners get the diagonals, a
/// curved light (Mitsuba 3 tests an area emitter's side and samples it by the interpolated
/// normal, which the light sampling here does not), refused naming the key.
#[test]
fn an_emitting_smooth_mesh_is_flat_or_refused_by_name() {
    let dir = fixtures();
    let flat = load(&dir, &cube_scene("cube.obj", "emission = 1.0"));
    let smooth = load(
        &dir,
        &cube_scene("cube.obj", "smooth_normals = true\nemission = 1.0"),
    );
    assert!(smooth.shapes[0].normals.is_none() && smooth.shapes[0].light.is_some());
    for kind in [IntegratorKind::Path, IntegratorKind::Bdpt] {
        assert!(
            render_bits(&flat, kind) == render_bits(&smooth, kind),
            "{kind:?}"
        );
    }
    let text = cube_scene("bare.obj", "smooth_normals = true\nemission = 1.0");
    let mut src = SceneSource::embedded("cube.toml", &text);
    src.base_dir = bare_cube("bare-emitting");
    let err = Scene::load(&src).err().expect("refused").to_string();
    assert!(
        err.contains("smooth_normals") && err.contains("curved"),
        "{err}"
    );
}

/// The interpolated normal is a unit vector: at the centre of a triangle whose corners carry
/// the three axes it is the diagonal, not a third of it.
#[test]
fn the_interpolated_normal_is_normalized() {
    let t = pathspace::geometry::shape::Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y).unwrap();
    let n = [Vec3::X, Vec3::Y, Vec3::Z];
    let centre = (Vec3::X + Vec3::Y) / 3.0;
    let s = t.shading_normal(&n, centre);
    assert!((s - Vec3::ONE / 3f32.sqrt()).length() < 1e-6, "{s}");
    for (p, c) in [(Vec3::ZERO, n[0]), (Vec3::X, n[1]), (Vec3::Y, n[2])] {
        assert!((t.shading_normal(&n, p) - c).length() < 1e-6, "corner {p}");
    }
}

/// `v` of a JSON array of three numbers.
fn v3(v: &serde_json::Value) -> Vec3 {
    let c = |i: usize| v[i].as_f64().unwrap() as f32;
    Vec3::new(c(0), c(1), c(2))
}

/// Mitsuba 3's meshes with and without `flip_normals` (recorded by
/// `scripts/make_mesh_normal_fixtures.py`: computed vertex normals, a file's `vn`, a PLY, and a
/// flat flipped mesh), read through the importer: the same rays hit the same points with the
/// same geometric and shading normals and uv (flipping turns both normals, not the uv), and on
/// the flat mesh an area emitter sends light back along a ray exactly where Mitsuba's does.
#[test]
fn flipped_meshes_normals_are_mitsubas() {
    use pathspace::geometry::Ray;
    use pathspace::scene::mitsuba;
    let dir = fixtures().join("textures");
    let text = std::fs::read_to_string(dir.join("mitsuba-mesh-normals.json")).unwrap();
    let r: serde_json::Value = serde_json::from_str(&text).unwrap();
    let cases = r["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 7);
    let close = |a: Vec3, b: Vec3, scale: f32| (a - b).abs().max_element() < 1e-5 * scale;
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let shape = c["xml"].as_str().unwrap();
        let flat = shape.contains("face_normals");
        // the flat mesh emits (a curved smooth emitter is refused), the others are textured
        let inside = if flat {
            r#"<emitter type="area"><rgb name="radiance" value="1"/></emitter>"#
        } else {
            r#"<bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf>"#
        };
        let xml = format!(
            "<scene version=\"3.0.0\"><sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/><rfilter type=\"box\"/></film></sensor>{shape}{inside}</shape></scene>"
        );
        let src = mitsuba::import("t.xml", &xml, dir.clone()).unwrap_or_else(|e| panic!("{e}"));
        let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{name}: {e}"));
        for h in c["hits"].as_array().unwrap() {
            let (o, d, p) = (v3(&h["o"]), v3(&h["d"]), v3(&h["p"]));
            let hit = scene.intersect(&Ray::new(o, d), 100.0).expect("a hit");
            let scale = 1.0 + p.abs().max_element();
            assert!(close(hit.p, p, scale), "{name}: hit {} against {p}", hit.p);
            let (n, sh_n) = (v3(&h["n"]), v3(&h["sh_n"]));
            assert!(
                close(hit.ng, n, 1.0),
                "{name} at {p}: ng {} against {n}",
                hit.ng
            );
            let ns = scene.shading_normal(&hit);
            assert!(
                close(ns, sh_n, 1.0),
                "{name} at {p}: ns {ns} against {sh_n}"
            );
            let shape = scene.shape_of(&hit);
            if let Some(l) = shape.light {
                let light = &scene.lights[l as usize];
                let le = pathspace::scene::light::emitted_by(
                    light,
                    &scene.prims,
                    hit.prim,
                    (hit.p, hit.ng),
                    -d,
                );
                assert_eq!(
                    le.x,
                    h["le"].as_f64().unwrap() as f32,
                    "{name} at {p}: emission"
                );
                continue;
            }
            let t = shape.texture.as_ref().expect("textured");
            let uv =
                t.uv.uv(hit.prim, &scene.prims[hit.prim as usize], hit.p, hit.ng);
            let want = Vec3::new(
                h["uv"][0].as_f64().unwrap() as f32,
                h["uv"][1].as_f64().unwrap() as f32,
                0.0,
            );
            assert!(
                close(uv.extend(0.0), want, 1.0),
                "{name} at {p}: uv {uv} against {want}"
            );
        }
    }
}
