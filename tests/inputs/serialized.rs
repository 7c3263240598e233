//! Mitsuba's `serialized` meshes (`scene::build::serialized`): every shape of the fixtures
//! `scripts/make_serialized_fixtures.py` writes (versions 3 and 4, single and double
//! precision, normals, texture coordinates, colours, several shapes per file) builds into the
//! triangles, corner normals and corner texture coordinates Mitsuba 3 loads from it (recorded
//! in `tests/fixtures/serialized/mitsuba.json`); the `serialized` shape renders bit for bit as
//! the OBJ it was written from; and every malformed file is refused naming the file, the shape
//! and what is wrong.

use crate::common;

use flate2::{write::ZlibEncoder, Compression};
use glam::{Vec2, Vec3};
use pathspace::geometry::Primitive;
use pathspace::scene::{mitsuba, Scene, SceneSource, UvMap};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A scene of one textured mesh `keys` (so that its texture coordinates are kept) read from
/// `dir`.
fn mesh_scene(dir: &Path, keys: &str) -> SceneSource {
    SceneSource {
        name: "t.toml".into(),
        text: format!(
            r#"[camera]
type = "pinhole"
eye = [0.0, 0.0, 6.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [8, 8]
[materials.checks]
type = "lambert"
albedo = {{ texture = "checkerboard" }}
[[shapes]]
type = "mesh"
material = "checks"
{keys}
"#
        ),
        base_dir: dir.to_path_buf(),
        origin: None,
        inputs: Default::default(),
    }
}

fn floats<const N: usize>(v: &Value) -> Vec<[f32; N]> {
    let row = |r: &Value| std::array::from_fn(|i| r[i].as_f64().unwrap() as f32);
    v.as_array().unwrap().iter().map(row).collect()
}

/// The most two unit normals computed in f32 by the two renderers from a mesh without normals
/// may differ per component: the same angle-weighted face normals summed and normalized in
/// another rounding order.
const NORMAL_ROUNDING: f32 = 4.0 * f32::EPSILON;

/// Every shape of every fixture: triangle corners, texture coordinates and the file's normals
/// (normalized) bit for bit as Mitsuba 3 loads them; normals computed for a shape without them
/// (angle-weighted) to f32 rounding.
#[test]
fn every_shape_builds_as_mitsuba_loads_it() {
    let dir = root().join("tests/fixtures/serialized");
    let text = std::fs::read_to_string(dir.join("mitsuba.json")).unwrap();
    let recorded: Value = serde_json::from_str(&text).unwrap();
    let shapes = recorded["shapes"].as_array().unwrap();
    assert_eq!(shapes.len(), 5);
    for rec in shapes {
        let (file, k) = (
            rec["file"].as_str().unwrap(),
            rec["shape_index"].as_u64().unwrap(),
        );
        let what = format!("{file} shape {k}");
        let keys = format!("obj = \"{file}\"\nshape_index = {k}\nsmooth_normals = true");
        let scene = Scene::load(&mesh_scene(&dir, &keys)).unwrap_or_else(|e| panic!("{e}"));
        let pos = floats::<3>(&rec["vertex_positions"]);
        let nrm = floats::<3>(&rec["vertex_normals"]);
        let uvs = floats::<2>(&rec["vertex_texcoords"]);
        let faces: Vec<[usize; 3]> = floats::<3>(&rec["faces"])
            .iter()
            .map(|f| f.map(|i| i as usize))
            .collect();
        let stored = rec["stored_normals"].as_bool().unwrap();
        let shape = &scene.shapes[0];
        let normals = shape.normals.as_ref().expect("a smooth mesh");
        let corner_uvs = match &shape.texture.as_ref().unwrap().uv {
            UvMap::Mesh { corners, .. } => Some(corners.clone()),
            _ => None,
        };
        assert_eq!(corner_uvs.is_some(), !uvs.is_empty(), "{what}");
        assert_eq!(normals.corners.len(), faces.len(), "{what}");
        for (t, f) in faces.iter().enumerate() {
            let Primitive::Triangle(tri) = scene.prims[normals.first_prim as usize + t] else {
                panic!("{what}: triangle {t} is not a triangle")
            };
            for (c, (p, &v)) in [tri.p0, tri.p1, tri.p2].iter().zip(f).enumerate() {
                let want = Vec3::from_array(pos[v]);
                assert_eq!(
                    p.to_array().map(f32::to_bits),
                    want.to_array().map(f32::to_bits)
                );
                let (n, m) = (normals.corners[t][c], Vec3::from_array(nrm[v]));
                let off = (n - m).abs().max_element();
                let bound = if stored { 0.0 } else { NORMAL_ROUNDING };
                assert!(off <= bound, "{what}: triangle {t} corner {c}: {n} vs {m}");
                if let Some(uv) = &corner_uvs {
                    let (a, b) = (uv[t][c], Vec2::from_array(uvs[v]));
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }
}

/// Every pixel of a 4-spp path-traced image of an imported XML read from `scenes/xml`.
fn xml_pixels(text: &str) -> Vec<[f32; 3]> {
    let src = mitsuba::import("t.xml", text, root().join("scenes/xml")).unwrap();
    let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
    let mut r = pathspace::integrator::Renderer::new(
        &scene,
        pathspace::integrator::IntegratorKind::Path,
        7,
        None,
    );
    r.pass(4, &|| {});
    let img = r.film.as_ref().unwrap().image();
    img.pixels.iter().map(|p| p.to_array()).collect()
}

/// `scenes/xml/serialized.xml` with each `serialized` shape replaced by `shape(index)`.
fn with_meshes(shape: impl Fn(usize) -> String) -> String {
    let text = std::fs::read_to_string(root().join("scenes/xml/serialized.xml")).unwrap();
    let mut out = String::new();
    let mut rest = text.as_str();
    while let Some(a) = rest.find("<shape type=\"serialized\">") {
        let b = a + rest[a..].find("name=\"shape_index\" value=\"").unwrap();
        let k = &rest[b..].split('"').nth(3).unwrap();
        let k: usize = k.parse().unwrap();
        let b = b + rest[b..].find('\n').unwrap();
        out.push_str(&rest[..a]);
        out.push_str(&shape(k));
        rest = &rest[b..];
    }
    out + rest
}

/// The spheres and the floor of `scenes/xml/serialized.xml`, read from `spheres.serialized`
/// (a double-precision sphere with normals, a single-precision one without, a floor with
/// texture coordinates), render bit for bit as the OBJ files they were written from (the
/// floor as the same quad in an OBJ with `vt`, not flipped: `flip_tex_coords` false); with a
/// shape index of another mesh the image changes.
#[test]
fn serialized_shapes_render_as_the_obj_they_were_written_from() {
    let dir = common::cli::scratch("serialized", "twin");
    std::fs::write(
        dir.join("floor.obj"),
        "v -3 0 3\nv 3 0 3\nv 3 0 -3\nv -3 0 -3\nvt 0 0\nvt 3 0\nvt 3 3\nvt 0 3\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    let floor = dir.join("floor.obj");
    let serialized = std::fs::read_to_string(root().join("scenes/xml/serialized.xml")).unwrap();
    let objs = with_meshes(|k| {
        let file = ["sphere-vn.obj", "sphere-bare.obj", floor.to_str().unwrap()][k];
        format!("<shape type=\"obj\">\n        <string name=\"filename\" value=\"{file}\"/>\n        <boolean name=\"flip_tex_coords\" value=\"false\"/>\n")
    });
    assert_ne!(objs, serialized);
    assert_eq!(xml_pixels(&objs), xml_pixels(&serialized));
    let swapped = serialized.replacen(
        "name=\"shape_index\" value=\"0\"",
        "name=\"shape_index\" value=\"1\"",
        1,
    );
    assert_ne!(xml_pixels(&swapped), xml_pixels(&serialized));
}

/// One shape of a serialized file: its header and its zlib stream of `flags`, the name
/// (version 4), the counts and `arrays` (already encoded).
fn shape_bytes(version: u16, flags: u32, counts: [u64; 2], arrays: &[u8]) -> Vec<u8> {
    let mut body = flags.to_le_bytes().to_vec();
    if version == 4 {
        body.extend(b"name\0");
    }
    body.extend(counts[0].to_le_bytes());
    body.extend(counts[1].to_le_bytes());
    body.extend(arrays);
    let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
    z.write_all(&body).unwrap();
    let mut out = [0x041Cu16.to_le_bytes(), version.to_le_bytes()].concat();
    out.extend(z.finish().unwrap());
    out
}

/// A triangle's single-precision positions and its indices `ids`.
fn triangle(ids: [u32; 3]) -> Vec<u8> {
    let pos = [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut b: Vec<u8> = pos.iter().flat_map(|x| x.to_le_bytes()).collect();
    b.extend(ids.iter().flat_map(|i| i.to_le_bytes()));
    b
}

/// The error of loading shape `k` (none: no `shape_index` key) of `bytes` written as `name`.
fn load_error(dir: &Path, name: &str, bytes: &[u8], k: Option<u32>) -> String {
    std::fs::write(dir.join(name), bytes).unwrap();
    let index = k.map_or(String::new(), |k| format!("\nshape_index = {k}"));
    let src = mesh_scene(dir, &format!("obj = \"{name}\"{index}"));
    match Scene::load(&src) {
        Ok(_) => panic!("{name} (shape {k:?}) was accepted"),
        Err(e) => e.to_string(),
    }
}

/// A malformed file is refused naming the file, the shape and what is wrong, before anything
/// its counts claim is allocated; `shape_index` on another format is refused.
#[test]
fn malformed_serialized_files_are_refused_by_file_shape_and_cause() {
    let dir = common::cli::scratch("serialized", "errors");
    let good = shape_bytes(4, 0x1000, [3, 1], &triangle([0, 1, 2]));
    let with_dictionary = |shapes: &[&[u8]]| {
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for s in shapes {
            offsets.push(out.len() as u64);
            out.extend(*s);
        }
        out.extend(offsets.iter().flat_map(|o| o.to_le_bytes()));
        out.extend((shapes.len() as u32).to_le_bytes());
        out
    };
    let two = with_dictionary(&[&good, &good]);
    let cases: Vec<(&str, Vec<u8>, Option<u32>, &str)> = vec![
        (
            "magic.serialized",
            [&[0x1D, 0x04], &good[2..]].concat(),
            None,
            "0x041C",
        ),
        (
            "v5.serialized",
            shape_bytes(5, 0x1000, [3, 1], &triangle([0, 1, 2])),
            None,
            "version 5",
        ),
        ("range.serialized", two.clone(), Some(2), "out of range"),
        (
            "cut.serialized",
            two[..good.len() + 20].to_vec(),
            Some(1),
            "dictionary",
        ),
        (
            "short.serialized",
            good[..good.len() - 6].to_vec(),
            None,
            "stream",
        ),
        (
            "index.serialized",
            shape_bytes(4, 0x1000, [3, 1], &triangle([0, 3, 2])),
            None,
            "names vertex 3",
        ),
        (
            "huge.serialized",
            shape_bytes(4, 0x1000, [1 << 40, 1], &triangle([0, 1, 2])),
            None,
            "MiB",
        ),
        (
            "flags.serialized",
            shape_bytes(4, 0x1040, [3, 1], &triangle([0, 1, 2])),
            None,
            "flags",
        ),
        (
            "lying.serialized",
            shape_bytes(4, 0x1000, [3_000_000, 1], &triangle([0, 1, 2])),
            None,
            "ends after",
        ),
    ];
    for (name, bytes, k, cause) in cases {
        let e = load_error(&dir, name, &bytes, k);
        let shape = format!("shape {}", k.unwrap_or(0));
        assert!(
            e.contains(name) && e.contains(&shape) && e.contains(cause),
            "{name}: {e}"
        );
    }
    // the dictionary's entry points outside the shapes
    let mut bad = two.clone();
    let at = bad.len() - 12;
    bad[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    let e = load_error(&dir, "offset.serialized", &bad, Some(1));
    assert!(e.contains("beyond"), "{e}");
    // both shapes of a good file load; version 3 keeps uint32 offsets
    std::fs::write(dir.join("two.serialized"), &two).unwrap();
    let src = mesh_scene(&dir, "obj = \"two.serialized\"\nshape_index = 1");
    Scene::load(&src).unwrap();
    // shape_index belongs to serialized files
    std::fs::copy(root().join("tests/fixtures/cube.obj"), dir.join("cube.obj")).unwrap();
    let src = mesh_scene(&dir, "obj = \"cube.obj\"\nshape_index = 0");
    let e = Scene::load(&src).err().unwrap().to_string();
    assert!(e.contains("shape_index") && e.contains("cube.obj"), "{e}");
    // the importer: a negative index
    let shape = |file: &str, k: i64| {
        format!(
            r#"<scene version="3.0.0"><shape type="serialized"><string name="filename" value="{file}"/><integer name="shape_index" value="{k}"/></shape></scene>"#
        )
    };
    let e = mitsuba::import("t.xml", &shape("two.serialized", -1), dir.clone())
        .err()
        .unwrap();
    assert!(e.to_string().contains("non-negative"), "{e}");
}

/// Mitsuba 3 reads a mesh by its plugin, whatever the file's name: a `serialized` shape whose
/// file is named otherwise imports with `format = "serialized"` and builds the very triangles
/// of the `.serialized` file; the TOML reads it so with the key, as OBJ without it; an OBJ read
/// by a `serialized` shape is refused by the serialized reader.
#[test]
fn a_serialized_file_is_read_by_the_shape_not_the_name() {
    let dir = common::cli::scratch("serialized", "renamed");
    let fixture = root().join("tests/fixtures/serialized");
    let file = std::fs::read_dir(&fixture)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "serialized"))
        .expect("a serialized fixture");
    std::fs::copy(&file, dir.join("mesh.serialized")).unwrap();
    std::fs::copy(&file, dir.join("mesh.bin")).unwrap();
    std::fs::copy(root().join("tests/fixtures/cube.obj"), dir.join("cube.obj")).unwrap();
    let triangles = |src: &SceneSource| -> Vec<[f32; 9]> {
        let scene = Scene::load(src).unwrap_or_else(|e| panic!("{e}"));
        let corners = |p: &Primitive| match p {
            Primitive::Triangle(t) => [t.p0, t.p1, t.p2].map(|p| p.to_array()).concat(),
            _ => panic!("not a triangle"),
        };
        scene
            .prims
            .iter()
            .map(|p| corners(p).try_into().unwrap())
            .collect()
    };
    let want = triangles(&mesh_scene(&dir, "obj = \"mesh.serialized\""));
    let keyed = mesh_scene(&dir, "obj = \"mesh.bin\"\nformat = \"serialized\"");
    assert_eq!(triangles(&keyed), want);
    let e = Scene::load(&mesh_scene(&dir, "obj = \"mesh.bin\""))
        .err()
        .expect("a serialized file read as OBJ")
        .to_string();
    assert!(e.contains("mesh.bin"), "{e}");
    let xml = |file: &str| {
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/><rfilter type="box"/></film></sensor><shape type="serialized"><string name="filename" value="{file}"/><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf></shape></scene>"#
        )
    };
    let src = mitsuba::import("t.xml", &xml("mesh.bin"), dir.clone()).unwrap();
    assert!(src.text.contains("format = \"serialized\""), "{}", src.text);
    assert_eq!(triangles(&src), want);
    let src = mitsuba::import("t.xml", &xml("cube.obj"), dir.clone()).unwrap();
    let e = Scene::load(&src).err().expect("an OBJ read as serialized");
    assert!(
        e.to_string().contains("cube.obj") && e.to_string().contains("0x041C"),
        "{e}"
    );
}
