//! The Mitsuba 3 importer (`scene::mitsuba`): each convention of Mitsuba's on a small scene
//! whose XML and hand-written TOML twin (written from Mitsuba's documented convention) must be
//! the same scene file and render the same image bit for bit; the shipped fog box in XML
//! against `scenes/fog-box.toml` within error; and every refusal names the plugin, the file and
//! the line.

use crate::common;

use common::stats::Family;
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::scene::file::{self, SceneFile};
use pathspace::scene::{mitsuba, Scene, SceneSource};
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn xml(text: &str) -> Result<SceneSource, String> {
    mitsuba::import("t.xml", text, dir()).map_err(|e| e.to_string())
}

fn toml(text: &str) -> SceneSource {
    SceneSource::embedded("t.toml", text)
}

fn desc(src: &SceneSource) -> SceneFile {
    file::parse(&src.text, &src.name).unwrap_or_else(|e| panic!("{e}\n{}", src.text))
}

/// Every pixel of a 4-spp path-traced image.
fn pixels(src: &SceneSource) -> Vec<[f32; 3]> {
    let scene = Scene::load(src).unwrap_or_else(|e| panic!("{e}"));
    let mut r = Renderer::new(&scene, IntegratorKind::Path, 7, None);
    r.pass(4, &|| {});
    let img = r.film.as_ref().unwrap().image();
    img.pixels.iter().map(|p| p.to_array()).collect()
}

/// The XML and the TOML are one scene file, and render one image bit for bit.
fn same_scene(xml_text: &str, toml_text: &str) {
    let (a, b) = (xml(xml_text).unwrap(), toml(toml_text));
    assert_eq!(desc(&a), desc(&b), "generated:\n{}", a.text);
    assert_eq!(pixels(&a), pixels(&b));
}

/// A sensor at the origin looking down -z through a 16x16 box-filtered film.
const SENSOR: &str = r#"<integrator type="volpath"/>
    <sensor type="perspective">
        <float name="fov" value="60"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/><rfilter type="box"/></film>
    </sensor>"#;

/// The TOML twin of `SENSOR` (Mitsuba's default sampler: 4 spp, seed 0).
const CAMERA: &str = r#"[render]
integrator = "path"
spp = 4
seed = 0
[camera]
type = "pinhole"
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 3.0]
up = [0.0, 1.0, 0.0]
fov_deg = 60.0
resolution = [16, 16]
"#;

fn scene(body: &str) -> String {
    format!("<scene version=\"3.0.0\">\n{SENSOR}\n{body}\n</scene>")
}

/// `rectangle` is [-1,1]^2 at z = 0 with normal +z (its area light emits along +z);
/// `diffuse` is one-sided, `twosided` makes it two-sided; a shape without a BSDF is a
/// one-sided diffuse of reflectance 0.5, an emitter without one is black.
#[test]
fn rectangle_extent_normal_and_sides_are_mitsubas() {
    same_scene(
        &scene(
            r#"<bsdf type="twosided" id="grey"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.3, 0.4"/></bsdf></bsdf>
    <bsdf type="diffuse" id="front"/>
    <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter></shape>
    <shape type="rectangle">
        <transform name="to_world"><scale x="2" y="3"/><translate z="-1"/></transform>
        <ref id="grey"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><translate z="-2"/></transform>
        <ref id="front"/>
    </shape>
    <shape type="rectangle">
        <boolean name="flip_normals" value="true"/>
        <transform name="to_world"><translate z="-3"/></transform>
    </shape>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.grey]
type = "lambert"
albedo = [0.2, 0.3, 0.4]
[materials.front]
type = "lambert"
albedo = 0.5
one_sided = true
[materials."default diffuse"]
type = "lambert"
albedo = 0.5
one_sided = true
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, 0.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
emission = [2.0, 3.0, 4.0]
[[shapes]]
type = "quad"
origin = [-2.0, -3.0, -1.0]
u = [4.0, 0.0, 0.0]
v = [0.0, 6.0, 0.0]
material = "grey"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "front"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -3.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
flip_normals = true
material = "default diffuse"
"#
        ),
    );
}

/// `disk` is the unit disk at z = 0 with normal +z, an ellipse under a scale, its normal
/// reversed by `flip_normals` (its axes, and so its uv, unchanged).
#[test]
fn disk_extent_and_normal_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="disk"><emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter>
        <transform name="to_world"><scale x="0.5" y="0.25"/><translate y="1"/></transform>
    </shape>
    <shape type="disk">
        <boolean name="flip_normals" value="true"/>
        <transform name="to_world"><scale x="2" y="1.5"/><translate z="-1"/></transform>
        <bsdf type="diffuse" id="diffuse"/>
    </shape>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.diffuse]
type = "lambert"
albedo = 0.5
one_sided = true
[[shapes]]
type = "disk"
center = [0.0, 1.0, 0.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.25, 0.0]
emission = [2.0, 3.0, 4.0]
[[shapes]]
type = "disk"
center = [0.0, 0.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 1.5, 0.0]
flip_normals = true
material = "diffuse"
"#
        ),
    );
}

/// `cylinder`: p0 (0,0,0) to p1 (0,0,1), radius 1, open, under `to_world` (a uniform scale
/// across the axis, another along it); `flip_normals` turns the normals (and the area light's
/// side) inwards; `x_axis`, where its phi starts, is the image of Mitsuba's frame about the axis.
#[test]
fn cylinder_extent_and_normal_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="cylinder">
        <point name="p0" x="0" y="-1" z="-1"/><point name="p1" x="0" y="1" z="-1"/>
        <float name="radius" value="0.5"/>
        <emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter>
    </shape>
    <shape type="cylinder">
        <boolean name="flip_normals" value="true"/>
        <transform name="to_world"><scale x="2" y="2" z="3"/><translate z="-3"/></transform>
        <bsdf type="diffuse" id="diffuse"/>
    </shape>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.diffuse]
type = "lambert"
albedo = 0.5
one_sided = true
[[shapes]]
type = "cylinder"
p0 = [0.0, -1.0, -1.0]
p1 = [0.0, 1.0, -1.0]
radius = 0.5
x_axis = [1.0, 0.0, 0.0]
emission = [2.0, 3.0, 4.0]
[[shapes]]
type = "cylinder"
p0 = [0.0, 0.0, -3.0]
p1 = [0.0, 0.0, 0.0]
radius = 2.0
flip_normals = true
x_axis = [1.0, 0.0, 0.0]
material = "diffuse"
"#
        ),
    );
}

/// `conductor` and `roughconductor`: a named `material` (Mitsuba's spectra as its RGB variants
/// see them), or `eta` (default 0) and `k` (default 1), none at all a Fresnel term of 1;
/// `specular_reflectance` scales the term; one-sided unless in a `twosided`.
#[test]
fn conductor_materials_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="sphere"><bsdf type="conductor" id="gold"><string name="material" value="Au"/></bsdf></shape>
    <shape type="rectangle">
        <bsdf type="roughconductor" id="copper">
            <string name="material" value="Cu"/><string name="distribution" value="ggx"/>
            <float name="alpha" value="0.3"/><rgb name="specular_reflectance" value="0.9, 0.8, 0.7"/>
        </bsdf>
        <transform name="to_world"><scale x="3" y="3"/><translate z="-2"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="twosided" id="tinted"><bsdf type="conductor">
            <rgb name="eta" value="0.2, 0.9, 1.1"/><float name="specular_reflectance" value="0.5"/>
        </bsdf></bsdf>
        <transform name="to_world"><translate x="1.5" z="-1"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="conductor" id="plain"/>
        <transform name="to_world"><translate x="-1.5" z="-1"/></transform>
    </shape>
    <emitter type="constant"><float name="radiance" value="0.5"/></emitter>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.gold]
type = "conductor"
material = "Au"
one_sided = true
[materials.copper]
type = "rough_conductor"
alpha = 0.3
material = "Cu"
specular = [0.9, 0.8, 0.7]
one_sided = true
[materials.tinted]
type = "conductor"
eta = [0.2, 0.9, 1.1]
k = 1.0
specular = 0.5
[materials.plain]
type = "conductor"
one_sided = true
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "gold"
[[shapes]]
type = "quad"
origin = [-3.0, -3.0, -2.0]
u = [6.0, 0.0, 0.0]
v = [0.0, 6.0, 0.0]
material = "copper"
[[shapes]]
type = "quad"
origin = [0.5, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "tinted"
[[shapes]]
type = "quad"
origin = [-2.5, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "plain"
[[lights]]
type = "environment"
radiance = 0.5
"#
        ),
    );
}

/// `diffuse` with a `bitmap` and a `checkerboard` `reflectance`: every parameter with its
/// Mitsuba name and default, `to_uv` from a 4x4 transform without its z row and column; a
/// missing file and an unknown wrap mode are refused with their line.
#[test]
fn textures_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="rectangle">
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance">
                <string name="filename" value="tests/fixtures/textures/rgb4x3.png"/>
                <string name="filter_type" value="nearest"/>
                <string name="wrap_mode" value="mirror"/>
                <boolean name="raw" value="true"/>
                <transform name="to_uv"><scale x="2" y="3"/><translate x="0.25" y="-0.5" z="7"/></transform>
            </texture>
        </bsdf>
    </shape>
    <shape type="sphere">
        <float name="radius" value="0.3"/>
        <bsdf type="twosided"><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf></bsdf>
    </shape>
    <shape type="disk"><transform name="to_world"><translate z="1"/></transform><emitter type="area"/></shape>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials."bsdf@9"]
type = "lambert"
albedo = {{ texture = "bitmap", file = "tests/fixtures/textures/rgb4x3.png", filter_type = "nearest", wrap_mode = "mirror", raw = true, to_uv = [[2.0, 0.0, 0.25], [0.0, 3.0, -0.5]] }}
one_sided = true
[materials."bsdf@21"]
type = "lambert"
albedo = {{ texture = "checkerboard", color0 = 0.4, color1 = 0.2 }}
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, 0.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "bsdf@9"
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 0.3
material = "bsdf@21"
[[shapes]]
type = "disk"
center = [0.0, 0.0, 1.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
emission = 1.0
"#
        ),
    );
    let refused = |body: &str, line: &str| {
        let e =
            xml(&scene(body)).and_then(|s| Scene::load(&s).map(|_| ()).map_err(|e| e.to_string()));
        let e = e.expect_err(body);
        assert!(e.contains(line), "{e}");
    };
    refused(
        r#"<shape type="rectangle"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="missing.png"/></texture></bsdf></shape>"#,
        "missing.png",
    );
    refused(
        r#"<shape type="rectangle"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="x.png"/><string name="wrap_mode" value="border"/></texture></bsdf></shape>"#,
        "t.xml:8",
    );
}

/// Textures on the shapes whose uv needs more than their surface, with their Mitsuba uv: a
/// flipped `rectangle` and `disk` keep their axes (`flip_normals` turns the normal only), a
/// `sphere` rotated by `to_world` keeps the rotated axes (`x_axis`, `z_axis`), a `cylinder`
/// the image of Mitsuba's frame about its axis (`x_axis`).
#[test]
fn textured_flipped_rotated_and_cylinder_shapes_are_mitsubas() {
    let checker = r#"<bsdf type="diffuse" id="check"><texture type="checkerboard" name="reflectance"><transform name="to_uv"><scale x="4" y="3"/></transform></texture></bsdf>"#;
    same_scene(
        &scene(&format!(
            r#"{checker}
    <shape type="rectangle"><boolean name="flip_normals" value="true"/><ref id="check"/>
        <transform name="to_world"><scale x="2" y="0.5"/><translate z="-2"/></transform>
    </shape>
    <shape type="disk"><boolean name="flip_normals" value="true"/><ref id="check"/>
        <transform name="to_world"><scale value="0.5"/><translate x="1" z="-1"/></transform>
    </shape>
    <shape type="sphere"><float name="radius" value="0.4"/><ref id="check"/>
        <transform name="to_world"><matrix value="0 1 0 -0.8  0 0 1 0  1 0 0 -1  0 0 0 1"/></transform>
    </shape>
    <shape type="cylinder"><float name="radius" value="0.3"/><ref id="check"/>
        <transform name="to_world"><matrix value="0 1 0 0.5  0 0 1 -0.5  1 0 0 -1.5  0 0 0 1"/></transform>
    </shape>
    <emitter type="constant"/>"#
        )),
        &format!(
            r#"{CAMERA}
[materials.check]
type = "lambert"
albedo = {{ texture = "checkerboard", color0 = 0.4, color1 = 0.2, to_uv = [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0]] }}
one_sided = true
[[shapes]]
type = "quad"
origin = [-2.0, -0.5, -2.0]
u = [4.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
flip_normals = true
material = "check"
[[shapes]]
type = "disk"
center = [1.0, 0.0, -1.0]
u = [0.5, 0.0, 0.0]
v = [0.0, 0.5, 0.0]
flip_normals = true
material = "check"
[[shapes]]
type = "sphere"
center = [-0.8, 0.0, -1.0]
radius = 0.4
x_axis = [0.0, 0.0, 1.0]
z_axis = [0.0, 1.0, 0.0]
material = "check"
[[shapes]]
type = "cylinder"
p0 = [0.5, -0.5, -1.5]
p1 = [0.5, 0.5, -1.5]
radius = 0.3
x_axis = [0.0, 0.0, 1.0]
material = "check"
[[lights]]
type = "environment"
radiance = 1.0
"#
        ),
    );
}

