//! A chain of Dirac vertices between two strategies (book: "Bidirectional path tracing",
//! "Weights across a chain of Dirac vertices"): a light on the floor, a mirror ceiling, a
//! Lambertian wall and a meter, the path through the mirror with the mirror image that
//! straightens it, and the two strategies' weights as `mis_weight_of_path` computes them.

use glam::Vec3;
use plotters::prelude::*;

use super::side::{self, EYE_PATH, RIGHT};
use super::svg;
use crate::bidir::{mis_weight_of_path, Bdpt, Strategies};
use crate::math::Sampler;
use crate::measure::chart::ChartError;
use crate::path::pdf::densities;
use crate::path::{Path, Vertex, VertexKind, PLAIN};
use crate::scene::{Scene, SceneSource};

/// A mirror ceiling y = 1 facing down (primitive 0) over a light on the floor facing up
/// (primitive 1, light 0): the start of the chain's scene, and of other mirror paths' (the
/// spec of the path module adds its own sensor).
pub const MIRROR_OVER_LIGHT: &str = r#"
[materials.mirror]
type = "mirror"
reflectance = 0.9
[[shapes]]
type = "quad"
origin = [-1.0, 1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 0.0, 2.0]
material = "mirror"
[[shapes]]
type = "quad"
origin = [0.2, -1.0, -0.4]
u = [0.0, 0.0, 0.8]
v = [0.8, 0.0, 0.0]
emission = 2.0
"#;

/// The rest of the chain's scene: a Lambertian back wall (primitive 2) and an irradiance
/// meter facing it.
const WALL_AND_METER: &str = r#"
[materials.wall]
type = "lambert"
albedo = 0.5
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "wall"
[[sensors]]
type = "irradiance_meter"
name = "facing the wall"
origin = [-0.5, -0.5, -0.6]
u = [0.0, 0.2, 0.0]
v = [0.2, 0.0, 0.0]
"#;

/// The wall point x_2 of the chain, and its image in the mirror plane y = 1.
const WALL_POINT: Vec3 = Vec3::new(-0.3, -0.2, -1.0);

/// The scene and the path x_0 (light) x_1 (mirror, a Dirac vertex) x_2 (wall) x_3 (meter):
/// x_1 lies where the segment from x_0 to x_2's mirror image crosses the mirror.
pub fn mirror_chain() -> (Scene, Path) {
    let text = format!("{MIRROR_OVER_LIGHT}{WALL_AND_METER}");
    let scene = Scene::load(&SceneSource::embedded("mirror-chain.toml", &text))
        .expect("the mirror chain's scene is valid");
    let v = |kind, p, n| Vertex::new(kind, p, n, None, None);
    let x0 = Vec3::new(0.5, -1.0, 0.0);
    let image = mirror_image(WALL_POINT);
    let x1 = x0 + (image - x0) * ((1.0 - x0.y) / (image.y - x0.y));
    let mut mirror = v(VertexKind::Surface { prim: 0 }, x1, Vec3::NEG_Y);
    mirror.delta = true;
    let light = VertexKind::Light {
        light: 0,
        prim: Some(1),
    };
    let vertices = vec![
        v(light, x0, Vec3::Y),
        mirror,
        v(VertexKind::Surface { prim: 2 }, WALL_POINT, Vec3::Z),
        v(
            VertexKind::Meter { meter: 0 },
            Vec3::new(-0.4, -0.4, -0.6),
            Vec3::NEG_Z,
        ),
    ];
    (scene, Path { vertices })
}

/// A point's image in the mirror plane y = 1.
fn mirror_image(p: Vec3) -> Vec3 {
    Vec3::new(p.x, 2.0 - p.y, p.z)
}

/// The weights of the eye walk that hits the light (s = 0) and of the light walk connected
/// to the meter (s = 3), with the ratio p(x_0) / p(x_2 | x_3) of their densities.
pub fn mirror_chain_weights(scene: &Scene, path: &Path) -> (f32, f32, f32) {
    let b = Bdpt::new(&PLAIN, Some(4), Strategies::All);
    let mut sampler = Sampler::new(1, 0, 0);
    let d = densities(scene, &PLAIN, path, &mut sampler);
    let w = |s| mis_weight_of_path(&b, scene, path, s, &d);
    (w(0), w(3), d.light[0] / d.eye[2])
}

/// The chain in the side view, the straight edge to the wall point's mirror image dashed.
pub(super) fn figure() -> Result<String, ChartError> {
    let (scene, path) = mirror_chain();
    let (w0, w3, r) = mirror_chain_weights(&scene, &path);
    let view = (-1.3f32..0.9f32, -1.3f32..2.5f32);
    svg("mirror-chain", side::size(&view, 700), |root| {
        let title = "A chain through a mirror, weighed by its ends";
        let mut c = side::chart(root, title, view)?;
        side::draw_scene(&mut c, &scene)?;
        let v = &path.vertices;
        // the meter, which the scene view does not draw
        let meter = vec![(-0.6, -0.5), (-0.6, -0.3)];
        c.draw_series(std::iter::once(PathElement::new(
            meter,
            BLACK.stroke_width(5),
        )))?;
        let image = side::zy(mirror_image(v[2].p));
        let grey = side::OLD.stroke_width(2);
        c.draw_series(DashedLineSeries::new(
            vec![side::zy(v[1].p), image],
            8,
            5,
            grey,
        ))?;
        side::label(&mut c, image, RIGHT, "x\u{2082}' (x\u{2082} in the mirror)")?;
        side::draw_path(&mut c, v, (EYE_PATH, RIGHT), Some("x"), |_| true)?;
        let lines = [
            format!("p(x\u{2080}) / p(x\u{2082} | x\u{2083}) = {r:.2}"),
            "weighed by the balance heuristic:".to_string(),
            format!("w(s = 0) = {w0:.3}   w(s = 3) = {w3:.3}"),
        ];
        for (k, text) in lines.iter().enumerate() {
            side::label(&mut c, (0.05, 2.3 - 0.2 * k as f32), (0, 0), text)?;
        }
        Ok(())
    })
}
