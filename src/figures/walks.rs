//! Random walks in the fog box from BDPT's own subpath sampling: the strategies (s, t) that
//! join one light subpath and one eye subpath into paths of three edges, and the eye walk of
//! the Neumann series with a connection to the light from each of its vertices.

use glam::Vec2;
use plotters::prelude::*;

use super::side::{self, Side, EYE_PATH, LIGHT_PATH};
use super::{svg, Drawn, SEED, TRIES};
use crate::bidir::WalkLimits;
use crate::integrator::bdpt::{Bdpt, Strategies};
use crate::math::Sampler;
use crate::measure::chart::ChartError;
use crate::path::geometry_term::geometry_term_exact;
use crate::path::{Vertex, PLAIN};
use crate::scene::Scene;

/// The eye and light subpaths of BDPT sample `index` (stream 5 of the figures' seed).
fn subpaths(scene: &Scene, index: u64, stream: u64) -> Option<(Vec<Vertex>, Vec<Vertex>)> {
    let cam = scene.camera.as_ref()?;
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let mut sampler = Sampler::new(SEED, index, stream);
    let u = sampler.next_2d();
    let raster = Vec2::new(u.x * cam.width as f32, u.y * cam.height as f32);
    let (mut eye, mut light) = (Vec::new(), Vec::new());
    bdpt.camera_subpath(scene, raster, WalkLimits::BDPT, &mut sampler, &mut eye);
    bdpt.light_subpath(scene, WalkLimits::BDPT, &mut sampler, &mut light);
    Some((eye, light))
}

/// Whether the edge a-b carries light: unoccluded, and seen by the camera if one end is it.
fn joins(scene: &Scene, a: &Vertex, b: &Vertex) -> bool {
    let seen = match (a.is_sensor(), scene.camera.as_ref()) {
        (true, Some(c)) => c.importance(a.p, (b.p - a.p).normalize_or_zero()).is_some(),
        _ => true,
    };
    seen && geometry_term_exact(scene, a, b).0 > 0.0
}

/// The closest two consecutive vertices of a walk may be (scene units), so labels stay apart.
const SPACING: f32 = 0.3;

/// Whether the side view shows `walk` as it is: its scattering vertices (after the first)
/// `SPACING` apart, none on a side wall (which the view flattens into the box).
fn spaced(walk: &[Vertex]) -> bool {
    let on_side_wall = |v: &Vertex| !v.is_medium() && v.n.x.abs() > 0.5;
    walk.windows(2)
        .skip(1)
        .all(|w| w[0].p.distance(w[1].p) >= SPACING)
        && !walk.iter().any(on_side_wall)
}

/// The strategies (s, t) with s + t = 4: s light vertices joined to t eye vertices.
const STRATEGIES: [(usize, usize); 3] = [(1, 3), (2, 2), (3, 1)];

/// The first BDPT sample with three vertices on each side whose three joins carry light.
pub fn strategies_subpaths(scene: &Scene) -> Option<(Vec<Vertex>, Vec<Vertex>)> {
    (0..TRIES).find_map(|i| {
        let (eye, light) = subpaths(scene, i, 5)?;
        let ok = eye.len() >= 3
            && light.len() >= 3
            && spaced(&eye[..3])
            && spaced(&light[..3])
            && STRATEGIES
                .iter()
                .all(|&(s, t)| joins(scene, &light[s - 1], &eye[t - 1]));
        ok.then(|| (eye[..3].to_vec(), light[..3].to_vec()))
    })
}

/// A dashed edge a-b labelled at the fraction `at` of the way from a to b.
fn dashed(
    chart: &mut Side,
    (a, b): (&Vertex, &Vertex),
    at: f32,
    colour: RGBColor,
    text: &str,
) -> Drawn {
    let (p, q) = (side::zy(a.p), side::zy(b.p));
    let style = colour.stroke_width(2);
    chart.draw_series(DashedLineSeries::new(vec![p, q], 8, 5, style))?;
    let m = (p.0 + at * (q.0 - p.0), p.1 + at * (q.1 - p.1));
    side::label(chart, m, (4, -4), text)
}

/// One light subpath y and one eye subpath z, and the three joins of BDPT's strategies.
pub(super) fn strategies_figure(scene: &Scene) -> Result<String, ChartError> {
    let (eye, light) = strategies_subpaths(scene)
        .ok_or_else(|| ChartError::Drawing("bdpt", "no subpaths found".into()))?;
    let v = side::view(scene);
    svg("bdpt", side::size(&v, 1000), |root| {
        let title = "A light subpath y and an eye subpath z, joined by the strategies (s, t)";
        let mut c = side::chart(root, title, v)?;
        side::draw_scene(&mut c, scene)?;
        let colours = [
            RGBColor(27, 158, 119),
            RGBColor(117, 112, 179),
            RGBColor(231, 41, 138),
        ];
        for (&(s, t), colour) in STRATEGIES.iter().zip(colours) {
            let text = format!("(s, t) = ({s}, {t})");
            dashed(&mut c, (&light[s - 1], &eye[t - 1]), 0.5, colour, &text)?;
        }
        side::draw_path(&mut c, &light, (LIGHT_PATH, side::RIGHT), Some("y"), |_| {
            true
        })?;
        side::draw_path(&mut c, &eye, (EYE_PATH, side::RIGHT), Some("z"), |_| true)
    })
}

/// Eye-walk vertices the Neumann figure shows (the camera and three scattering vertices).
const WALK: usize = 4;

/// The first eye walk with `WALK` vertices from each of whose scattering vertices a light
/// point (the start of a light subpath of the same sample) is visible.
pub fn neumann_walk(scene: &Scene) -> Option<(Vec<Vertex>, Vec<Vertex>)> {
    (0..TRIES).find_map(|i| {
        let (eye, _) = subpaths(scene, i, 6)?;
        if eye.len() < WALK || !spaced(&eye[..WALK]) {
            return None;
        }
        let lights: Option<Vec<Vertex>> = (1..WALK)
            .map(|k| {
                subpaths(scene, i * WALK as u64 + k as u64, 7)?
                    .1
                    .first()
                    .copied()
            })
            .collect();
        let lights = lights?;
        let ok = (1..WALK).all(|k| joins(scene, &eye[k], &lights[k - 1]));
        ok.then(|| (eye[..WALK].to_vec(), lights))
    })
}

/// The path tracer's walk: each vertex z_j joined to a light point ends a path with j
/// scattering events, a sample of the series' term T^j L_i (j = 0 is emission seen directly).
pub(super) fn neumann_figure(scene: &Scene) -> Result<String, ChartError> {
    let (eye, lights) = neumann_walk(scene)
        .ok_or_else(|| ChartError::Drawing("neumann", "no walk found".into()))?;
    let v = side::view(scene);
    svg("neumann", side::size(&v, 1000), |root| {
        let title = "One walk, every term: the connection from z\u{2C7C} samples the term T\u{02B2} L\u{1D62}";
        let mut c = side::chart(root, title, v)?;
        side::draw_scene(&mut c, scene)?;
        for (k, l) in lights.iter().enumerate() {
            let text = format!("j = {}", k + 1);
            dashed(
                &mut c,
                (&eye[k + 1], l),
                0.2 + 0.2 * k as f32,
                LIGHT_PATH,
                &text,
            )?;
        }
        side::draw_path(&mut c, &eye, (EYE_PATH, side::RIGHT), Some("z"), |_| true)
    })
}