/// Textures beyond `diffuse`: a `plastic`'s and a `roughplastic`'s `diffuse_reflectance`, a
/// `roughconductor`'s and a `roughdielectric`'s `alpha` (read as one channel), and meshes with
/// texture coordinates: an OBJ's `vt` (v flipped by default, as Mitsuba's `obj`) and a PLY's
/// `u`, `v` (`flip_tex_coords` given), each becoming the same TOML keys. A texture as a
/// `roughplastic`'s `alpha` (a number in Mitsuba) is refused with its line.
#[test]
fn textured_bsdfs_and_meshes_are_mitsubas() {
    let png = "tests/fixtures/textures/rgb4x3.png";
    let checker = r#"<texture type="checkerboard" name="NAME"><float name="color0" value="0.3"/><float name="color1" value="0.05"/></texture>"#;
    let c = |name: &str| checker.replace("NAME", name);
    same_scene(
        &scene(&format!(
            r#"<shape type="rectangle">
        <bsdf type="plastic" id="coat">{}</bsdf>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="roughplastic" id="rcoat"><texture type="bitmap" name="diffuse_reflectance"><string name="filename" value="{png}"/></texture></bsdf>
        <transform name="to_world"><scale value="0.5"/><translate x="0.5" z="-1"/></transform>
    </shape>
    <shape type="sphere">
        <point name="center" x="-0.6" y="0" z="0"/><float name="radius" value="0.4"/>
        <bsdf type="roughdielectric" id="frosted"><texture type="bitmap" name="alpha"><string name="filename" value="{png}"/><boolean name="raw" value="true"/></texture></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="-0.6" z="0"/><float name="radius" value="0.3"/>
        <bsdf type="roughconductor" id="metal">{}</bsdf>
    </shape>
    <shape type="obj">
        <string name="filename" value="tests/fixtures/textures/mesh-vt.obj"/>
        <transform name="to_world"><translate x="-1" y="0.2"/></transform>
        <bsdf type="diffuse" id="wood"><texture type="bitmap" name="reflectance"><string name="filename" value="{png}"/></texture></bsdf>
    </shape>
    <shape type="ply">
        <string name="filename" value="tests/fixtures/textures/mesh-uv.ply"/>
        <boolean name="flip_tex_coords" value="true"/>
        <boolean name="face_normals" value="true"/>
        <transform name="to_world"><translate x="-1" y="-1"/></transform>
        <ref id="wood"/>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.25"/></emitter>"#,
            c("diffuse_reflectance"),
            c("alpha"),
        )),
        &format!(
            r#"{CAMERA}
[materials.coat]
type = "plastic"
diffuse = {{ texture = "checkerboard", color0 = 0.3, color1 = 0.05 }}
specular = 1.0
ior = {:?}
one_sided = true
[materials.rcoat]
type = "rough_plastic"
diffuse = {{ texture = "bitmap", file = "{png}" }}
one_sided = true
[materials.frosted]
type = "rough_dielectric"
distribution = "beckmann"
alpha = {{ texture = "bitmap", file = "{png}", raw = true }}
ior = {:?}
[materials.metal]
type = "rough_conductor"
distribution = "beckmann"
alpha = {{ texture = "checkerboard", color0 = 0.3, color1 = 0.05 }}
one_sided = true
[materials.wood]
type = "lambert"
albedo = {{ texture = "bitmap", file = "{png}" }}
one_sided = true
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "coat"
[[shapes]]
type = "quad"
origin = [0.0, -0.5, -1.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
material = "rcoat"
[[shapes]]
type = "sphere"
center = [-0.6, 0.0, 0.0]
radius = 0.4
material = "frosted"
[[shapes]]
type = "sphere"
center = [0.0, -0.6, 0.0]
radius = 0.3
material = "metal"
[[shapes]]
type = "mesh"
obj = "tests/fixtures/textures/mesh-vt.obj"
to_world = [[1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, 0.2], [0.0, 0.0, 1.0, 0.0]]
smooth_normals = true
material = "wood"
[[shapes]]
type = "mesh"
obj = "tests/fixtures/textures/mesh-uv.ply"
to_world = [[1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, -1.0], [0.0, 0.0, 1.0, 0.0]]
flip_tex_coords = true
material = "wood"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.25
"#,
            (1.49f64 / 1.000277) as f32,
            (1.5046f64 / 1.000277) as f32,
        ),
    );
    let e = xml(&scene(&format!(
        r#"<shape type="rectangle"><bsdf type="roughplastic">{}</bsdf></shape>"#,
        c("alpha")
    )))
    .expect_err("a textured roughplastic alpha");
    assert!(
        e.starts_with(&format!("t.xml:{}:", SENSOR.lines().count() + 2)) && e.contains("alpha"),
        "{e}"
    );
}

/// Textures as a conductor's `eta` and a rough conductor's `k` (Mitsuba 3 reads both as
/// unbounded textures) are the TOML's textured index, the other part at Mitsuba's default
/// (eta 0, k 1); the EXR's texels are taken as they are (linear).
#[test]
fn textured_conductor_index_is_mitsubas() {
    let exr = "tests/fixtures/textures/rgb4x3.exr";
    same_scene(
        &scene(&format!(
            r#"<shape type="rectangle">
        <bsdf type="conductor" id="gilt"><texture type="bitmap" name="eta"><string name="filename" value="{exr}"/><string name="filter_type" value="nearest"/></texture><rgb name="k" value="3, 2.5, 2"/></bsdf>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="-0.4" z="0"/><float name="radius" value="0.5"/>
        <bsdf type="roughconductor" id="metal"><float name="alpha" value="0.2"/><texture type="checkerboard" name="k"><rgb name="color0" value="0.9, 0.5, 0.2"/><float name="color1" value="0.1"/></texture></bsdf>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.25"/></emitter>"#
        )),
        &format!(
            r#"{CAMERA}
[materials.gilt]
type = "conductor"
eta = {{ texture = "bitmap", file = "{exr}", filter_type = "nearest" }}
k = [3.0, 2.5, 2.0]
one_sided = true
[materials.metal]
type = "rough_conductor"
distribution = "beckmann"
alpha = 0.2
eta = 0.0
k = {{ texture = "checkerboard", color0 = [0.9, 0.5, 0.2], color1 = 0.1 }}
one_sided = true
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "gilt"
[[shapes]]
type = "sphere"
center = [0.0, -0.4, 0.0]
radius = 0.5
material = "metal"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.25
"#
        ),
    );
}

/// An `area` emitter's `radiance` as a texture (Mitsuba 3 documentation, plugin `area`) is the
/// TOML's textured `emission`: a checkerboard (a `<float>` colour above 1, as Mitsuba reads it
/// in an emitter) on a rectangle and an EXR bitmap on a sphere, lighting a diffuse wall and
/// seen directly. A texture Mitsuba has and pathspace has not is refused at its line.
#[test]
fn textured_area_radiance_is_mitsubas() {
    let exr = "tests/fixtures/textures/rgb4x3.exr";
    same_scene(
        &scene(&format!(
            r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5"/><translate x="-0.5" z="-1"/></transform>
        <emitter type="area"><texture type="checkerboard" name="radiance"><float name="color0" value="5"/><rgb name="color1" value="0.2, 0.5, 0.9"/><transform name="to_uv"><scale x="3" y="2"/></transform></texture></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.6" y="-0.3" z="0"/><float name="radius" value="0.3"/>
        <emitter type="area"><texture type="bitmap" name="radiance"><string name="filename" value="{exr}"/><string name="filter_type" value="nearest"/></texture></emitter>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="2"/><translate z="-2"/></transform>
    </shape>"#
        )),
        &format!(
            r#"{CAMERA}
[materials."default diffuse"]
type = "lambert"
albedo = 0.5
one_sided = true
[[shapes]]
type = "quad"
origin = [-1.0, -0.5, -1.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
emission = {{ texture = "checkerboard", color0 = 5.0, color1 = [0.2, 0.5, 0.9], to_uv = [[3.0, 0.0, 0.0], [0.0, 2.0, 0.0]] }}
[[shapes]]
type = "sphere"
center = [0.6, -0.3, 0.0]
radius = 0.3
emission = {{ texture = "bitmap", file = "{exr}", filter_type = "nearest" }}
[[shapes]]
type = "quad"
origin = [-2.0, -2.0, -2.0]
u = [4.0, 0.0, 0.0]
v = [0.0, 4.0, 0.0]
material = "default diffuse"
"#
        ),
    );
    let e = xml(&scene(
        r#"<shape type="rectangle"><emitter type="area"><texture type="volume" name="radiance"/></emitter></shape>"#,
    ))
    .expect_err("a volume texture as radiance");
    assert!(
        e.starts_with(&format!("t.xml:{}:", SENSOR.lines().count() + 2)) && e.contains("volume"),
        "{e}"
    );
    // Mitsuba 3 refuses a checkerboard's <rgb> above 1 even in an emitter
    let e = xml(&scene(
        r#"<shape type="rectangle"><emitter type="area"><texture type="checkerboard" name="radiance">
        <rgb name="color0" value="5, 2, 1"/></texture></emitter></shape>"#,
    ))
    .expect_err("an <rgb> above 1 in a checkerboard");
    assert!(
        e.starts_with(&format!("t.xml:{}:", SENSOR.lines().count() + 3)) && e.contains("[0, 1]"),
        "{e}"
    );
}

/// A texture as a conductor's or rough conductor's `specular_reflectance` is the TOML
/// `specular` texture (Mitsuba 3 documentation, plugins `conductor`, `roughconductor`: it scales
/// the Fresnel term at each point), and likewise a plastic's and rough plastic's.
#[test]
fn textured_specular_reflectance_is_mitsubas() {
    let png = "tests/fixtures/textures/rgb4x3.png";
    same_scene(
        &scene(&format!(
            r#"<shape type="rectangle">
        <bsdf type="conductor" id="gilt"><string name="material" value="Au"/><texture type="bitmap" name="specular_reflectance"><string name="filename" value="{png}"/></texture></bsdf>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="-0.4" z="0"/><float name="radius" value="0.5"/>
        <bsdf type="roughconductor" id="metal"><float name="alpha" value="0.2"/><texture type="checkerboard" name="specular_reflectance"><rgb name="color0" value="0.9, 0.5, 0.2"/><float name="color1" value="0.3"/></texture></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="-0.6" y="0.4" z="0"/><float name="radius" value="0.3"/>
        <bsdf type="plastic" id="coat"><texture type="checkerboard" name="specular_reflectance"><float name="color0" value="0.8"/><float name="color1" value="0.1"/></texture></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.6" y="0.4" z="0"/><float name="radius" value="0.3"/>
        <bsdf type="roughplastic" id="rcoat"><texture type="bitmap" name="specular_reflectance"><string name="filename" value="{png}"/></texture><texture type="checkerboard" name="diffuse_reflectance"/></bsdf>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.25"/></emitter>"#
        )),
        &format!(
            r#"{CAMERA}
[materials.gilt]
type = "conductor"
material = "Au"
specular = {{ texture = "bitmap", file = "{png}" }}
one_sided = true
[materials.metal]
type = "rough_conductor"
distribution = "beckmann"
alpha = 0.2
specular = {{ texture = "checkerboard", color0 = [0.9, 0.5, 0.2], color1 = 0.3 }}
one_sided = true
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "gilt"
[materials.coat]
type = "plastic"
specular = {{ texture = "checkerboard", color0 = 0.8, color1 = 0.1 }}
ior = {:?}
one_sided = true
[materials.rcoat]
type = "rough_plastic"
diffuse = {{ texture = "checkerboard" }}
specular = {{ texture = "bitmap", file = "{png}" }}
one_sided = true
[[shapes]]
type = "sphere"
center = [0.0, -0.4, 0.0]
radius = 0.5
material = "metal"
[[shapes]]
type = "sphere"
center = [-0.6, 0.4, 0.0]
radius = 0.3
material = "coat"
[[shapes]]
type = "sphere"
center = [0.6, 0.4, 0.0]
radius = 0.3
material = "rcoat"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.25
"#,
            (1.49f64 / 1.000277) as f32,
        ),
    );
}

/// A dielectric's `specular_reflectance` and `specular_transmittance` (Mitsuba 3
/// documentation, plugins `dielectric`, `roughdielectric`, `thindielectric`: a colour or a
/// texture scaling reflection and transmission) are the TOML keys of the same names.
#[test]
fn tinted_dielectrics_are_mitsubas() {
    let png = "tests/fixtures/textures/rgb4x3.png";
    same_scene(
        &scene(&format!(
            r#"<shape type="sphere">
        <point name="center" x="-0.5" y="0" z="0"/><float name="radius" value="0.5"/>
        <bsdf type="dielectric" id="tinted"><rgb name="specular_reflectance" value="0.5, 0.8, 1"/><texture type="checkerboard" name="specular_transmittance"><rgb name="color0" value="1, 0.5, 0.1"/><rgb name="color1" value="0.1, 0.5, 1"/></texture></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.6" y="0" z="0"/><float name="radius" value="0.4"/>
        <bsdf type="roughdielectric" id="frosted"><float name="alpha" value="0.3"/><texture type="bitmap" name="specular_reflectance"><string name="filename" value="{png}"/></texture><float name="specular_transmittance" value="0.7"/></bsdf>
    </shape>
    <shape type="rectangle">
        <bsdf type="thindielectric" id="pane"><rgb name="specular_reflectance" value="0.2, 0.5, 1"/><rgb name="specular_transmittance" value="1, 0.5, 0.2"/></bsdf>
        <transform name="to_world"><translate z="-1"/></transform>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.5"/></emitter>"#
        )),
        &format!(
            r#"{CAMERA}
[materials.tinted]
type = "dielectric"
ior = {:?}
specular_reflectance = [0.5, 0.8, 1.0]
specular_transmittance = {{ texture = "checkerboard", color0 = [1.0, 0.5, 0.1], color1 = [0.1, 0.5, 1.0] }}
[materials.frosted]
type = "rough_dielectric"
distribution = "beckmann"
ior = {:?}
alpha = 0.3
specular_reflectance = {{ texture = "bitmap", file = "{png}" }}
specular_transmittance = 0.7
[materials.pane]
type = "thin_dielectric"
ior = {:?}
specular_reflectance = [0.2, 0.5, 1.0]
specular_transmittance = [1.0, 0.5, 0.2]
[[shapes]]
type = "sphere"
center = [-0.5, 0.0, 0.0]
radius = 0.5
material = "tinted"
[[shapes]]
type = "sphere"
center = [0.6, 0.0, 0.0]
radius = 0.4
material = "frosted"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "pane"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.5
"#,
            (1.5046f64 / 1.000277) as f32,
            (1.5046f64 / 1.000277) as f32,
            (1.5046f64 / 1.000277) as f32,
        ),
    );
}

/// `thindielectric`: `int_ior` over `ext_ior` (numbers or Mitsuba's names), reflected or passed
/// unbent, two-sided.
#[test]
fn thin_dielectric_is_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="thindielectric" id="pane"><string name="int_ior" value="water"/><float name="ext_ior" value="1.0"/></bsdf>
        <transform name="to_world"><scale x="0.5"/><translate z="-1"/></transform>
    </shape>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.pane]
type = "thin_dielectric"
ior = 1.333
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
emission = [2.0, 3.0, 4.0]
[[shapes]]
type = "quad"
origin = [-0.5, -1.0, -1.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "pane"
"#
        ),
    );
}

