//! Area lights (`src/scene/light.rs`) with a textured radiance (Mitsuba 3 documentation, plugin
//! `area`: `radiance` a texture over the shape's (u, v)): every entry point of a light (a
//! direction towards it, an emitted ray, a point found by chance, a point drawn elsewhere)
//! reads the texture at its own point, the power weighs the texture's mean, and a texture
//! with one value renders bit for bit as that constant.

use glam::Vec3;
use pathspace::geometry::Ray;
use pathspace::integrator::IntegratorKind;
use pathspace::math::Sampler;
use pathspace::scene::light::emitted_by;
use pathspace::scene::light::LightPointDraw::{Area, SolidAngleNear};
use pathspace::scene::{AreaRadiance, Light, Scene, SceneSource};
use pathspace::spectrum::Rgb;

/// A floor and a wall lit by a quad lamp with `quad` and a sphere lamp with `sphere` as
/// `emission`.
fn lamps(quad: &str, sphere: &str) -> String {
    format!(
        r#"[camera]
type = "pinhole"
eye = [0.0, 0.6, 3.2]
look_at = [0.0, -0.2, 0.0]
fov_deg = 50.0
resolution = [8, 8]

[materials.white]
type = "lambert"
albedo = 0.7

[[shapes]]
type = "quad"
origin = [-1.5, -0.8, 1.5]
u = [3.0, 0.0, 0.0]
v = [0.0, 0.0, -3.0]
material = "white"

[[shapes]]
type = "quad"
origin = [-1.5, -0.8, -1.5]
u = [3.0, 0.0, 0.0]
v = [0.0, 2.5, 0.0]
material = "white"

[[shapes]]
type = "quad"
origin = [-1.1, -0.3, -0.6]
u = [1.2, 0.0, 0.3]
v = [0.0, 0.9, 0.4]
emission = {quad}

[[shapes]]
type = "sphere"
center = [0.7, -0.35, 0.2]
radius = 0.35
emission = {sphere}
"#
    )
}

fn load(text: &str) -> Scene {
    let mut src = SceneSource::embedded("lamps.toml", text);
    src.base_dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    Scene::load(&src).unwrap_or_else(|e| panic!("{e}"))
}

const CHECKER: &str = r#"{ texture = "checkerboard", color0 = [6.0, 3.0, 1.0], color1 = [0.3, 0.8, 3.0], to_uv = [[3.0, 0.0, 0.0], [0.0, 2.0, 0.1]] }"#;
const BITMAP: &str = r#"{ texture = "bitmap", file = "textures/rgb4x3.png", to_uv = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0]] }"#;

/// The texture of light `l` at point `p` of primitive `prim`, by the primitive's own (u, v)
/// (both lamps map uv as their primitive does: `spec::texture` checks it is Mitsuba's).
fn expected(scene: &Scene, l: usize, prim: u32, p: Vec3) -> Rgb {
    let Light::Area {
        radiance: AreaRadiance::Textured { texture, .. },
        ..
    } = &scene.lights[l]
    else {
        panic!("light {l} is not textured");
    };
    texture.eval(scene.prims[prim as usize].uv(p))
}

/// The primitive of light `l` (each lamp is one).
fn prim_of(scene: &Scene, l: usize) -> u32 {
    match &scene.lights[l] {
        Light::Area { prims, .. } => prims[0],
        _ => panic!("light {l} is no area light"),
    }
}

/// Next-event estimation's sample, a light subpath's emitted ray, a point drawn elsewhere (the
/// adjoint image's) and a point a ray finds each carry the texture at their own point; the
/// back of the lamp is black.
#[test]
fn every_entry_point_reads_the_texture_at_its_own_point() {
    let scene = load(&lamps(CHECKER, BITMAP));
    let mut s = Sampler::new(3, 0, 0);
    let p_ref = Vec3::new(0.1, 0.9, 1.5);
    // 0.3 in front of the quad lamp's centre (its normal is u x v, normalized)
    let near_quad = Vec3::new(-0.5, 0.15, -0.25) + 0.3 * Vec3::new(-0.27, -0.48, 1.08).normalize();
    let mut distinct = std::collections::HashSet::new();
    for l in 0..2 {
        let (light, prim) = (&scene.lights[l], prim_of(&scene, l));
        for _ in 0..500 {
            // by area from afar, and by solid angle from near the quad lamp's centre
            for (from, draw) in [(p_ref, Area), (near_quad, SolidAngleNear)] {
                let u = (s.next_2d(), s.next_f32());
                if let Some(ls) = light.sample_li(&scene.prims, from, u, draw) {
                    assert_eq!(ls.value, expected(&scene, l, prim, ls.p), "sample_li");
                    distinct.insert(ls.value.to_array().map(f32::to_bits));
                }
            }
            let es = light
                .sample_le(
                    &scene.prims,
                    s.next_2d(),
                    s.next_2d(),
                    s.next_f32(),
                    scene.center,
                    scene.radius,
                )
                .expect("an area light always emits");
            assert_eq!(es.value, expected(&scene, l, prim, es.p), "sample_le");
            let at = light.emission_at(&scene.prims, prim, (es.p, es.n), 1.0, s.next_2d());
            assert_eq!(at.value, es.value, "emission_at");
            let ls = light.li_from(&scene.prims, prim, es.p + es.d, es.p, es.n, 1.0);
            assert_eq!(ls.map(|ls| ls.value), Some(es.value), "li_from");
            // a camera ray finds the same point: the radiance at the hit
            let ray = Ray::new(es.p + 0.05 * es.d, -es.d);
            let hit = scene
                .intersect(&ray, f32::INFINITY)
                .expect("the lamp is hit");
            assert_eq!(hit.prim, prim);
            let found = emitted_by(light, &scene.prims, hit.prim, (hit.p, hit.ng), es.d);
            assert_eq!(found, expected(&scene, l, prim, hit.p), "emitted_by");
            let back = emitted_by(light, &scene.prims, hit.prim, (hit.p, hit.ng), -es.d);
            assert_eq!(back, Rgb::ZERO, "the back of a lamp");
        }
    }
    // both checks, and many texels, were seen
    assert!(distinct.len() > 4, "{} distinct values", distinct.len());
}

