//! Textures (`src/texture`) and the (u, v) of the shapes, against Mitsuba 3: the values its
//! `bitmap` and `checkerboard` give at a list of points for every filter, wrap mode and `raw`,
//! and the uv its `rectangle`, `disk`, `sphere` and `cube` give at ray hits, all recorded by
//! `scripts/make_texture_fixtures.py` in `tests/fixtures/textures/mitsuba.json`, with the uv
//! its `obj` and `ply` meshes give (texture coordinates interpolated, v flipped or not, or
//! barycentrics) and its one-channel `eval_1` (a textured roughness); and the identities a
//! texture keeps (bilinear at texel centres, the wrap of edge texels, sRGB).

use glam::{Vec2, Vec3};
use pathspace::geometry::{Hit, Ray};
use pathspace::scene::{mitsuba, Scene, SceneSource};
use pathspace::texture::{srgb_to_linear, Bitmap, FilterType, Texture, UvTransform, WrapMode};
use serde_json::Value;
use std::path::PathBuf;

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/textures")
}

fn recorded() -> Value {
    let text = std::fs::read_to_string(fixtures().join("mitsuba.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn v3(v: &Value) -> Vec3 {
    Vec3::new(
        v[0].as_f64().unwrap() as f32,
        v[1].as_f64().unwrap() as f32,
        v[2].as_f64().unwrap() as f32,
    )
}

/// Two renderers' f32 evaluations of one formula: a few ulps apart, and Dr.Jit's sRGB curve is
/// a polynomial within 1e-6 of the exact one.
const F32_AGREEMENT: f32 = 1e-5;

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= F32_AGREEMENT * (1.0 + b.abs().max_element())
}

/// The albedo texture of the first shape of a TOML scene (a quad) whose material is `albedo`.
fn texture_of(albedo: &str) -> Texture {
    let text = format!(
        "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 40.0\nresolution = [4, 4]\n\
         [materials.t]\ntype = \"lambert\"\nalbedo = {albedo}\n\
         [[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, 0.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nmaterial = \"t\"\n\
         [[lights]]\ntype = \"point\"\nposition = [0.0, 0.0, 2.0]\nintensity = 1.0\n"
    );
    let mut src = SceneSource::embedded("t.toml", &text);
    src.base_dir = fixtures();
    let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
    let t = scene.shapes[0].texture.as_ref().expect("a textured shape");
    (**t.reflectance.as_ref().expect("a textured reflectance")).clone()
}

#[test]
fn bitmap_lookups_are_mitsubas_for_every_filter_wrap_and_raw() {
    let r = recorded();
    let uvs: Vec<Vec2> = r["uvs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| Vec2::new(p[0].as_f64().unwrap() as f32, p[1].as_f64().unwrap() as f32))
        .collect();
    let lookups = r["lookups"].as_array().unwrap();
    assert!(lookups.len() >= 25);
    for l in lookups {
        let to_uv = match l.get("to_uv") {
            Some(m) => format!(", to_uv = {m}"),
            None => String::new(),
        };
        let albedo = format!(
            "{{ texture = \"bitmap\", file = {}, filter_type = {}, wrap_mode = {}, raw = {}{to_uv} }}",
            l["file"], l["filter_type"], l["wrap_mode"], l["raw"]
        );
        let t = texture_of(&albedo);
        for (uv, want) in uvs.iter().zip(l["values"].as_array().unwrap()) {
            let (got, want) = (t.eval(*uv), v3(want));
            assert!(
                close(got, want),
                "{albedo} at {uv}: {got} against Mitsuba's {want}"
            );
        }
    }
}

#[test]
fn checkerboard_is_mitsubas() {
    let r = recorded();
    let t =
        texture_of("{ texture = \"checkerboard\", to_uv = [[3.0, 0.0, 0.0], [0.0, 2.0, 0.0]] }");
    for (uv, want) in r["uvs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(r["checkerboard"]["values"].as_array().unwrap())
    {
        let uv = Vec2::new(
            uv[0].as_f64().unwrap() as f32,
            uv[1].as_f64().unwrap() as f32,
        );
        assert_eq!(t.eval(uv), v3(want), "at {uv}");
    }
    // the pattern: color0 (0.4) on the diagonal quarters of each unit square, color1 (0.2) off it
    let t = texture_of("{ texture = \"checkerboard\" }");
    for (u, v, c) in [
        (0.25, 0.25, 0.4),
        (0.75, 0.75, 0.4),
        (0.75, 0.25, 0.2),
        (0.25, 0.75, 0.2),
        (-0.25, 0.25, 0.2),
        (1.25, 1.75, 0.2),
    ] {
        assert_eq!(t.eval(Vec2::new(u, v)), Vec3::splat(c), "at ({u}, {v})");
    }
}

fn bitmap(filter: FilterType, wrap: WrapMode) -> Bitmap {
    let texels = (0..12)
        .map(|k| Vec3::new(k as f32, 2.0 * k as f32, 0.5))
        .collect();
    Bitmap::new(4, 3, texels, filter, wrap, UvTransform::default()).unwrap()
}

#[test]
fn bilinear_at_a_texel_centre_is_the_texel_and_nearest_is_constant_on_a_texel() {
    for wrap in [WrapMode::Repeat, WrapMode::Mirror, WrapMode::Clamp] {
        let b = bitmap(FilterType::Bilinear, wrap);
        let n = bitmap(FilterType::Nearest, wrap);
        for j in 0..3 {
            for i in 0..4 {
                let centre = Vec2::new((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 3.0);
                let texel = b.texels()[j * 4 + i];
                assert_eq!(b.eval(centre), texel, "texel ({i}, {j}), {wrap:?}");
                // v = 0 is row 0, the image's first (top) row
                for d in [
                    Vec2::new(0.12, 0.0),
                    Vec2::new(-0.1, 0.16),
                    Vec2::new(0.0, -0.16),
                ] {
                    assert_eq!(n.eval(centre + d / Vec2::new(4.0, 3.0) * 0.9), texel);
                }
            }
        }
        // halfway between two texel centres: their mean
        let mid = Vec2::new(2.0 / 4.0, 0.5 / 3.0);
        assert_eq!(b.eval(mid), 0.5 * (b.texels()[1] + b.texels()[2]));
    }
}

#[test]
fn wrap_modes_at_the_edges() {
    // repeat: the opposite edge; mirror: the edge texel again, then inwards; clamp: the edge
    let cases = [
        (
            WrapMode::Repeat,
            [(-1, 3), (-4, 0), (4, 0), (5, 1), (-5, 3)],
        ),
        (WrapMode::Mirror, [(-1, 0), (-2, 1), (4, 3), (5, 2), (8, 0)]),
        (WrapMode::Clamp, [(-1, 0), (-7, 0), (4, 3), (9, 3), (2, 2)]),
    ];
    for (mode, pairs) in cases {
        for (i, want) in pairs {
            assert_eq!(mode.wrap(i, 4), want, "{mode:?} of {i}");
        }
    }
    // bilinear at u = 0 blends the first texel with what the wrap puts left of it
    let t = |w| {
        bitmap(FilterType::Bilinear, w)
            .eval(Vec2::new(0.0, 0.5 / 3.0))
            .x
    };
    assert_eq!(t(WrapMode::Repeat), 0.5 * (0.0 + 3.0));
    assert_eq!(t(WrapMode::Mirror), 0.0);
    assert_eq!(t(WrapMode::Clamp), 0.0);
}

#[test]
fn srgb_decoding_of_known_8_bit_values() {
    // IEC 61966-2-1: the linear segment below 0.04045, the 2.4 power above
    assert_eq!(srgb_to_linear(0.0), 0.0);
    assert_eq!(srgb_to_linear(1.0), 1.0);
    assert_eq!(srgb_to_linear(10.0 / 255.0), 10.0 / 255.0 / 12.92);
    for (byte, linear) in [
        (128u8, 0.215_860_5f32),
        (200, 0.577_580_4),
        (64, 0.051_269_46),
    ] {
        let got = srgb_to_linear(byte as f32 / 255.0);
        assert!(
            (got - linear).abs() < 1e-6,
            "{byte}: {got} against {linear}"
        );
    }
    // the PNG fixture's texel (0, 0) is the bytes (10, 200, 0), decoded unless raw
    let centre = Vec2::new(0.125, 1.0 / 6.0);
    let png = |raw| {
        texture_of(&format!(
            "{{ texture = \"bitmap\", file = \"rgb4x3.png\", raw = {raw} }}"
        ))
        .eval(centre)
    };
    assert_eq!(png(true), Vec3::new(10.0, 200.0, 0.0) / 255.0);
    assert_eq!(
        png(false),
        Vec3::new(10.0, 200.0, 0.0).map(|b| srgb_to_linear(b / 255.0))
    );
}

/// The uv of Mitsuba's shapes at the points its rays hit, from the XML through the importer.
#[test]
fn each_shapes_uv_is_mitsubas() {
    let r = recorded();
    let xml = |shape: &str| {
        format!(
            "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/><film type=\"hdrfilm\"><integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/><rfilter type=\"box\"/></film></sensor>{shape}<bsdf type=\"diffuse\"><texture type=\"checkerboard\" name=\"reflectance\"/></bsdf></shape></scene>"
        )
    };
    let shapes = [
        ("rectangle", "<shape type=\"rectangle\"><transform name=\"to_world\"><scale x=\"2\" y=\"0.5\"/><rotate z=\"1\" angle=\"30\"/><translate x=\"1\" y=\"2\" z=\"3\"/></transform>"),
        ("disk", "<shape type=\"disk\"><transform name=\"to_world\"><scale x=\"2\" y=\"1\"/><translate z=\"1\"/></transform>"),
        ("sphere", "<shape type=\"sphere\"><point name=\"center\" x=\"1\" y=\"-1\" z=\"0.5\"/><float name=\"radius\" value=\"2\"/>"),
        ("cube", "<shape type=\"cube\"><transform name=\"to_world\"><scale x=\"1\" y=\"2\" z=\"0.5\"/><translate x=\"0.5\" z=\"-1\"/></transform>"),
    ];
    for (name, shape) in shapes {
        let src =
            mitsuba::import("t.xml", &xml(shape), fixtures()).unwrap_or_else(|e| panic!("{e}"));
        let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
        let hits = r["shapes"][name].as_array().unwrap();
        assert!(!hits.is_empty());
        for h in hits {
            let (p, n) = (v3(&h["p"]), v3(&h["n"]));
            // a ray towards the recorded point along its normal finds the same point
            let hit = scene.intersect(&Ray::new(p + n, -n), 2.0).expect("a hit");
            assert_uv_is_recorded(&scene, &hit, h, name);
        }
    }
}

/// The uv pathspace's texture lookup gives at `hit` equals the `uv` Mitsuba recorded in `h`,
/// within f32 rounding at the recorded point's magnitude.
fn assert_uv_is_recorded(scene: &Scene, hit: &Hit, h: &Value, name: &str) {
    let p = v3(&h["p"]);
    let shape = &scene.shapes[scene.prim_shape[hit.prim as usize] as usize];
    let t = shape.texture.as_ref().unwrap();
    let prim = &scene.prims[hit.prim as usize];
    let uv = t.uv.uv(hit.prim, prim, hit.p, hit.ng);
    let want = Vec2::new(
        h["uv"][0].as_f64().unwrap() as f32,
        h["uv"][1].as_f64().unwrap() as f32,
    );
    assert!(
        (uv - want).abs().max_element() < 1e-5 * (1.0 + p.abs().max_element()),
        "{name} at {p}: uv {uv} against Mitsuba's {want}"
    );
    assert_dp_du_is_the_uv_derivative(t, hit, prim, name);
}

/// The shape's dp/du at `hit` (the tangent of an anisotropic roughness, Mitsuba's shading
/// frame) is the derivative of its (u, v): a step along it changes u at the rate 1 / |dp/du|
/// and leaves v (central differences, the seams of a periodic coordinate unwrapped).
fn assert_dp_du_is_the_uv_derivative(
    t: &pathspace::scene::ShapeTexture,
    hit: &Hit,
    prim: &pathspace::geometry::Primitive,
    name: &str,
) {
    let d = t.uv.dp_du(hit.prim, prim, hit.p, hit.ng);
    let len = d.length();
    assert!(len > 0.0, "{name} at {}: dp/du is zero", hit.p);
    let h = 3e-3 * (1.0 + hit.p.abs().max_element());
    let e = d / len;
    let step = t.uv.uv(hit.prim, prim, hit.p + h * e, hit.ng)
        - t.uv.uv(hit.prim, prim, hit.p - h * e, hit.ng);
    let step = step - step.round();
    let rate = step * len / (2.0 * h);
    assert!(
        (rate - Vec2::X).abs().max_element() < 1e-2,
        "{name} at {}: along dp/du {d} the uv changes at {rate} x |dp/du|, not (1, 0)",
        hit.p
    );
}

/// The uv of Mitsuba's shapes where its own uv depends on more than the surface: a flipped
/// `rectangle` and `disk` (the normal turns, the uv stays), a `sphere` rotated by its
/// `to_world` (uv in its own frame) and `cylinder`s (phi from the frame Mitsuba builds about
/// the axis, mapped by `to_world`), recorded by `scripts/make_shape_uv_fixtures.py` and read
/// through the importer: the same rays hit the same points, with the same normals and uv.
#[test]
fn each_transformed_shapes_uv_is_mitsubas() {
    let text = std::fs::read_to_string(fixtures().join("mitsuba-shapes.json")).unwrap();
    let r: Value = serde_json::from_str(&text).unwrap();
    let cases = r["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 11);
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let xml = format!(
            "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/><film type=\"hdrfilm\"><integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/><rfilter type=\"box\"/></film></sensor>{}<bsdf type=\"diffuse\"><texture type=\"checkerboard\" name=\"reflectance\"/></bsdf></shape></scene>",
            c["xml"].as_str().unwrap()
        );
        let src = mitsuba::import("t.xml", &xml, fixtures()).unwrap_or_else(|e| panic!("{e}"));
        let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
        for h in c["hits"].as_array().unwrap() {
            let (o, d, p, n) = (v3(&h["o"]), v3(&h["d"]), v3(&h["p"]), v3(&h["n"]));
            let hit = scene.intersect(&Ray::new(o, d), 100.0).expect("a hit");
            let scale = 1.0 + p.abs().max_element();
            assert!(
                (hit.p - p).abs().max_element() < 1e-5 * scale,
                "{name}: hit {} against Mitsuba's {p}",
                hit.p
            );
            assert!(
                hit.ng.dot(n) > 0.9999,
                "{name} at {p}: normal {} against Mitsuba's {n}",
                hit.ng
            );
            assert_uv_is_recorded(&scene, &hit, h, name);
        }
    }
}

/// The uv of Mitsuba's `obj` and `ply` meshes at the points its rays hit, for every
/// `flip_tex_coords` (default: flipped for OBJ, not for PLY), with texture coordinates (OBJ
/// `vt`, PLY `u`, `v` and `s`, `t`) and without (the barycentrics), through the importer.
#[test]
fn each_meshs_uv_is_mitsubas() {
    let r = recorded();
    let meshes = r["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 12);
    for m in meshes {
        let file = m["file"].as_str().unwrap();
        let kind = file.rsplit('.').next().unwrap();
        let flip = match m["flip_tex_coords"].as_bool() {
            Some(f) => format!("<boolean name=\"flip_tex_coords\" value=\"{f}\"/>"),
            None => String::new(),
        };
        let xml = format!(
            "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/><film type=\"hdrfilm\"><integer name=\"width\" value=\"4\"/><integer name=\"height\" value=\"4\"/><rfilter type=\"box\"/></film></sensor><shape type=\"{kind}\"><string name=\"filename\" value=\"{file}\"/>{flip}<boolean name=\"face_normals\" value=\"true\"/><bsdf type=\"diffuse\"><texture type=\"checkerboard\" name=\"reflectance\"/></bsdf></shape></scene>"
        );
        let src = mitsuba::import("t.xml", &xml, fixtures()).unwrap_or_else(|e| panic!("{e}"));
        let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
        for h in m["hits"].as_array().unwrap() {
            let p = v3(&h["p"]);
            let hit = scene
                .intersect(&Ray::new(p + Vec3::Z, -Vec3::Z), 2.0)
                .expect("a hit");
            let t = scene.shapes[0].texture.as_ref().unwrap();
            let prim = &scene.prims[hit.prim as usize];
            let uv = t.uv.uv(hit.prim, prim, hit.p, hit.ng);
            let want = Vec2::new(
                h["uv"][0].as_f64().unwrap() as f32,
                h["uv"][1].as_f64().unwrap() as f32,
            );
            assert!(
                (uv - want).abs().max_element() < 1e-5,
                "{file}, flip_tex_coords {:?}, at {p}: uv {uv} against Mitsuba's {want}",
                m["flip_tex_coords"]
            );
            assert_dp_du_is_the_uv_derivative(t, &hit, prim, file);
        }
    }
}

/// A texture's one-channel value (a textured roughness) is Mitsuba's `eval_1`: the luminance
/// of the RGB lookup with Mitsuba's weights, and a checkerboard's colours swapped as Mitsuba's.
#[test]
fn one_channel_lookups_are_mitsubas() {
    let r = recorded();
    let uvs = r["uvs"].as_array().unwrap();
    for e in r["eval_1"].as_array().unwrap() {
        let t = match e.get("checkerboard") {
            Some(c) => texture_of(&format!(
                "{{ texture = \"checkerboard\", color0 = {}, color1 = {}, to_uv = {} }}",
                c["color0"], c["color1"], c["to_uv"]
            )),
            None => texture_of(&format!("{{ texture = \"bitmap\", file = {} }}", e["file"])),
        };
        for (uv, want) in uvs.iter().zip(e["values"].as_array().unwrap()) {
            let uv = Vec2::new(
                uv[0].as_f64().unwrap() as f32,
                uv[1].as_f64().unwrap() as f32,
            );
            let (got, want) = (t.eval_1(uv), want.as_f64().unwrap() as f32);
            assert!(
                (got - want).abs() <= F32_AGREEMENT,
                "{} at {uv}: {got} against Mitsuba's {want}",
                e["file"]
            );
        }
    }
}

/// A conductor whose `eta` is a 2 x 2 EXR (nearest) with texels above 1 and whose `k` is a
/// checkerboard, as a TOML scene on the quad [-1, 1]^2; `eta` is the texels' first channel.
fn textured_conductor(etas: [f32; 4], tag: &str) -> Result<Scene, String> {
    use pathspace::image_io::{write_exr, Image, ImageMeta};
    let dir = std::env::temp_dir().join(format!("pathspace-eta-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let image = Image {
        width: 2,
        height: 2,
        pixels: etas.iter().map(|&e| Vec3::new(e, 1.0, 1.0)).collect(),
    };
    write_exr(&dir.join("eta.exr"), &image, &ImageMeta::default()).unwrap();
    let text = "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 40.0\nresolution = [4, 4]\n\
         [materials.t]\ntype = \"conductor\"\n\
         eta = { texture = \"bitmap\", file = \"eta.exr\", filter_type = \"nearest\" }\n\
         k = { texture = \"checkerboard\", color0 = 3.0, color1 = 1.0 }\n\
         [[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, 0.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nmaterial = \"t\"\n\
         [[lights]]\ntype = \"point\"\nposition = [0.0, 0.0, 2.0]\nintensity = 1.0\n";
    let mut src = SceneSource::embedded("t.toml", text);
    src.base_dir = dir;
    Scene::load(&src).map_err(|e| e.to_string())
}

/// A textured `eta` and `k` (Mitsuba 3 documentation, plugin `conductor`: "spectrum or
/// texture") are the conductor's index at each point: the EXR's texels unclamped (2.5, 4 are
/// indices, not reflectances), the checkerboard's colours as `k`, and the Fresnel term of
/// that index at the point.
#[test]
fn a_textured_conductor_index_is_the_texel_at_the_point() {
    use pathspace::bsdf::{conductor::fresnel_complex, Bsdf};
    let texels = [0.2, 2.5, 4.0, 1.5];
    let scene = textured_conductor(texels, "ok").unwrap_or_else(|e| panic!("{e}"));
    let (mut etas, mut ks) = (vec![], vec![]);
    for p in [[-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5], [0.5, 0.5]] {
        let p = Vec3::new(p[0], p[1], 0.0);
        let b = scene.bsdf_at(0, p).expect("a material");
        let Bsdf::Conductor(c) = &*b else {
            panic!("{b:?} is not a conductor")
        };
        etas.push(c.eta.x);
        ks.push(c.k.x);
        let want = fresnel_complex(1.0, c.eta.x, c.k.x);
        assert_eq!(b.albedo(1.0).x, want, "Fresnel at {p}");
    }
    etas.sort_by(f32::total_cmp);
    ks.sort_by(f32::total_cmp);
    assert_eq!(etas, [0.2, 1.5, 2.5, 4.0], "eta at the four texels");
    assert_eq!(ks, [1.0, 1.0, 3.0, 3.0], "k at the four checks");
}

/// A negative or non-finite index texel is refused at its file, line and key.
#[test]
fn a_negative_or_non_finite_index_texel_is_refused() {
    for (bad, tag) in [(-0.5, "neg"), (f32::INFINITY, "inf")] {
        let Err(e) = textured_conductor([0.2, bad, 4.0, 1.5], tag) else {
            panic!("a bad texel {bad} was accepted")
        };
        assert!(
            e.contains("t.toml:") && e.contains("materials.t.eta.file") && e.contains("eta.exr"),
            "{e}"
        );
        assert!(e.contains("an index must be finite and >= 0"), "{e}");
    }
}