/// `cube` is [-1,1]^3; a homogeneous medium's `sigma_t` and `albedo` (times `scale`) are
/// sigma_s = sigma_t albedo and sigma_a = sigma_t (1 - albedo); `hg`'s g keeps its sign
/// (forward for g > 0 in both); a black emitter is an emitter without a material.
#[test]
fn cube_extent_and_medium_coefficients_are_mitsubas() {
    same_scene(
        &scene(
            r#"<medium type="homogeneous" id="fog">
        <rgb name="sigma_t" value="1, 2, 4"/><float name="albedo" value="0.75"/><float name="scale" value="0.5"/>
        <phase type="hg"><float name="g" value="0.3"/></phase>
    </medium>
    <shape type="cube">
        <transform name="to_world"><scale x="0.5" y="1" z="2"/><translate x="1"/></transform>
        <bsdf type="null"/>
        <ref name="interior" id="fog"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="1" z="0"/><float name="radius" value="0.5"/>
        <transform name="to_world"><scale value="2"/><translate x="-2"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0, 0, 0"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter>
    </shape>"#,
        ),
        &format!(
            r#"{CAMERA}
[media.fog]
type = "homogeneous"
sigma_a = [0.125, 0.25, 0.5]
sigma_s = [0.375, 0.75, 1.5]
phase = {{ type = "hg", g = 0.3 }}
[[shapes]]
type = "box"
min = [0.5, -1.0, -2.0]
max = [1.5, 1.0, 2.0]
material = "null"
interior = "fog"
[[shapes]]
type = "sphere"
center = [-2.0, 2.0, 0.0]
radius = 1.0
emission = 5.0
"#
        ),
    );
}

/// `lookat` builds Mitsuba's frame (image right = direction x up), `fov` spans the width by
/// default (`fov_axis` x), `max_depth` counts segments (pathspace counts scattering vertices),
/// the sampler's count and seed are the render's.
#[test]
fn sensor_fov_axis_lookat_and_depth_are_mitsubas() {
    let body = |axis: &str| {
        format!(
            r#"<scene version="3.0.0">
    <integrator type="volpath"><integer name="max_depth" value="5"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="50"/>{axis}
        <transform name="to_world"><lookat origin="1, 2, 3" target="0, 0.5, 0" up="0, 0, 1"/></transform>
        <sampler type="independent"><integer name="sample_count" value="8"/><integer name="seed" value="3"/></sampler>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="12"/><rfilter type="box"/></film>
    </sensor>
    <shape type="rectangle"><emitter type="area"/></shape>
</scene>"#
        )
    };
    let camera = |fov_deg: f32| {
        let d = glam::DVec3::new(-1.0, -1.5, -3.0).normalize();
        let t = glam::DVec3::new(1.0, 2.0, 3.0) + d;
        let up = d.cross(glam::DVec3::Z.cross(d).normalize());
        format!(
            r#"[render]
integrator = "path"
spp = 8
seed = 3
max_depth = 4
[camera]
type = "pinhole"
eye = [1.0, 2.0, 3.0]
look_at = [{}, {}, {}]
up = [{}, {}, {}]
fov_deg = {fov_deg:?}
resolution = [24, 12]
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, 0.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
emission = 1.0
"#,
            t.x as f32, t.y as f32, t.z as f32, up.x as f32, up.y as f32, up.z as f32
        )
    };
    let half = 25f64.to_radians().tan();
    let across_x = (2.0 * (half * 12.0 / 24.0).atan()).to_degrees() as f32;
    same_scene(&body(""), &camera(across_x));
    let axis_y = r#"<string name="fov_axis" value="y"/>"#;
    same_scene(&body(axis_y), &camera(50.0));
}

/// Mitsuba's dielectric `int_ior` / `ext_ior` (names from its table) make pathspace's ratio;
/// a GGX rough conductor keeps alpha, eta and k; point, spot (hard cone), directional and
/// constant emitters keep Mitsuba's units and directions (local +z through `to_world`).
#[test]
fn bsdf_and_emitter_parameters_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="sphere">
        <bsdf type="dielectric" id="water"><string name="int_ior" value="water"/><string name="ext_ior" value="air"/></bsdf>
    </shape>
    <shape type="rectangle">
        <bsdf type="roughconductor" id="metal">
            <string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>
            <rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.4, 2.1"/>
        </bsdf>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="0"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="spot">
        <transform name="to_world"><lookat origin="0, 3, 0" target="0, 0, 0" up="1, 0, 0"/></transform>
        <float name="intensity" value="7"/><float name="cutoff_angle" value="30"/><float name="beam_width" value="30"/>
    </emitter>
    <emitter type="directional"><vector name="direction" x="0" y="-1" z="-1"/><float name="irradiance" value="2"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.25"/></emitter>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.water]
type = "dielectric"
ior = {:?}
[materials.metal]
type = "rough_conductor"
alpha = 0.2
eta = [0.2, 0.9, 1.1]
k = [3.9, 2.4, 2.1]
one_sided = true
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "water"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "metal"
[[lights]]
type = "point"
position = [0.0, 2.0, 0.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "spot"
position = [0.0, 3.0, 0.0]
direction = [0.0, -1.0, 0.0]
intensity = 7.0
cone_deg = 30.0
falloff_deg = 0.0
[[lights]]
type = "directional"
direction = [0.0, -1.0, -1.0]
irradiance = 2.0
[[lights]]
type = "environment"
radiance = 0.25
"#,
            (1.3330f64 / 1.000277) as f32
        ),
    );
}

/// `plastic`: Mitsuba's defaults (diffuse 0.5, specular 1, int_ior "polypropylene" over
/// ext_ior "air", linear, one-sided), named and numeric indices, `nonlinear`, and `twosided`.
#[test]
fn plastic_parameters_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="sphere"><bsdf type="plastic"/></shape>
    <shape type="rectangle">
        <bsdf type="twosided" id="coated"><bsdf type="plastic">
            <rgb name="diffuse_reflectance" value="0.1, 0.4, 0.8"/><rgb name="specular_reflectance" value="1, 0.9, 0.7"/>
            <string name="int_ior" value="water"/><float name="ext_ior" value="1.1"/><boolean name="nonlinear" value="true"/>
        </bsdf></bsdf>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><float name="intensity" value="5"/></emitter>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials."bsdf@8"]
type = "plastic"
diffuse = 0.5
specular = 1.0
ior = {:?}
one_sided = true
[materials.coated]
type = "plastic"
diffuse = [0.1, 0.4, 0.8]
specular = [1.0, 0.9, 0.7]
ior = {:?}
nonlinear = true
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "bsdf@8"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "coated"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = 5.0
"#,
            (1.49f64 / 1.000277) as f32,
            (1.3330f64 / 1.1) as f32
        ),
    );
}