/// Light selection weighs a textured lamp by its texture's mean (the checkerboard's two colours
/// cover its unit square equally; the bitmap's texel mean): pi A mean.
#[test]
fn the_power_of_a_textured_lamp_is_its_texture_mean() {
    let scene = load(&lamps(CHECKER, "[0.25, 0.5, 0.75]"));
    let Light::Area { area, .. } = &scene.lights[0] else {
        panic!("an area light");
    };
    let mean = 0.5 * (Vec3::new(6.0, 3.0, 1.0) + Vec3::new(0.3, 0.8, 3.0));
    let power = std::f32::consts::PI * area * pathspace::spectrum::average(mean);
    assert_eq!(scene.lights[0].power(scene.radius), power);
    let other = scene.lights[1].power(scene.radius);
    assert_eq!(scene.light_pmf(0), power / (power + other));
}

/// A checkerboard of one colour on both lamps renders as that colour, bit for bit, with every
/// integrator: the lookup returns the colour itself, and the mean 0.5 (c + c) = c is exact in
/// f32, so the light selection is the same too.
#[test]
fn a_one_colour_texture_renders_bit_for_bit_as_the_constant() {
    let one = |c: &str| format!(r#"{{ texture = "checkerboard", color0 = {c}, color1 = {c} }}"#);
    let (q, s) = ("[4.0, 3.0, 2.5]", "[0.7, 1.9, 0.35]");
    let constant = load(&lamps(q, s));
    let textured = load(&lamps(&one(q), &one(s)));
    assert!(matches!(
        &textured.lights[0],
        Light::Area {
            radiance: AreaRadiance::Textured { .. },
            ..
        }
    ));
    for &kind in IntegratorKind::ALL {
        let a = crate::common::film_bits(&constant, kind, 5);
        assert!(a.iter().any(|&x| x != 0), "{kind:?}: a black image");
        let b = crate::common::film_bits(&textured, kind, 5);
        assert!(
            a == b,
            "{kind:?}: the one-colour texture renders another image"
        );
    }
}

/// A box lamp reads its texture with the box's (u, v) (Mitsuba's `cube`: each face the unit
/// square), not its faces' own quad coordinates.
#[test]
fn a_box_lamp_reads_the_cube_uv() {
    let text = lamps(CHECKER, BITMAP).replace(
        "type = \"sphere\"\ncenter = [0.7, -0.35, 0.2]\nradius = 0.35",
        "type = \"box\"\nmin = [0.4, -0.7, 0.0]\nmax = [0.9, -0.2, 0.5]",
    );
    let scene = load(&text);
    let Light::Area {
        prims,
        radiance: AreaRadiance::Textured { texture, uv, .. },
        ..
    } = &scene.lights[1]
    else {
        panic!("a textured box lamp");
    };
    assert!(matches!(uv, pathspace::scene::UvMap::Cube { .. }));
    let mut s = Sampler::new(9, 0, 0);
    for _ in 0..200 {
        let es = scene.lights[1]
            .sample_le(
                &scene.prims,
                s.next_2d(),
                s.next_2d(),
                s.next_f32(),
                scene.center,
                scene.radius,
            )
            .expect("emits");
        let ray = Ray::new(es.p + 0.05 * es.d, -es.d);
        let hit = scene
            .intersect(&ray, f32::INFINITY)
            .expect("the lamp is hit");
        assert!(prims.contains(&hit.prim));
        assert_eq!(
            es.value,
            texture.eval(uv.uv_of(&scene.prims, hit.prim, es.p))
        );
    }
}

/// A box lamp on the floor of the fog box: five faces emit into the fog, the bottom one under
/// the floor, outside it. Light paths start from each face in that face's own medium
/// (`Scene::light_medium`), so light tracing and BDPT see the lamp as path tracing does.
#[test]
fn each_face_of_a_lamp_starts_its_paths_in_its_own_medium() {
    let text = pathspace::scene::FOG_BOX.to_string()
        + "\n[[shapes]]\ntype = \"box\"\nmin = [0.5, -1.0, -0.9]\nmax = [0.8, -0.7, -0.6]\nemission = 2.0\n";
    let scene = Scene::load(&SceneSource::embedded("lamp.toml", &text)).unwrap();
    let fog = scene.medium_names.iter().position(|n| n == "fog").unwrap() as u32;
    let (l, prims) = (scene.lights.iter().enumerate())
        .find_map(|(l, light)| match light {
            Light::Area { prims, .. } if prims.len() > 2 => Some((l, prims.clone())),
            _ => None,
        })
        .expect("the box lamp");
    for prim in prims {
        let (_, n) = scene.prims[prim as usize].sample_area(glam::Vec2::splat(0.5));
        let expected = if n.y < -0.5 { None } else { Some(fog) };
        assert_eq!(
            scene.light_medium(l, Some(prim)),
            expected,
            "face with normal {n}"
        );
    }
}