/// `roughplastic` with Mitsuba's defaults (Beckmann alpha 0.1, polypropylene over air,
/// diffuse 0.5, one-sided) and with every parameter inside a `twosided` (a panel turned away
/// from the camera: its back is seen); `roughdielectric` and `roughconductor` default to
/// Beckmann too.
#[test]
fn rough_plastic_and_beckmann_are_mitsubas() {
    same_scene(
        &scene(
            r#"<shape type="rectangle">
        <bsdf type="roughplastic" id="plain"/>
        <transform name="to_world"><translate z="-2"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="twosided" id="tinted">
            <bsdf type="roughplastic">
                <string name="distribution" value="GGX"/><float name="alpha" value="0.3"/>
                <float name="int_ior" value="1.6"/><string name="ext_ior" value="water"/>
                <rgb name="diffuse_reflectance" value="0.8, 0.4, 0.1"/>
                <rgb name="specular_reflectance" value="0.7, 0.7, 0.7"/>
                <boolean name="nonlinear" value="true"/>
            </bsdf>
        </bsdf>
        <transform name="to_world"><scale value="0.5"/><rotate y="1" angle="180"/><translate x="0.5"/></transform>
    </shape>
    <shape type="sphere">
        <point name="center" x="-0.6" y="0" z="0"/><float name="radius" value="0.4"/>
        <bsdf type="roughdielectric" id="frosted"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="-0.6" z="0"/><float name="radius" value="0.3"/>
        <bsdf type="roughconductor" id="metal"><float name="alpha" value="0.4"/></bsdf>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.25"/></emitter>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials.plain]
type = "rough_plastic"
one_sided = true
[materials.tinted]
type = "rough_plastic"
distribution = "ggx"
alpha = 0.3
ior = {:?}
diffuse = [0.8, 0.4, 0.1]
specular = 0.7
nonlinear = true
[materials.frosted]
type = "rough_dielectric"
distribution = "beckmann"
alpha = 0.1
ior = {:?}
[materials.metal]
type = "rough_conductor"
distribution = "beckmann"
alpha = 0.4
one_sided = true
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -2.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "plain"
[[shapes]]
type = "quad"
origin = [1.0, -0.5, 0.0]
u = [-1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
material = "tinted"
[[shapes]]
type = "sphere"
center = [-0.6, 0.0, 0.0]
radius = 0.4
material = "frosted"
[[shapes]]
type = "sphere"
center = [0.0, -0.6, 0.0]
radius = 0.3
material = "metal"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.25
"#,
            (1.6f64 / 1.3330) as f32,
            (1.5046f64 / 1.000277) as f32,
        ),
    );
}

/// `envmap`: the file relative to the XML, `scale`, and `to_world` as the map light's
/// rotation (the mapping itself is Mitsuba's, pinned texel by texel in `tests/spec/scene/envmap.rs`); a
/// translation is refused.
#[test]
fn envmap_is_the_map_light_turned_by_to_world() {
    same_scene(
        &scene(
            r#"<shape type="sphere"><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>
    <emitter type="envmap">
        <string name="filename" value="scenes/envmap-sky.exr"/><float name="scale" value="2"/>
        <transform name="to_world"><rotate y="1" angle="90"/></transform>
    </emitter>"#,
        ),
        &format!(
            r#"{CAMERA}
[materials."bsdf@8"]
type = "lambert"
albedo = 0.5
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "bsdf@8"
[[lights]]
type = "environment"
map = "scenes/envmap-sky.exr"
scale = 2.0
to_world = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
"#
        ),
    );
    let moved = scene(
        r#"<emitter type="envmap"><string name="filename" value="scenes/envmap-sky.exr"/>
        <transform name="to_world"><translate x="1"/></transform></emitter>"#,
    );
    let Err(err) = xml(&moved) else {
        panic!("a translated envmap is refused")
    };
    assert!(
        err.contains("t.xml:8:") && err.contains("rotation"),
        "{err}"
    );
}

/// The fog box as shipped for Mitsuba (`benches/mitsuba-fog-box.xml`, one-sided walls, its
/// medium box grown behind them) and with the exact cube renders like `scenes/fog-box.toml`
/// (two-sided walls whose backs no path reaches) within error.
#[test]
fn the_fog_box_in_xml_renders_like_the_toml() {
    let text = std::fs::read_to_string(dir().join("benches/mitsuba-fog-box.xml")).unwrap();
    let small = text.replace(
        r#"<default name="res"        value="256"/>"#,
        r#"<default name="res"        value="32"/>"#,
    );
    assert_ne!(
        small, text,
        "the XML's res default changed; update this test"
    );
    let exact = small
        .replace(r#""gx"         value="1.001""#, r#""gx" value="1""#)
        .replace(r#""gz"         value="1.0005""#, r#""gz" value="1""#)
        .replace(r#""tz"         value="-0.0005""#, r#""tz" value="0""#);
    assert_eq!(
        exact.matches(r#"value="1"/>"#).count() + exact.matches(r#"value="0"/>"#).count(),
        small.matches(r#"value="1"/>"#).count() + small.matches(r#"value="0"/>"#).count() + 3,
        "the cube's defaults changed; update this test"
    );
    let toml_text = std::fs::read_to_string(dir().join("scenes/fog-box.toml"))
        .unwrap()
        .replace("resolution = [256, 256]", "resolution = [32, 32]");
    let mean = |src: &SceneSource, seed: u64| {
        let scene = Scene::load(src).unwrap_or_else(|e| panic!("{e}"));
        let mut r = Renderer::new(&scene, IntegratorKind::Path, seed, None);
        r.pass(64, &|| {});
        let film = r.film.as_ref().unwrap();
        let m: [(f64, f64, f64); 3] = std::array::from_fn(|c| common::film_mean(film, c));
        m
    };
    let reference = mean(&toml(&toml_text), 1);
    let mut fam = Family::new("mitsuba import: fog box XML vs TOML");
    for (what, text, seed) in [("grown", &small, 2), ("exact", &exact, 3)] {
        let m = mean(&xml(text).unwrap(), seed);
        for c in 0..3 {
            fam.means_agree(
                &format!("{what} XML vs TOML, channel {c}"),
                m[c],
                reference[c],
            );
        }
    }
    fam.finish();
}

/// A lit rectangle in front of a darker one, seen through `film` (the film's inner XML).
fn filtered_scene(film: &str) -> String {
    let body = r#"<shape type="rectangle"><transform name="to_world"><scale x="0.5" y="1"/></transform><emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter></shape>
    <shape type="rectangle"><transform name="to_world"><scale value="3"/><translate z="-1"/></transform></shape>"#;
    scene(body).replace(r#"<rfilter type="box"/>"#, film)
}

/// The TOML twin of [`filtered_scene`] with the camera key `filter`.
fn filtered_twin(filter: &str) -> String {
    format!(
        r#"{CAMERA}{filter}
[materials."default diffuse"]
type = "lambert"
albedo = 0.5
one_sided = true
[[shapes]]
type = "quad"
origin = [-0.5, -1.0, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
emission = [2.0, 3.0, 4.0]
[[shapes]]
type = "quad"
origin = [-3.0, -3.0, -1.0]
u = [6.0, 0.0, 0.0]
v = [0.0, 6.0, 0.0]
material = "default diffuse"
"#
    )
}

/// A film without `<rfilter>` is Mitsuba's default, the gaussian of stddev 0.5 (Mitsuba 3
/// documentation, plugin `gaussian`): the same scene file as the TOML with
/// `filter = { type = "gaussian", stddev = 0.5 }`, and the same image bit for bit; `tent` and
/// `gaussian` keep their parameters and defaults; `box` stays the box.
#[test]
fn a_film_without_rfilter_is_mitsubas_gaussian() {
    let gaussian = r#"filter = { type = "gaussian", stddev = 0.5 }"#;
    same_scene(&filtered_scene(""), &filtered_twin(gaussian));
    let a = pixels(&xml(&filtered_scene("")).unwrap());
    let b = pixels(&xml(&filtered_scene(r#"<rfilter type="box"/>"#)).unwrap());
    assert_ne!(a, b, "the gaussian and the box give one image");
    for (film, twin) in [
        (r#"<rfilter type="gaussian"/>"#, gaussian),
        (
            r#"<rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>"#,
            r#"filter = { type = "gaussian", stddev = 0.25 }"#,
        ),
        (
            r#"<rfilter type="tent"/>"#,
            r#"filter = { type = "tent", radius = 1.0 }"#,
        ),
        (
            r#"<rfilter type="tent"><float name="radius" value="1.5"/></rfilter>"#,
            r#"filter = { type = "tent", radius = 1.5 }"#,
        ),
        (r#"<rfilter type="box"/>"#, ""),
    ] {
        let x = xml(&filtered_scene(film)).unwrap();
        assert_eq!(desc(&x), desc(&toml(&filtered_twin(twin))), "{film}");
    }
}

/// Filters without an exact counterpart are refused by name at their line, and so is a
/// sample border, which would put camera samples outside the film.
#[test]
fn other_filters_are_refused_by_name() {
    for (film, needle) in [
        (
            r#"<rfilter type="lanczos"/>"#,
            "the reconstruction filter `lanczos`",
        ),
        (
            r#"<rfilter type="mitchell"/>"#,
            "the reconstruction filter `mitchell`",
        ),
        (
            r#"<rfilter type="catmullrom"/>"#,
            "the reconstruction filter `catmullrom`",
        ),
        (
            r#"<rfilter type="gaussian"><float name="stddev" value="0"/></rfilter>"#,
            "stddev = 0",
        ),
        (
            r#"<rfilter type="tent"><float name="radius" value="1"/><float name="b" value="1"/></rfilter>"#,
            "`b`",
        ),
        (
            r#"<boolean name="sample_border" value="true"/>"#,
            "sample_border",
        ),
    ] {
        let e = xml(&filtered_scene(film)).expect_err(film);
        assert!(e.contains(needle), "{film}: `{e}` does not name {needle}");
        assert!(
            e.starts_with("t.xml:6:"),
            "{film}: `{e}` is not at the film's line"
        );
    }
}

/// Every refusal names the plugin or parameter, the file and the line; nothing outside the
/// subset is imported as a different scene.
#[test]
fn unsupported_input_is_refused_with_its_name_and_line() {
    let line = SENSOR.lines().count() + 2;
    let cases: [(&str, &str); 16] = [
        (
            r#"<shape type="rectangle"><bsdf type="conductor"><string name="material" value="Au"/><texture type="checkerboard" name="eta"/></bsdf></shape>"#,
            "give either the material or eta and k",
        ),
        (
            r#"<shape type="sphere"><boolean name="flip_normals" value="true"/></shape>"#,
            "flip_normals is supported on rectangles, disks, cylinders and meshes",
        ),
        (
            r#"<shape type="cylinder"><transform name="to_world"><scale x="2"/></transform></shape>"#,
            "keep it round",
        ),
        (
            r#"<shape type="rectangle"><bsdf type="blendbsdf"/></shape>"#,
            "the BSDF `blendbsdf`",
        ),
        (r#"<emitter type="envmap"/>"#, "`filename` is missing"),
        (
            r#"<shape type="rectangle"><bsdf type="roughconductor"><string name="distribution" value="phong"/></bsdf></shape>"#,
            "distribution = phong",
        ),
        (
            r#"<shape type="rectangle"><bsdf type="conductor"><string name="material" value="Xx"/></bsdf></shape>"#,
            "material = \"Xx\"",
        ),
        (
            r#"<shape type="rectangle"><bsdf type="roughconductor"><string name="material" value="Au"/><rgb name="eta" value="1, 1, 1"/></bsdf></shape>"#,
            "either the material or eta and k",
        ),
        (
            r#"<shape type="rectangle"><bsdf type="dielectric"><texture name="specular_transmittance" type="mesh_attribute"/></bsdf></shape>"#,
            "the texture `mesh_attribute`",
        ),
        (
            r#"<shape type="rectangle"><bsdf type="diffuse"><float name="roughness" value="1"/></bsdf></shape>"#,
            "the parameter `roughness` of `diffuse`",
        ),
        (r#"<include filename="other.xml"/>"#, "<include>"),
        (
            r#"<shape type="rectangle"><float name="x" value="$nope"/></shape>"#,
            "`$nope`",
        ),
        (r#"<emitter type="spot"/>"#, "beam_width"),
        (
            r#"<shape type="cube"><transform name="to_world"><rotate y="1" angle="30"/></transform></shape>"#,
            "rotated cube",
        ),
        (
            r#"<shape type="rectangle"><ref id="missing"/></shape>"#,
            "id=\"missing\"",
        ),
        (
            r#"<medium type="homogeneous" id="m"/><shape type="cube"><ref name="interior" id="m"/><bsdf type="null"/><transform name="to_world"><scale value="9"/></transform></shape>"#,
            "the camera in vacuum",
        ),
    ];
    for (body, needle) in cases {
        let text = scene(body);
        let e =
            match xml(&text).and_then(|s| Scene::load(&s).map(|_| ()).map_err(|e| e.to_string())) {
                Ok(()) => panic!("accepted: {body}"),
                Err(e) => e,
            };
        assert!(e.contains(needle), "{body}: `{e}` does not name {needle}");
        let at = if needle == "the camera in vacuum" {
            3
        } else {
            line
        };
        assert!(
            e.starts_with(&format!("t.xml:{at}:")),
            "{body}: `{e}` is not at line {at}"
        );
    }
    // the volpath/path distinction: Mitsuba's `path` ignores media
    let path = scene(r#"<medium type="homogeneous" id="m"/><shape type="sphere"><bsdf type="null"/><ref name="interior" id="m"/></shape>"#)
        .replace(r#"<integrator type="volpath"/>"#, r#"<integrator type="path"/>"#);
    let e = xml(&path).expect_err("path with media accepted");
    assert!(
        e.contains("ignores media") && e.starts_with("t.xml:2:"),
        "{e}"
    );
    let broken = xml("<scene version=\"3.0.0\">\n<shape>\n</scene>")
        .err()
        .unwrap();
    assert!(
        broken.starts_with("t.xml:3:") && broken.contains("XML"),
        "{broken}"
    );
}

/// A `gridvolume`'s values sit at the cell centres of the unit cube mapped by `to_world`
/// (Mitsuba 3 ignores the `.vol`'s own box): pathspace's lattice spans the outer centres; a
/// grid that is not zero on its faces (where Mitsuba clamps) is refused.
#[test]
fn gridvolume_values_sit_at_cell_centres() {
    use pathspace::medium::grid::{encode_vol, Grid};
    use pathspace::scene::file::{MediumDesc, PhaseDesc, PropagationDesc, RgbValue};
    let src = mitsuba::import(
        "grid-cloud.xml",
        &std::fs::read_to_string(dir().join("scenes/xml/grid-cloud.xml")).unwrap(),
        dir().join("scenes/xml"),
    )
    .unwrap();
    // the outer cell centres of 16 cells over [-1, 1]; sigma = scale albedo and
    // scale (1 - albedo) in f64, rounded once
    let h = 1.0 - 1.0 / 16.0;
    let per =
        |f: fn(f64) -> f64| RgbValue::Triple([0.9f64, 0.92, 0.95].map(|x| (f(x) * 8.0) as f32));
    let expected = MediumDesc::Grid {
        sigma_a: per(|x| 1.0 - x),
        sigma_s: per(|x| x),
        phase: PhaseDesc::Isotropic {},
        emission: None,
        file: "blob.vol".into(),
        min: Some([-h; 3]),
        max: Some([h; 3]),
        propagation: PropagationDesc::DeltaTracking,
        step: None,
    };
    assert_eq!(desc(&src).media["cloud"], expected);
    // a face that is not zero
    let tmp = std::env::temp_dir().join(format!("pathspace-xml-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let g = Grid::new([2, 2, 2], vec![1.0; 8]).unwrap();
    std::fs::write(
        tmp.join("ones.vol"),
        encode_vol(&g, glam::Vec3::ZERO, glam::Vec3::ONE),
    )
    .unwrap();
    let text = scene(
        r#"<medium type="heterogeneous" id="m"><volume name="sigma_t" type="gridvolume"><string name="filename" value="ones.vol"/></volume></medium>
    <shape type="cube"><bsdf type="null"/><ref name="interior" id="m"/></shape>"#,
    );
    let e = mitsuba::import("t.xml", &text, tmp.clone())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("t.xml:8:") && e.contains("not zero on its faces"),
        "{e}"
    );
    // Mitsuba 3 reads no OpenVDB file: a `.vdb` is refused, pointing to the TOML medium
    let vdb = text.replace("ones.vol", "smoke.vdb");
    let e = mitsuba::import("t.xml", &vdb, tmp.clone())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("t.xml:8:")
            && e.contains("no OpenVDB reader")
            && e.contains("type = \"vdb\""),
        "{e}"
    );
    std::fs::remove_dir_all(&tmp).unwrap();
}

/// A PLY mesh (ASCII or binary, either byte order) reads as the same triangles as the OBJ it
/// was written from (the same image bit for bit); Mitsuba's `ply` shape becomes that mesh; a
/// truncated PLY is refused with the file's name.
#[test]
fn ply_meshes_read_like_obj() {
    let obj = std::fs::read_to_string(dir().join("tests/fixtures/cube.obj")).unwrap();
    let vs: Vec<Vec<f32>> = obj
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| {
            l[2..]
                .split_whitespace()
                .map(|w| w.parse().unwrap())
                .collect()
        })
        .collect();
    let fs: Vec<Vec<i32>> = obj
        .lines()
        .filter(|l| l.starts_with("f "))
        .map(|l| {
            l[2..]
                .split_whitespace()
                .map(|w| w.split('/').next().unwrap().parse::<i32>().unwrap() - 1)
                .collect()
        })
        .collect();
    let head = |format: &str| {
        format!("ply\nformat {format} 1.0\ncomment the test cube\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n", vs.len(), fs.len())
    };
    let mut ascii = head("ascii").into_bytes();
    for v in &vs {
        ascii.extend(format!("{} {} {}\n", v[0], v[1], v[2]).bytes());
    }
    for f in &fs {
        let ids: Vec<String> = f.iter().map(i32::to_string).collect();
        ascii.extend(format!("{} {}\n", f.len(), ids.join(" ")).bytes());
    }
    let binary = |big: bool| {
        let mut b = head(if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        })
        .into_bytes();
        let word = |x: [u8; 4]| {
            if big {
                let mut y = x;
                y.reverse();
                y
            } else {
                x
            }
        };
        for v in &vs {
            for c in v {
                b.extend(word(c.to_le_bytes()));
            }
        }
        for f in &fs {
            b.push(f.len() as u8);
            for i in f {
                b.extend(word(i.to_le_bytes()));
            }
        }
        b
    };
    let tmp = std::env::temp_dir().join(format!("pathspace-ply-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    std::fs::copy(dir().join("tests/fixtures/cube.obj"), tmp.join("cube.obj")).unwrap();
    std::fs::write(tmp.join("ascii.ply"), &ascii).unwrap();
    std::fs::write(tmp.join("little.ply"), binary(false)).unwrap();
    std::fs::write(tmp.join("big.ply"), binary(true)).unwrap();
    std::fs::write(tmp.join("short.ply"), &binary(false)[..300]).unwrap();
    let with_mesh = |file: &str| {
        SceneSource {
        name: "t.toml".into(),
        text: format!("{CAMERA}\n[[shapes]]\ntype = \"mesh\"\nobj = \"{file}\"\nemission = 1.0\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 9.0\nmaterial = \"w\"\n[materials.w]\ntype = \"lambert\"\nalbedo = 0.5\n"),
        base_dir: tmp.clone(),
        origin: None,
        inputs: Default::default(),
    }
    };
    let want = pixels(&with_mesh("cube.obj"));
    for f in ["ascii.ply", "little.ply", "big.ply"] {
        assert_eq!(pixels(&with_mesh(f)), want, "{f}");
    }
    let e = Scene::load(&with_mesh("short.ply"))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("short.ply") && e.contains("ends early"), "{e}");
    let text = scene(
        r#"<shape type="ply"><string name="filename" value="little.ply"/><boolean name="face_normals" value="true"/></shape>"#,
    );
    let src = mitsuba::import("t.xml", &text, tmp.clone()).unwrap();
    assert!(
        matches!(&desc(&src).shapes[0], file::ShapeDesc::Mesh { obj, .. } if obj == "little.ply")
    );
    Scene::load(&src).unwrap();
    std::fs::remove_dir_all(&tmp).unwrap();
}

/// An `obj` without `face_normals` is a smooth mesh (Mitsuba 3 interpolates its vertex
/// normals: the file's `vn`, else computed ones), with `face_normals` a flat one; each XML is its
/// TOML twin, bit for bit, and the two shadings are different images.
#[test]
fn an_obj_without_face_normals_is_a_smooth_mesh() {
    let obj = "tests/fixtures/agreement/sphere-vn.obj";
    let body = |flat: &str| {
        format!(
            r#"<shape type="obj"><string name="filename" value="{obj}"/>{flat}
        <bsdf type="diffuse" id="clay"><rgb name="reflectance" value="0.2, 0.3, 0.4"/></bsdf>
    </shape>
    <emitter type="point"><point name="position" x="1" y="2" z="3"/><float name="intensity" value="5"/></emitter>"#
        )
    };
    let twin = |smooth: &str| {
        format!(
            r#"{CAMERA}
[materials.clay]
type = "lambert"
albedo = [0.2, 0.3, 0.4]
one_sided = true
[[shapes]]
type = "mesh"
obj = "{obj}"
{smooth}material = "clay"
[[lights]]
type = "point"
position = [1.0, 2.0, 3.0]
intensity = 5.0
"#
        )
    };
    let smooth = scene(&body(""));
    let flat = scene(&body(r#"<boolean name="face_normals" value="true"/>"#));
    same_scene(&smooth, &twin("smooth_normals = true\n"));
    same_scene(&flat, &twin(""));
    assert_ne!(pixels(&xml(&smooth).unwrap()), pixels(&xml(&flat).unwrap()));
}

/// `flip_normals` on `obj` (and `ply`, `serialized`) turns a mesh around as Mitsuba 3 does:
/// around the camera, a smooth sphere's one-sided diffuse faces inwards and a lamp mesh emits
/// from its other side; each XML is its TOML twin bit for bit, and the flip changes the image.
#[test]
fn flip_normals_on_meshes_is_mitsubas() {
    let (sphere, lamp) = (
        "tests/fixtures/agreement/sphere-vn.obj",
        "tests/fixtures/agreement/lamp.obj",
    );
    let body = |flip: bool| {
        format!(
            r#"<shape type="obj"><string name="filename" value="{sphere}"/><boolean name="flip_normals" value="{flip}"/>
        <transform name="to_world"><scale value="8"/></transform>
        <bsdf type="diffuse" id="clay"><rgb name="reflectance" value="0.2, 0.3, 0.4"/></bsdf>
    </shape>
    <shape type="obj"><string name="filename" value="{lamp}"/><boolean name="flip_normals" value="{flip}"/>
        <transform name="to_world"><translate y="1"/></transform>
        <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter>
    </shape>"#
        )
    };
    let twin = format!(
        r#"{CAMERA}
[materials.clay]
type = "lambert"
albedo = [0.2, 0.3, 0.4]
one_sided = true
[[shapes]]
type = "mesh"
obj = "{sphere}"
to_world = [[8.0, 0.0, 0.0, 0.0], [0.0, 8.0, 0.0, 0.0], [0.0, 0.0, 8.0, 0.0]]
smooth_normals = true
flip_normals = true
material = "clay"
[[shapes]]
type = "mesh"
obj = "{lamp}"
to_world = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0]]
smooth_normals = true
flip_normals = true
emission = [3.0, 2.0, 1.0]
"#
    );
    let flipped = scene(&body(true));
    same_scene(&flipped, &twin);
    let img = pixels(&xml(&flipped).unwrap());
    assert!(
        img.iter().any(|p| p[0] > 0.0),
        "the flipped sphere is black"
    );
    assert_ne!(img, pixels(&xml(&scene(&body(false))).unwrap()));
}

/// `info` on an XML lists every imported element with its line and what it became; the scene's
/// hash (provenance, shards) does not depend on the path it was read by.
#[test]
fn info_lists_what_was_imported_and_how() {
    let text = std::fs::read_to_string(dir().join("scenes/xml/hg-sphere.xml")).unwrap();
    let (a, b) = (
        mitsuba::import("hg-sphere.xml", &text, dir()).unwrap(),
        mitsuba::import("/elsewhere/hg-sphere.xml", &text, dir()).unwrap(),
    );
    assert_eq!(a.hash(), b.hash());
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .arg("info")
        .arg(dir().join("scenes/xml/hg-sphere.xml"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for line in [
        "imported from Mitsuba 3 XML, element by element:",
        "line 8: <integrator type=\"volpath\"> -> render: ",
        "line 33: <medium type=\"homogeneous\"> -> media.haze: homogeneous, sigma_s = scale sigma_t albedo = [1.425, 2.025, 2.4]",
        "line 51: <shape type=\"sphere\"> -> shapes[1]: sphere at [0, 0.8, 0], radius 0.8, material null, interior haze",
    ] {
        assert!(text.contains(line), "`{line}` missing from:\n{text}");
    }
}

/// pathspace does not clip: a near clip beyond Mitsuba's default would give another image, so
/// it is refused at its line; the defaults themselves are accepted.
#[test]
fn clipping_beyond_mitsubas_defaults_is_refused() {
    let text = scene("").replace(
        "<float name=\"fov\" value=\"60\"/>",
        "<float name=\"fov\" value=\"60\"/><float name=\"near_clip\" value=\"0.5\"/>",
    );
    let Err(err) = xml(&text) else {
        panic!("near_clip = 0.5 must be refused")
    };
    assert!(
        err.contains("t.xml:3:") && err.contains("near_clip"),
        "{err}"
    );
    let defaults = scene("").replace(
        "<float name=\"fov\" value=\"60\"/>",
        "<float name=\"fov\" value=\"60\"/><float name=\"near_clip\" value=\"0.01\"/><float name=\"far_clip\" value=\"10000\"/>",
    );
    xml(&defaults).unwrap();
}

/// An element with more attributes than any Mitsuba element has is refused before the XML
/// library reads it (which checks each attribute against its element's earlier ones: 80,000
/// attributes cost it tens of CPU seconds), naming the line of the tag; attributes in
/// comments, in quoted values and in CDATA are not counted.
#[test]
fn an_element_with_thousands_of_attributes_is_refused_before_parsing() {
    let attrs: String = (0..80_000).map(|i| format!(" a{i}=\"{i}\"")).collect();
    let text = format!("<scene version=\"3.0.0\">\n\n<shape type=\"sphere\"{attrs}/>\n</scene>");
    let e = xml(&text).unwrap_err();
    assert!(
        e.contains("t.xml:3") && e.contains("more than 64 attributes"),
        "{e}"
    );
    let limit: String = (0..64).map(|i| format!(" a{i}=\"{i}\"")).collect();
    let e = xml(&format!("<scene version=\"3.0.0\"><x{limit}/></scene>")).unwrap_err();
    assert!(
        !e.contains("attributes"),
        "64 attributes are within the limit: {e}"
    );
    let hidden = format!(
        "<scene version=\"3.0.0\"><!-- <x{attrs}/> --><x a=\"{}\"/><![CDATA[<x{attrs}>]]></scene>",
        "=".repeat(100)
    );
    let e = xml(&hidden).unwrap_err();
    assert!(
        !e.contains("attributes"),
        "counted outside tags or inside quotes: {e}"
    );
}

/// A fresh folder holding `files` (name, text), for scenes that include others.
fn folder(tag: &str, files: &[(&str, &str)]) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pathspace-include-{tag}-{}", std::process::id()));
    for (name, text) in files {
        let p = d.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    d
}

/// The scene `main.xml` of `d`, read as the command line reads it.
fn read_xml(d: &std::path::Path) -> Result<SceneSource, String> {
    SceneSource::read(&d.join("main.xml")).map_err(|e| e.to_string())
}

/// `<include>`: the children of the included file's `<scene>` in place of the element, found
/// relative to the including file (`parts/ball.xml` includes `lamp.xml`: `parts/lamp.xml`, not
/// the main folder's), with `id`s shared; the scene is its TOML twin, bit for bit.
#[test]
fn include_splices_the_included_scene_in_place() {
    let d = folder(
        "twin",
        &[
            (
                "main.xml",
                &format!(
                    "<scene version=\"3.0.0\">\n{SENSOR}\n<include filename=\"parts/ball.xml\"/>\n\
                     <emitter type=\"constant\"><float name=\"radiance\" value=\"0.25\"/></emitter>\n</scene>\n"
                ),
            ),
            (
                "parts/ball.xml",
                "<?xml version=\"1.0\"?>\n<scene version=\"3.0.0\">\n\
                 <bsdf type=\"diffuse\" id=\"clay\"><rgb name=\"reflectance\" value=\"0.2, 0.3, 0.4\"/></bsdf>\n\
                 <include filename=\"lamp.xml\"/>\n<shape type=\"sphere\"><ref id=\"clay\"/></shape>\n</scene>\n",
            ),
            (
                "lamp.xml",
                "<scene version=\"3.0.0\"><emitter type=\"constant\"/></scene>",
            ),
            (
                "parts/lamp.xml",
                "<scene version=\"3.0.0\"><emitter type=\"point\"><point name=\"position\" x=\"0\" y=\"2\" z=\"0\"/>\
                 <rgb name=\"intensity\" value=\"3, 2, 1\"/></emitter></scene>",
            ),
        ],
    );
    let a = read_xml(&d).unwrap_or_else(|e| panic!("{e}"));
    let b = toml(&format!(
        r#"{CAMERA}
[materials.clay]
type = "lambert"
albedo = [0.2, 0.3, 0.4]
one_sided = true
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "clay"
[[lights]]
type = "point"
position = [0.0, 2.0, 0.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.25
"#
    ));
    assert_eq!(desc(&a), desc(&b), "generated:\n{}", a.text);
    assert_eq!(pixels(&a), pixels(&b));
    let _ = std::fs::remove_dir_all(d);
}

/// The files of an include case, the file the error names and its text.
type IncludeCase<'a> = (Vec<(&'a str, String)>, &'a str, &'a str);

/// Errors in included files name the included file and its own line, also when the build finds
/// them (a missing map); lines of the including file after an include keep their numbers;
/// a cycle, nesting beyond Mitsuba's 15 files, a root other than `<scene>` and a missing file
/// are refused at the `<include>`.
#[test]
fn include_errors_name_the_included_file_and_line() {
    let head = "<scene version=\"3.0.0\">\n";
    let main = |body: &str| format!("{head}{body}\n</scene>\n");
    let sensor = SENSOR.replace('\n', " ");
    // (the files, the file named in the error, the error's text)
    let cases: Vec<IncludeCase> = vec![
        (
            vec![
                ("main.xml", main("<include filename=\"parts/bad.xml\"/>")),
                (
                    "parts/bad.xml",
                    format!("{head}\n<shape type=\"sdfgrid\"/>\n</scene>"),
                ),
            ],
            "parts/bad.xml:3:",
            "sdfgrid",
        ),
        (
            vec![
                (
                    "main.xml",
                    main(&format!(
                        "{sensor}\n<include filename=\"five.xml\"/>\n<shape type=\"torus\"/>"
                    )),
                ),
                ("five.xml", format!("{head}\n\n\n</scene>")),
            ],
            "main.xml:4:",
            "torus",
        ),
        (
            vec![
                (
                    "main.xml",
                    main(&format!("{sensor}\n<include filename=\"map.xml\"/>")),
                ),
                (
                    "map.xml",
                    format!(
                        "{head}\n<emitter type=\"envmap\"><string name=\"filename\" \
                         value=\"missing.exr\"/></emitter>\n</scene>"
                    ),
                ),
            ],
            "map.xml:3:",
            "missing.exr",
        ),
        (
            vec![("main.xml", main("<include filename=\"main.xml\"/>"))],
            "main.xml:2:",
            "includes itself",
        ),
        (
            vec![
                ("main.xml", main("<include filename=\"leaf.xml\"/>")),
                (
                    "leaf.xml",
                    "<bsdf version=\"3.0.0\" type=\"diffuse\"/>".into(),
                ),
            ],
            "leaf.xml:1:",
            "root must be <scene",
        ),
        (
            vec![("main.xml", main("<include filename=\"nowhere.xml\"/>"))],
            "main.xml:2:",
            "nowhere.xml",
        ),
    ];
    for (k, (files, at, needle)) in cases.into_iter().enumerate() {
        let files: Vec<(&str, &str)> = files.iter().map(|(n, t)| (*n, t.as_str())).collect();
        let d = folder(&format!("err{k}"), &files);
        let e = match read_xml(&d)
            .and_then(|s| Scene::load(&s).map(|_| ()).map_err(|e| e.to_string()))
        {
            Ok(()) => panic!("accepted: {files:?}"),
            Err(e) => e,
        };
        let want = format!("{}", d.join(at).display());
        assert!(
            e.starts_with(&want) && e.contains(needle),
            "case {k}: `{e}` is not at {want} or does not name {needle}"
        );
        let _ = std::fs::remove_dir_all(d);
    }
    // a chain of 16 files nests deeper than Mitsuba's limit of 15; 15 are read
    for (n, ok) in [(15, true), (16, false)] {
        let files: Vec<(String, String)> = (0..n)
            .map(|i| {
                let name = if i == 0 {
                    "main.xml".to_string()
                } else {
                    format!("d{i}.xml")
                };
                let body = if i + 1 < n {
                    format!("<include filename=\"d{}.xml\"/>", i + 1)
                } else {
                    sensor.clone()
                };
                (name, main(&body))
            })
            .collect();
        let files: Vec<(&str, &str)> = files
            .iter()
            .map(|(n, t)| (n.as_str(), t.as_str()))
            .collect();
        let d = folder(&format!("deep{n}"), &files);
        match read_xml(&d) {
            Ok(_) => assert!(ok, "{n} files read"),
            Err(e) => assert!(!ok && e.contains("deeper than 15"), "{n} files: {e}"),
        }
        let _ = std::fs::remove_dir_all(d);
    }
}

/// `thinlens` is `perspective` through a lens (Mitsuba 3 documentation, plugin `thinlens`):
/// `aperture_radius` (required) and `focus_distance` (the distance of the focal plane along the
/// viewing direction, defaulting to `far_clip`, itself 10^4 by default) become the camera's
/// keys; a zero aperture, which Mitsuba replaces by its float epsilon, is the pinhole.
#[test]
fn thinlens_aperture_and_focus_are_mitsubas() {
    let sensor = |props: &str| {
        SENSOR
            .replace("type=\"perspective\"", "type=\"thinlens\"")
            .replace(
                "<float name=\"fov\" value=\"60\"/>",
                &format!("<float name=\"fov\" value=\"60\"/>{props}"),
            )
    };
    let body = r#"<shape type="rectangle"><emitter type="area"/></shape>"#;
    let quad = "[[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, 0.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nemission = 1.0\n";
    let scene_with = |s: String| format!("<scene version=\"3.0.0\">\n{s}\n{body}\n</scene>");
    let twin = |lens: &str| format!("{CAMERA}{lens}\n{quad}");
    same_scene(
        &scene_with(sensor(
            r#"<float name="aperture_radius" value="0.25"/><float name="focus_distance" value="3.5"/>"#,
        )),
        &twin("aperture_radius = 0.25\nfocus_distance = 3.5"),
    );
    same_scene(
        &scene_with(sensor(r#"<float name="aperture_radius" value="0.1"/>"#)),
        &twin("aperture_radius = 0.1\nfocus_distance = 10000.0"),
    );
    same_scene(
        &scene_with(sensor(
            r#"<float name="aperture_radius" value="0.1"/><float name="far_clip" value="50"/>"#,
        )),
        &twin("aperture_radius = 0.1\nfocus_distance = 50.0"),
    );
    same_scene(
        &scene_with(sensor(r#"<float name="aperture_radius" value="0"/>"#)),
        &twin(""),
    );
    // the lens changes the image
    let a = xml(&scene_with(sensor(
        r#"<float name="aperture_radius" value="0.5"/><float name="focus_distance" value="1"/>"#,
    )))
    .unwrap();
    assert_ne!(pixels(&a), pixels(&toml(&twin(""))));
    for (props, word) in [
        ("", "aperture_radius"),
        (
            r#"<float name="aperture_radius" value="-1"/>"#,
            "aperture_radius",
        ),
        (
            r#"<float name="aperture_radius" value="0.1"/><float name="focus_distance" value="0"/>"#,
            "focus_distance",
        ),
    ] {
        let e = xml(&scene_with(sensor(props))).unwrap_err();
        assert!(e.contains(word) && e.contains("t.xml:"), "{e}");
    }
}

/// A scene as users download them, with Mitsuba's defaults and common plugins at once
/// (scenes/xml/combined.xml, compared with Mitsuba 3 in the book's *Importing scenes*): a film
/// without `<rfilter>`, a thin lens, an OBJ with vertex normals, a bitmap texture and an
/// environment map all import, `info` shows each, and a few samples render finite.
#[test]
fn a_scene_with_mitsubas_defaults_imports_whole() {
    let path = dir().join("scenes/xml/combined.xml");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .arg("info")
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for line in [
        "camera: thin lens of radius 0.08 focused at 4.2 at [0, 1.2, 4.5]",
        "gaussian (stddev 0.5) filter",
        "mesh `sphere-vn.obj`, smooth (interpolated vertex normals)",
        "albedo bitmap `../../tests/fixtures/textures/rgb4x3.png`",
        "environment map `../envmap-sky.exr`, scale 0.3, looked up bilinearly",
    ] {
        assert!(text.contains(line), "`{line}` missing from:\n{text}");
    }
    let src = mitsuba::import(
        "combined.xml",
        &std::fs::read_to_string(&path).unwrap(),
        dir().join("scenes/xml"),
    )
    .unwrap();
    let px = pixels(&src);
    assert!(px.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    assert!(px.iter().flatten().any(|v| *v > 0.0));
}

/// The scene `benches/peers/to_mitsuba.py` (the peers' harness) writes for Mitsuba 3 from a
/// TOML scene, read back by the importer: the same shapes, materials, media and camera medium
/// (the importer refuses a sensor whose medium is not the one around the eye), and the same
/// image within error. The fog box (emitter facing down, medium box grown behind coplanar
/// walls), the maze in fog (the camera inside the fog, both sides of the inner walls seen
/// through the doorways, a glass sphere) at 48x32, where a horizontal field of view would frame
/// another image, one room of the 100 rooms (boxes inside the medium, Henyey-Greenstein), and
/// the harness's variants of the paper scenes (`benches/peers/scene.py`): the door slit with a
/// complex-index floor (a GGX rough conductor; the baked smoke as a padded `.vol`), the cloud
/// tracked, the volume caustic with a hard-cone spot light and with a square light. A grid
/// medium is compared by its density at points through its box, which a transposed or shifted
/// lattice changes by far more than float rounding.
#[test]
fn the_peers_mitsuba_converter_writes_the_toml_scene() {
    let mut fam = Family::new("peers: to_mitsuba.py's XML vs the TOML");
    let tmp = std::env::temp_dir().join(format!("pathspace-peers-xml-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    for (name, seed) in [
        ("fog-box", 11),
        ("maze-fog", 12),
        ("many-lights", 13),
        ("door-slit-ior", 14),
        ("cloud-tracking", 15),
        ("volume-caustic-hard-cone", 16),
        ("volume-caustic-quad", 17),
    ] {
        let path = peers_scene(name, &tmp);
        let out = std::process::Command::new("python3")
            .arg(dir().join("benches/peers/to_mitsuba.py"))
            .arg(&path)
            .args([
                "--res",
                "48x32",
                "--bin",
                env!("CARGO_BIN_EXE_pathspace"),
                "--grids",
            ])
            .arg(tmp.join(format!("{name}-grids")))
            .output()
            .expect("python3 runs benches/peers/to_mitsuba.py");
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let imported = xml(&text).unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
        let mut toml_text = std::fs::read_to_string(&path).unwrap();
        for res in ["[256, 256]", "[128, 128]", "[160, 120]"] {
            toml_text = toml_text.replace(&format!("resolution = {res}"), "resolution = [48, 32]");
        }
        assert!(
            toml_text.contains("[48, 32]"),
            "{name}: its resolution changed"
        );
        let (a, b) = (desc(&imported), desc(&toml(&toml_text)));
        assert_eq!(a.shapes.len(), b.shapes.len(), "{name}: shapes");
        for (k, m) in &b.materials {
            let got = a.materials.get(k).map(|x| triples(x.clone()));
            assert_eq!(got, Some(triples(m.clone())), "{name}: material {k}");
        }
        assert_eq!(a.lights, b.lights, "{name}: lights");
        grid_boxes_grow_behind_walls_only(name, &a, &b);
        let (x_scene, t_scene) = (load(&imported, name), load(&toml(&toml_text), name));
        for (k, m) in &b.media {
            match m {
                file::MediumDesc::Procedural { .. } => same_density(&x_scene, &t_scene, k),
                _ => assert_eq!(a.media.get(k), Some(m), "{name}: medium {k}"),
            }
        }
        let mean = |scene: &Scene, seed: u64| {
            let mut r = Renderer::new(scene, IntegratorKind::Path, seed, None);
            r.pass(64, &|| {});
            let film = r.film.as_ref().unwrap();
            let m: [(f64, f64, f64); 3] = std::array::from_fn(|c| common::film_mean(film, c));
            m
        };
        let (x, t) = (mean(&x_scene, seed), mean(&t_scene, seed + 100));
        for c in 0..3 {
            fam.means_agree(&format!("{name}, channel {c}"), x[c], t[c]);
        }
    }
    fam.finish();
    std::fs::remove_dir_all(&tmp).ok();
}

/// A grid medium's box is grown (by 1e-3, against Mitsuba 3's leak at a null face coplanar
/// with a wall) only where a wall covers the face, so the shell lies behind it: the smoke's box
/// below (the floor) and at z = 1.5 (the side wall), the cloud's nowhere. Elsewhere the shell
/// would hold medium the TOML's box does not.
fn grid_boxes_grow_behind_walls_only(name: &str, a: &SceneFile, b: &SceneFile) {
    let grown: [[f32; 3]; 2] = match name {
        "door-slit-ior" => [[0.0, -1e-3, 0.0], [0.0, 0.0, 1e-3]],
        "cloud-tracking" => [[0.0; 3]; 2],
        _ => return,
    };
    let boxes = |f: &SceneFile| -> Vec<([f32; 3], [f32; 3])> {
        f.shapes
            .iter()
            .filter_map(|s| match s {
                file::ShapeDesc::Box { min, max, .. } => Some((*min, *max)),
                _ => None,
            })
            .collect()
    };
    let (x, t) = (boxes(a), boxes(b));
    assert_eq!(x.len(), 1, "{name}: one box");
    let v = glam::Vec3::from;
    for (k, (g, w)) in [(x[0].0, t[0].0), (x[0].1, t[0].1)].into_iter().enumerate() {
        let off = v(g) - v(w) - v(grown[k]);
        assert!(off.abs().max_element() < 1e-6, "{name}: {x:?} vs {t:?}");
    }
}

/// `m` with its colours as triples (the importer writes a grey as one number).
fn triples(m: file::MaterialDesc) -> file::MaterialDesc {
    use file::{MaterialDesc as M, ReflectanceValue as R, RgbValue as V};
    let t = |v: V| V::Triple(v.to_rgb().to_array());
    let r = |r: R| match r {
        R::Value(v) => R::Value(t(v)),
        r => r,
    };
    match m {
        M::Lambert { albedo, one_sided } => M::Lambert {
            albedo: r(albedo),
            one_sided,
        },
        M::RoughConductor {
            alpha,
            alpha_u,
            alpha_v,
            distribution,
            reflectance,
            material,
            eta,
            k,
            specular,
            one_sided,
        } => M::RoughConductor {
            alpha,
            alpha_u,
            alpha_v,
            distribution,
            reflectance: reflectance.map(t),
            material,
            eta: eta.map(r),
            k: k.map(r),
            specular: r(specular),
            one_sided,
        },
        m => m,
    }
}

/// A scene of the peers' harness as a TOML file: `scenes/NAME.toml`, or the variant NAME that
/// `benches/peers/scene.py` prints, written under `tmp`.
fn peers_scene(name: &str, tmp: &std::path::Path) -> PathBuf {
    let file = dir().join("scenes").join(format!("{name}.toml"));
    if file.exists() {
        return file;
    }
    let out = std::process::Command::new("python3")
        .arg(dir().join("benches/peers/scene.py"))
        .arg(name)
        .output()
        .expect("python3 runs benches/peers/scene.py");
    assert!(
        out.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let path = tmp.join(format!("{name}.toml"));
    std::fs::write(&path, out.stdout).unwrap();
    path
}

fn load(src: &SceneSource, name: &str) -> Scene {
    Scene::load(src).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The medium `name` of `x` (imported) and `t` (the TOML) has the same sigma_s at the points of
/// a 21 x 19 x 17 lattice through the TOML medium's box, faces included, to float rounding (the
/// two lattices' coordinates are computed from different boxes): 1e-4 of the largest value.
fn same_density(x: &Scene, t: &Scene, name: &str) {
    let medium = |s: &Scene| {
        let i = s
            .medium_names
            .iter()
            .position(|n| n == name)
            .expect("the medium");
        match &s.media[i] {
            pathspace::medium::Medium::Heterogeneous(h) => h.as_ref().clone(),
            _ => panic!("{name} is not heterogeneous"),
        }
    };
    let (mx, mt) = (medium(x), medium(t));
    let (lo, hi) = (mt.bounds.min, mt.bounds.max);
    let n = [21, 19, 17];
    let mut pairs = vec![];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let f = glam::Vec3::new(i as f32, j as f32, k as f32)
                    / glam::Vec3::new(n[0] as f32 - 1.0, n[1] as f32 - 1.0, n[2] as f32 - 1.0);
                let p = lo + (hi - lo) * f;
                pairs.push((
                    p,
                    mx.sigma_s * mx.density_at(p),
                    mt.sigma_s * mt.density_at(p),
                ));
            }
        }
    }
    let top = pairs
        .iter()
        .map(|(_, _, b)| b.max_element())
        .fold(0.0, f32::max);
    assert!(top > 0.0, "{name}: no density at all");
    for (p, a, b) in pairs {
        assert!(
            (a - b).abs().max_element() <= 1e-4 * top,
            "{name} at {p}: imported sigma_s {a}, TOML {b}"
        );
    }
}

/// `direct` (emitters seen directly plus one scattering, both strategies combined by the power
/// heuristic) has the expectation of `path` with max_depth 2: pathspace's max_depth 1. Without
/// samples of one strategy Mitsuba misses light (point lights or mirrors), so that is refused,
/// as is `shading_samples` beside the fine-grained counts (Mitsuba refuses it too); like
/// `path`, `direct` ignores media.
#[test]
fn direct_is_the_path_tracer_with_one_scattering() {
    let light = r#"<shape type="rectangle"><emitter type="area"/></shape>"#;
    let with =
        |integrator: &str| scene(light).replace(r#"<integrator type="volpath"/>"#, integrator);
    let twin = CAMERA.replace("seed = 0\n", "seed = 0\nmax_depth = 1\n")
        + "[[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, 0.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nemission = 1.0\n";
    same_scene(&with(r#"<integrator type="direct"/>"#), &twin);
    same_scene(
        &with(
            r#"<integrator type="direct"><integer name="emitter_samples" value="4"/><integer name="bsdf_samples" value="2"/></integrator>"#,
        ),
        &twin,
    );
    same_scene(
        &with(
            r#"<integrator type="direct"><integer name="shading_samples" value="3"/></integrator>"#,
        ),
        &twin,
    );
    for (params, needle) in [
        (
            r#"<integer name="emitter_samples" value="0"/>"#,
            "emitter_samples = 0",
        ),
        (
            r#"<integer name="shading_samples" value="0"/>"#,
            "emitter_samples = 0",
        ),
        (
            r#"<integer name="bsdf_samples" value="0"/>"#,
            "bsdf_samples = 0",
        ),
        (
            r#"<integer name="shading_samples" value="1"/><integer name="bsdf_samples" value="1"/>"#,
            "shading_samples with",
        ),
        (
            r#"<integer name="max_depth" value="3"/>"#,
            "`max_depth` of `direct`",
        ),
    ] {
        let text = with(&format!(
            r#"<integrator type="direct">{params}</integrator>"#
        ));
        let e = xml(&text).expect_err(params);
        assert!(
            e.contains(needle) && e.starts_with("t.xml:2:"),
            "{params}: {e}"
        );
    }
    let media = with(r#"<integrator type="direct"/>"#).replace(
        light,
        r#"<medium type="homogeneous" id="m"/><shape type="sphere"><bsdf type="null"/><ref name="interior" id="m"/></shape>"#,
    );
    let e = xml(&media).expect_err("direct with media accepted");
    assert!(e.contains("`direct` integrator ignores media"), "{e}");
}

/// A `perspective` sensor reads `focus_distance` (every projective camera does) and never uses
/// it; without `fov` its field of view is a 35 mm camera's diagonal one at `focal_length`, 50 mm
/// by default (Mitsuba 3 documentation, plugin `perspective`): 2 atan(43.27 / (2 f)) across the
/// film's diagonal. Both `fov` and `focal_length`, or a focal length that is not a positive
/// number of millimetres, are refused.
#[test]
fn focus_distance_and_focal_length_are_mitsubas() {
    let fov = r#"<float name="fov" value="60"/>"#;
    let lens = |s: &str| scene("").replace(fov, s);
    // the 16 x 16 film's diagonal half-angle tan(d / 2) = 21.633 / f; vertical = that / sqrt 2
    let vertical =
        |f: f64| (2.0 * ((36f64.hypot(24.0) / (2.0 * f)) / 2f64.sqrt()).atan()).to_degrees() as f32;
    let twin = |deg: f32| CAMERA.replace("fov_deg = 60.0", &format!("fov_deg = {deg:?}"));
    same_scene(&lens(""), &twin(vertical(50.0)));
    same_scene(
        &lens(r#"<string name="focal_length" value="35mm"/>"#),
        &twin(vertical(35.0)),
    );
    same_scene(
        &lens(r#"<string name="focal_length" value="28"/>"#),
        &twin(vertical(28.0)),
    );
    same_scene(
        &lens(r#"<float name="fov" value="60"/><float name="focus_distance" value="1000"/>"#),
        CAMERA,
    );
    for (s, needle, line) in [
        (
            r#"<float name="fov" value="60"/><string name="focal_length" value="35mm"/>"#,
            "both `fov` and `focal_length`",
            3,
        ),
        (
            r#"<string name="focal_length" value="-5mm"/>"#,
            "positive number of millimetres",
            3,
        ),
        (
            r#"<string name="focal_length" value="wide"/>"#,
            "positive number of millimetres",
            3,
        ),
        (
            r#"<string name="focal_length" value="35mm"/><string name="fov_axis" value="y"/>"#,
            "`fov_axis`",
            4,
        ),
    ] {
        let e = xml(&lens(s)).expect_err(s);
        assert!(
            e.contains(needle) && e.starts_with(&format!("t.xml:{line}:")),
            "{s}: {e}"
        );
    }
}

/// An emitting OBJ without `face_normals` (Mitsuba's default) is the same light as with it when
/// the mesh is planar, its vertex normals being its face normal (the tutorial Cornell box's
/// luminaire): it renders as the flat emitting mesh; a curved emitting mesh, whose shading and
/// face normals differ, is refused naming `face_normals`.
#[test]
fn a_planar_emitting_mesh_needs_no_face_normals() {
    let body = |obj: &str, flat: &str| {
        format!(
            r#"<shape type="obj"><string name="filename" value="{obj}"/>{flat}
        <transform name="to_world"><rotate x="1" y="0.3" angle="97"/><translate z="-0.5"/></transform>
        <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter>
    </shape>
    <shape type="sphere"><point name="center" x="0" y="0" z="-2"/></shape>"#
        )
    };
    let lamp = "scenes/xml/public/cbox/meshes/cbox_luminaire.obj";
    let face = r#"<boolean name="face_normals" value="true"/>"#;
    let (smooth, flat) = (
        xml(&scene(&body(lamp, ""))).unwrap(),
        xml(&scene(&body(lamp, face))).unwrap(),
    );
    let img = pixels(&smooth);
    assert_eq!(img, pixels(&flat));
    assert!(img.iter().any(|p| p[0] > 0.0), "the lamp is not seen");
    let curved = xml(&scene(&body("tests/fixtures/agreement/sphere-vn.obj", ""))).unwrap();
    let e = Scene::load(&curved)
        .map(|_| ())
        .expect_err("a curved smooth emitter accepted")
        .to_string();
    assert!(
        e.contains("face_normals") && e.contains("curved") && e.starts_with("t.xml:"),
        "{e}"
    );
}

/// The public scenes under `scenes/xml/public/` (Mitsuba 3's own tutorial scenes, unedited)
/// import and build with what the importer notes for them, and render a few samples without a
/// NaN; their comparisons with Mitsuba 3 are in the book (Importing scenes).
#[test]
fn public_scenes_import_unedited() {
    for (file, shapes, lights, notes) in [
        (
            "scenes/xml/public/cbox/cbox.xml",
            8,
            1,
            &[
                "max_depth 5 (Mitsuba's 6",
                "tent (radius 1) filter",
                "material mirror",
            ][..],
        ),
        (
            "scenes/xml/public/simple/simple.xml",
            1,
            2,
            &[
                "path tracer with max_depth 1",
                "along diagonal",
                "box filter",
                "smooth",
            ][..],
        ),
    ] {
        let src = SceneSource::read(&dir().join(file)).unwrap_or_else(|e| panic!("{e}"));
        let origin = src.origin.clone().expect("an XML scene keeps its origin");
        for n in notes {
            assert!(
                origin.notes.iter().any(|l| l.contains(n)),
                "{file}: no note with `{n}`"
            );
        }
        let scene = Scene::load(&src).unwrap_or_else(|e| panic!("{e}"));
        let d = desc(&src);
        assert_eq!(
            (d.shapes.len(), scene.lights.len()),
            (shapes, lights),
            "{file}"
        );
        let mut r = Renderer::new(&scene, IntegratorKind::Path, 1, None);
        r.pass(1, &|| {});
        let img = r.film.as_ref().unwrap().image();
        let sum: f64 = img.pixels.iter().map(|p| p.x as f64 + p.y as f64).sum();
        assert!(sum.is_finite() && sum > 0.0, "{file}: sum {sum}");
    }
}

/// `hide_emitters` (Mitsuba 3.9.1's `volpath`: no emission before the first scattering, which
/// null surfaces and media do not count) is pathspace's `hide_emitters`: the environment seen
/// directly or through a null surface is dark, through glass and off a mirror it stays. An area
/// emitter is imported (transparent to the camera's rays until they scatter, in both), except
/// where Mitsuba's integrators stop seeing through it: `path` behind a null surface, `volpath`
/// in a medium; `direct` with a null surface is refused too (Mitsuba's shows emitters through
/// it).
#[test]
fn hide_emitters_is_pathspaces() {
    let hidden =
        r#"<integrator type="volpath"><boolean name="hide_emitters" value="true"/></integrator>"#;
    let body = r#"<shape type="sphere">
        <point name="center" x="0.5" y="0" z="0"/><float name="radius" value="0.5"/>
        <bsdf type="dielectric" id="glass"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
    </shape>
    <shape type="rectangle">
        <bsdf type="conductor" id="plain"/>
        <transform name="to_world"><translate x="-1.5" z="-1"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="null" id="pass"/>
        <transform name="to_world"><scale x="3" y="3"/><translate z="1"/></transform>
    </shape>
    <emitter type="constant"><float name="radiance" value="0.5"/></emitter>"#;
    let with = |integrator: &str, body: &str| {
        scene(body).replace(r#"<integrator type="volpath"/>"#, integrator)
    };
    let twin = format!(
        r#"hide_emitters = true
{CAMERA}
[materials.glass]
type = "dielectric"
ior = 1.5
[materials.plain]
type = "conductor"
one_sided = true
[[shapes]]
type = "sphere"
center = [0.5, 0.0, 0.0]
radius = 0.5
material = "glass"
[[shapes]]
type = "quad"
origin = [-2.5, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "plain"
[[shapes]]
type = "quad"
origin = [-3.0, -3.0, 1.0]
u = [6.0, 0.0, 0.0]
v = [0.0, 6.0, 0.0]
material = "null"
[[lights]]
type = "environment"
radiance = 0.5
"#
    );
    same_scene(&with(hidden, body), &twin);
    // the same scene shown differs: the sky seen directly is 0.5
    let shown = pixels(&xml(&with(r#"<integrator type="volpath"/>"#, body)).unwrap());
    assert_ne!(shown, pixels(&toml(&twin)));
    let lamp = r#"<shape type="rectangle"><emitter type="area"/><transform name="to_world"><translate z="-2"/></transform></shape>"#;
    // an area emitter the camera sees through before the first scattering, as `volpath` does
    let lit = with(hidden, &format!("{body}\n{lamp}"));
    let lamp_twin = "[[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, -2.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nemission = 1.0\n";
    same_scene(&lit, &format!("{twin}{lamp_twin}"));
    let fog = r#"<medium type="homogeneous" id="m"/><shape type="sphere"><bsdf type="null"/><ref name="interior" id="m"/><transform name="to_world"><translate x="-0.5"/><scale value="0.5"/></transform></shape>"#;
    let refused = [
        with(
            r#"<integrator type="path"><boolean name="hide_emitters" value="true"/></integrator>"#,
            &format!("{body}\n{lamp}"),
        ),
        with(
            r#"<integrator type="direct"><boolean name="hide_emitters" value="true"/></integrator>"#,
            body,
        ),
        with(hidden, &format!("{body}\n{lamp}\n{fog}")),
    ];
    for (text, needle) in refused.iter().zip([
        "`path` with an area emitter and a null surface",
        "`direct` with a null surface",
        "an area emitter and a medium",
    ]) {
        let e = xml(text).unwrap_err();
        assert!(
            e.contains("hide_emitters") && e.contains(needle) && e.contains("t.xml"),
            "{e}"
        );
    }
}

/// `<spectrum>` lists and `.spd` files become the RGB colours Mitsuba 3's RGB variants give them
/// (the f32 values below are Mitsuba's own, from `tests/fixtures/spectra/mitsuba.txt`): a
/// reflectance and a medium's `sigma_t` and `albedo` bounded under D65 (`sigma_t` clamped to
/// 1, as Mitsuba clamps it), a conductor's `eta` and `k` unbounded under D65, emission from a
/// `.spd` file without D65, and a uniform emission the sRGB of a flat spectrum.
#[test]
fn spectra_are_mitsubas_rgb() {
    let st = [1.0f32, 1.0, 0.4287373];
    let albedo = [0.5115173f32, 0.46194986, 0.1477761];
    let (ss, sa): (Vec<f32>, Vec<f32>) = (0..3)
        .map(|c| {
            let (t, a) = (st[c] as f64 * 0.5, albedo[c] as f64);
            ((t * a) as f32, (t * (1.0 - a)) as f32)
        })
        .unzip();
    same_scene(
        &scene(
            r#"<medium type="homogeneous" id="haze">
        <spectrum name="sigma_t" value="380:1.5, 480:0.2, 580:2.5, 780:0.7"/>
        <spectrum name="albedo" value="450:0.3 650:0.6"/><float name="scale" value="0.5"/>
    </medium>
    <shape type="sphere"><bsdf type="null"/><ref name="interior" id="haze"/></shape>
    <shape type="sphere">
        <point name="center" x="0" y="1.5" z="0"/><float name="radius" value="0.3"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0, 0, 0"/></bsdf>
        <emitter type="area"><spectrum name="radiance" filename="tests/fixtures/spectra/ramp.spd"/></emitter>
    </shape>
    <shape type="rectangle">
        <bsdf type="diffuse" id="a"><spectrum name="reflectance" value="400:0.1, 500:0.5, 600:0.7, 700:0.8"/></bsdf>
        <transform name="to_world"><scale x="3" y="3"/><translate z="-2"/></transform>
    </shape>
    <shape type="rectangle">
        <bsdf type="conductor" id="b">
            <spectrum name="eta" value="300:0.2, 450:0.9, 550:0.1, 900:0.6"/>
            <spectrum name="k" value="380:1.5, 480:0.2, 580:2.5, 780:0.7"/>
        </bsdf>
        <transform name="to_world"><translate x="1.5" z="-1"/></transform>
    </shape>
    <emitter type="constant"><spectrum name="radiance" value="0.1"/></emitter>"#,
        ),
        &format!(
            r#"{CAMERA}
[media.haze]
type = "homogeneous"
sigma_a = {sa:?}
sigma_s = {ss:?}
phase = {{ type = "isotropic" }}
[materials.a]
type = "lambert"
albedo = [0.75443333, 0.5950902, 0.27726075]
one_sided = true
[materials.b]
type = "conductor"
eta = [0.12662868, 0.20219022, 0.85763144]
k = [2.6911857, 1.588412, 0.4287373]
one_sided = true
[[shapes]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "null"
interior = "haze"
[[shapes]]
type = "sphere"
center = [0.0, 1.5, 0.0]
radius = 0.3
emission = [0.9271941, 0.5627954, 0.22137243]
[[shapes]]
type = "quad"
origin = [-3.0, -3.0, -2.0]
u = [6.0, 0.0, 0.0]
v = [0.0, 6.0, 0.0]
material = "a"
[[shapes]]
type = "quad"
origin = [0.5, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "b"
[[lights]]
type = "environment"
radiance = [0.1204794, 0.0948291, 0.09089161]
"#
        ),
    );
}

/// A malformed `<spectrum>` is refused naming the file, the line, the property and what is
/// wrong with it; a `.spd` file's own line is named too.
#[test]
fn malformed_spectra_are_refused_by_line_and_key() {
    let line = SENSOR.lines().count() + 2;
    let bad = std::env::temp_dir().join(format!("pathspace-bad-{}.spd", std::process::id()));
    std::fs::write(&bad, "400 0.1\n500 x\n").unwrap();
    let bad = bad.display().to_string();
    for (spectrum, needle) in [
        (
            r#"value="500:0.1, 400:0.2""#,
            "the wavelengths must increase",
        ),
        (r#"value="400:0.1""#, "at least two"),
        (
            r#"value="400:0.1, 500:abc""#,
            "the value `abc` is not a finite number",
        ),
        (r#"value="400:0.1, 500:-1""#, "negative"),
        (r#"filename="missing.spd""#, "filename=\"missing.spd\""),
        (&format!(r#"filename="{bad}""#), "line 2: the value `x`"),
        (
            r#"value="400:0.1, 500:0.2" filename="x.spd""#,
            "either `value` or `filename`",
        ),
    ] {
        let text = scene(&format!(
            "<shape type=\"sphere\"><bsdf type=\"diffuse\"><spectrum name=\"reflectance\" {spectrum}/></bsdf></shape>"
        ));
        let e = xml(&text).expect_err(spectrum);
        assert!(
            e.contains(needle),
            "{spectrum}: `{e}` does not say {needle}"
        );
        assert!(
            e.starts_with(&format!("t.xml:{line}:")) && e.contains("name=\"reflectance\""),
            "{spectrum}: `{e}` does not name the line and the key"
        );
    }
}

/// Anisotropic roughness (Mitsuba 3 documentation, plugins `roughconductor`,
/// `roughdielectric`: `alpha_u` along the shape's dp/du, `alpha_v` across it) becomes the same
/// TOML keys, on a rectangle, a sphere and an OBJ mesh with texture coordinates (whose dp/du
/// comes from them), a checkerboard as `alpha_u`; `alpha_u` equal to `alpha_v` is the isotropic
/// `alpha`, bit for bit; half a pair, a pair with `alpha` and a `roughplastic`'s pair are
/// refused with the line.
#[test]
fn anisotropic_roughness_is_mitsubas() {
    let pair = |u: f32, v: f32| {
        format!(r#"<float name="alpha_u" value="{u}"/><float name="alpha_v" value="{v}"/>"#)
    };
    let body = |metal: &str| {
        format!(
            r#"<shape type="rectangle">
        <bsdf type="roughconductor" id="brushed"><string name="distribution" value="ggx"/>{metal}</bsdf>
        <transform name="to_world"><rotate z="1" angle="30"/><translate z="-2"/></transform>
    </shape>
    <shape type="sphere">
        <point name="center" x="-0.6" y="0" z="0"/><float name="radius" value="0.4"/>
        <bsdf type="roughdielectric" id="frosted"><texture type="checkerboard" name="alpha_u"><float name="color0" value="0.5"/><float name="color1" value="0.1"/></texture><float name="alpha_v" value="0.08"/></bsdf>
    </shape>
    <shape type="obj">
        <string name="filename" value="tests/fixtures/textures/mesh-vt.obj"/>
        <transform name="to_world"><translate x="-1" y="-0.8"/></transform>
        <ref id="brushed"/>
    </shape>
    <emitter type="point"><point name="position" x="0" y="2" z="1"/><rgb name="intensity" value="3, 2, 1"/></emitter>
    <emitter type="constant"><float name="radiance" value="0.25"/></emitter>"#
        )
    };
    let twin = |metal: &str| {
        format!(
            r#"{CAMERA}
[materials.brushed]
type = "rough_conductor"
distribution = "ggx"
{metal}
one_sided = true
[materials.frosted]
type = "rough_dielectric"
distribution = "beckmann"
alpha_u = {{ texture = "checkerboard", color0 = 0.5, color1 = 0.1 }}
alpha_v = 0.08
ior = {:?}
[[shapes]]
type = "quad"
origin = [-0.36602542, -1.3660254, -2.0]
u = [1.7320508, 1.0, 0.0]
v = [-1.0, 1.7320508, 0.0]
material = "brushed"
[[shapes]]
type = "sphere"
center = [-0.6, 0.0, 0.0]
radius = 0.4
material = "frosted"
[[shapes]]
type = "mesh"
obj = "tests/fixtures/textures/mesh-vt.obj"
to_world = [[1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, -0.8], [0.0, 0.0, 1.0, 0.0]]
smooth_normals = true
material = "brushed"
[[lights]]
type = "point"
position = [0.0, 2.0, 1.0]
intensity = [3.0, 2.0, 1.0]
[[lights]]
type = "environment"
radiance = 0.25
"#,
            (1.5046f64 / 1.000277) as f32,
        )
    };
    let aniso = scene(&body(&pair(0.05, 0.3)));
    same_scene(&aniso, &twin("alpha_u = 0.05\nalpha_v = 0.3"));
    // at a point of the rectangle (turned 30 degrees about z) the metal's tangent is its local
    // x, Mitsuba's dp/du: alpha_u = 0.05 lies along (cos 30, sin 30, 0)
    let s = Scene::load(&xml(&aniso).unwrap()).unwrap();
    let ray = pathspace::geometry::Ray::new(glam::Vec3::new(0.3, 0.5, 4.0), -glam::Vec3::Z);
    let hit = s.intersect(&ray, f32::INFINITY).expect("the rectangle");
    let bsdf = s.bsdf_at(hit.prim, hit.p);
    let Some(pathspace::bsdf::Bsdf::RoughConductor(m)) = bsdf.as_deref() else {
        panic!("no rough conductor at {}", hit.p);
    };
    let a = m.anisotropy.expect("anisotropic");
    let x = glam::Vec3::new(30f32.to_radians().cos(), 30f32.to_radians().sin(), 0.0);
    assert!(
        (m.alpha, a.alpha_v) == (0.05, 0.3) && a.tangent.normalize().dot(x) > 0.9999,
        "{m:?}"
    );
    // equal: the isotropic material, the same image as `alpha`
    let equal = xml(&scene(&body(&pair(0.3, 0.3)))).unwrap();
    assert_eq!(pixels(&equal), pixels(&toml(&twin("alpha = 0.3"))));
    // the orientation matters: swapped, another image
    let swapped = xml(&scene(&body(&pair(0.3, 0.05)))).unwrap();
    assert_ne!(pixels(&swapped), pixels(&xml(&aniso).unwrap()));
    let line = SENSOR.lines().count() + 2;
    for (bsdf, needle) in [
        (
            r#"<bsdf type="roughconductor"><float name="alpha_u" value="0.1"/></bsdf>"#,
            "both alpha_u and alpha_v",
        ),
        (
            r#"<bsdf type="roughdielectric"><float name="alpha" value="0.1"/><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.2"/></bsdf>"#,
            "either alpha or alpha_u and alpha_v",
        ),
        (
            r#"<bsdf type="roughplastic"><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.2"/></bsdf>"#,
            "refuses anisotropic roughness",
        ),
    ] {
        let body = format!(r#"<shape type="rectangle">{bsdf}</shape>"#);
        let e = xml(&scene(&body)).expect_err(bsdf);
        assert!(e.contains(needle), "{bsdf}: `{e}` does not name {needle}");
        assert!(e.starts_with(&format!("t.xml:{line}:")), "{bsdf}: `{e}`");
    }
}
