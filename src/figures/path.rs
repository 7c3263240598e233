//! Pauly et al.'s Figs. 1 and 2 in the fog box (the ray of eq. (3), a path with its
//! characteristic) and the transmittance along one ray through the fog box and the cloud.

use glam::Vec2;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{side, subscript, svg, Area, Drawn, SEED, TRIES};
use crate::geometry::Ray;
use crate::integrator::bdpt::{Bdpt, Strategies};
use crate::math::Sampler;
use crate::measure::chart::{ChartError, FAMILY};
use crate::path::distance::RayMedia;
use crate::path::geometry_term::geometry_term_exact;
use crate::path::{characteristic, characteristic::measure_of, Vertex, VertexKind, PLAIN};
use crate::scene::Scene;

/// A path of characteristic l = 1011_2 = 11, as in Pauly et al. Fig. 2: x_0 on the light, x_1
/// on a wall, x_2 in the fog, x_3 the camera. It is the first BDPT sample (eye subpath
/// camera, medium, surface; x_0 the light subpath's start) whose surface vertex lies on the
/// floor or the back wall (so the side view shows it where it is), at least 0.8 from x_2, and
/// whose join edge x_0 x_1 is unoccluded. Returns the path from the light to the camera.
pub fn figure_2_path(scene: &Scene) -> Option<Vec<Vertex>> {
    let cam = scene.camera.as_ref()?;
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let (mut eye, mut light) = (Vec::new(), Vec::new());
    let limits = crate::bidir::WalkLimits::BDPT;
    for index in 0..TRIES {
        let mut sampler = Sampler::new(SEED, index, 0);
        let u = sampler.next_2d();
        let raster = Vec2::new(u.x * cam.width as f32, u.y * cam.height as f32);
        bdpt.camera_subpath(scene, raster, limits, &mut sampler, &mut eye);
        bdpt.light_subpath(scene, limits, &mut sampler, &mut light);
        if eye.len() < 3 || light.is_empty() {
            continue;
        }
        let (x2, x1) = (eye[1], eye[2]);
        // the floor or the back wall (not the side walls, which the side view flattens)
        let floor_or_back = x1.n.y > 0.5 || x1.n.z > 0.5;
        let on_wall = matches!(x1.kind, VertexKind::Surface { .. }) && floor_or_back;
        if !x2.is_medium() || !on_wall || x1.p.distance(x2.p) < 0.8 {
            continue;
        }
        let x0 = light[0];
        if geometry_term_exact(scene, &x0, &x1).0 > 0.0 {
            return Some(vec![x0, x1, x2, eye[0]]);
        }
    }
    None
}

/// The side view (z to the right, y up) of the fog box with the path of [`figure_2_path`].
pub(super) fn path_figure(scene: &Scene) -> Result<String, ChartError> {
    let path = figure_2_path(scene).ok_or_else(|| {
        ChartError::Drawing(
            "path",
            format!("no path of characteristic 11 in {TRIES} samples"),
        )
    })?;
    svg("path", (1100, 560), |root| draw_path(root, &path))
}

fn draw_path(root: &Area<'_>, path: &[Vertex]) -> Drawn {
    let l = characteristic(path);
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!(
                "A path x\u{2080} x\u{2081} x\u{2082} x\u{2083} in the fog box, seen from the side: l = {l:04b}\u{2082} = {l}"
            ),
            (FAMILY, 22),
        )
        .margin(20)
        .build_cartesian_2d(-1.4f32..4.3f32, -1.35f32..1.45f32)?;
    let fog = RGBColor(205, 222, 238);
    let wall = BLACK.stroke_width(4);
    let font = (FAMILY, 18).into_font();
    chart.draw_series(std::iter::once(Rectangle::new(
        [(-1.0, -1.0), (1.0, 1.0)],
        fog.filled(),
    )))?;
    // floor, back wall, ceiling (the open face z = +1 is the fog's null boundary only)
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)],
        wall,
    )))?;
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(1.0, -1.0), (1.0, 1.0)],
        RGBColor(120, 150, 190).stroke_width(1),
    )))?;
    let orange = RGBColor(230, 120, 0);
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(-0.25, 0.999), (0.25, 0.999)],
        orange.stroke_width(9),
    )))?;
    let notes = [
        ((-0.1, 1.2), "light"),
        ((0.2, 0.6), "fog (medium)"),
        ((-0.2, -1.25), "floor"),
        ((-1.38, 1.2), "back wall"),
        ((1.05, 0.9), "null boundary (open face)"),
        ((3.5, 0.3), "camera"),
    ];
    for (p, s) in notes {
        chart.draw_series(std::iter::once(Text::new(s, p, font.clone())))?;
    }
    let pts: Vec<(f32, f32)> = path.iter().map(|v| (v.p.z, v.p.y)).collect();
    chart.draw_series(std::iter::once(PathElement::new(
        pts.clone(),
        RGBColor(40, 40, 40).stroke_width(2),
    )))?;
    for (i, (v, &p)) in path.iter().zip(&pts).enumerate() {
        let label = format!("x{} ({})", subscript(i), measure_of(l, i));
        if v.is_medium() {
            chart.draw_series(std::iter::once(
                EmptyElement::at(p) + Circle::new((0, 0), 7, BLUE.stroke_width(3)),
            ))?;
        } else {
            chart.draw_series(std::iter::once(
                EmptyElement::at(p) + Rectangle::new([(-6, -6), (6, 6)], BLACK.filled()),
            ))?;
        }
        chart.draw_series(std::iter::once(
            EmptyElement::at(p) + Text::new(label, (10, 6), font.clone()),
        ))?;
    }
    // the edges' factors of eq. (6): G tau on each, centred beside each edge's middle, on
    // its upper side
    let centred = TextStyle::from(font).pos(Pos::new(HPos::Center, VPos::Center));
    for (i, w) in pts.windows(2).enumerate() {
        let (a, b) = (chart.backend_coord(&w[0]), chart.backend_coord(&w[1]));
        let d = ((b.0 - a.0) as f32, (b.1 - a.1) as f32);
        let len = d.0.hypot(d.1).max(1.0);
        let side = if d.0 >= 0.0 { 1.0 } else { -1.0 };
        // wider from steep edges: the label is wider than it is tall
        let r = 22.0 + 30.0 * (d.1 / len).abs();
        let off = (side * d.1 / len * r, -side * d.0 / len * r);
        let m = ((w[0].0 + w[1].0) / 2.0, (w[0].1 + w[1].1) / 2.0);
        let s = format!("G\u{03C4}(x{}\u{2194}x{})", subscript(i), subscript(i + 1));
        chart.draw_series(std::iter::once(
            EmptyElement::at(m) + Text::new(s, (off.0 as i32, off.1 as i32), centred.clone()),
        ))?;
    }
    Ok(())
}

/// The sample points of one transmittance curve and the free flights drawn along the ray.
struct RayCurve {
    name: &'static str,
    curve: Vec<(f32, f32)>,
    /// Collision distances (a medium vertex each); passages are not drawn.
    collisions: Vec<f32>,
    passages: usize,
}

/// The ray of eq. (3): from the camera through the image centre, tau(x, x') (first channel)
/// by the media's exact transmittance, and `FLIGHTS` free flights sampled as the walks do.
fn ray_curve(scene: &Scene, name: &'static str) -> Option<RayCurve> {
    const FLIGHTS: u64 = 40;
    let cam = scene.camera.as_ref()?;
    let ray = Ray::new(cam.eye, cam.forward);
    let media = RayMedia::collect(scene, ray, scene.camera_medium);
    let spans = media.spans();
    let (first, last) = (spans.first()?, spans.last()?);
    let end = last.t1.min(first.t0 + 8.0);
    let curve = (0..=400)
        .map(|k| {
            let t = first.t0 + (end - first.t0) * k as f32 / 400.0;
            let i = spans
                .iter()
                .position(|s| t <= s.t1)
                .unwrap_or(spans.len() - 1);
            (t, media.transmittance_exact(scene, i, t.max(spans[i].t0)).x)
        })
        .collect();
    let (mut collisions, mut passages) = (Vec::new(), 0);
    for k in 0..FLIGHTS {
        let mut sampler = Sampler::new(SEED, k, 1);
        let s = spans[0];
        let med = &scene.media[s.medium as usize];
        let ff = med.sample_free_flight(&Ray::new(ray.at(s.t0), ray.d), s.t1 - s.t0, &mut sampler);
        if ff.scattered {
            collisions.push(s.t0 + ff.t);
        } else {
            passages += 1;
        }
    }
    Some(RayCurve {
        name,
        curve,
        collisions,
        passages,
    })
}

/// tau along the central camera ray of both scenes, with the sampled collision distances.
pub(super) fn transmittance_figure(fog_box: &Scene, cloud: &Scene) -> Result<String, ChartError> {
    let none = || ChartError::Drawing("transmittance", "no medium on the central ray".into());
    let curves = [
        ray_curve(fog_box, "fog box (homogeneous)").ok_or_else(none)?,
        ray_curve(cloud, "cloud (grid)").ok_or_else(none)?,
    ];
    svg("transmittance", (1000, 560), |root| {
        draw_transmittance(root, &curves)
    })
}

fn draw_transmittance(root: &Area<'_>, curves: &[RayCurve]) -> Drawn {
    let t0 = curves.iter().flat_map(|c| c.curve.first()).map(|p| p.0);
    let t1 = curves.iter().flat_map(|c| c.curve.last()).map(|p| p.0);
    let lo = t0.fold(f32::INFINITY, f32::min) - 0.1;
    let hi = t1.fold(f32::NEG_INFINITY, f32::max) + 0.1;
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Transmittance \u{03C4}(x, x + t\u{03C9}) along the camera's central ray",
            (FAMILY, 22),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(lo..hi, -0.12f32..1.05f32)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("distance t from the camera")
        .y_desc("\u{03C4}")
        .label_style((FAMILY, 16))
        .axis_desc_style((FAMILY, 18))
        .draw()?;
    let colours = [RGBColor(33, 102, 172), RGBColor(178, 24, 43)];
    for (k, (c, colour)) in curves.iter().zip(colours).enumerate() {
        let legend = format!(
            "{}: {} collisions of {} free flights",
            c.name,
            c.collisions.len(),
            c.collisions.len() + c.passages
        );
        chart
            .draw_series(LineSeries::new(c.curve.clone(), colour.stroke_width(3)))?
            .label(legend)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
        // one tick per sampled collision, below the axis of tau = 0
        let y = -0.04 - 0.05 * k as f32;
        chart.draw_series(c.collisions.iter().map(|&t| {
            PathElement::new(vec![(t, y - 0.018), (t, y + 0.018)], colour.stroke_width(2))
        }))?;
    }
    chart
        .configure_series_labels()
        .label_font((FAMILY, 16))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

/// Pauly et al. Fig. 1: the ray of eq. (3) from the camera x back to the surface point
/// x_∂V = h(x, -ω), with the collision points x' of 40 free flights sampled along it (the
/// flights that reach the wall are the surface term's).
pub(super) fn ray_figure(scene: &Scene) -> Result<String, ChartError> {
    let c = ray_curve(scene, "fog box")
        .ok_or_else(|| ChartError::Drawing("ray", "no medium on the central ray".into()))?;
    let cam = scene
        .camera
        .as_ref()
        .ok_or_else(|| ChartError::Drawing("ray", "no camera".into()))?;
    let ray = Ray::new(cam.eye, cam.forward);
    let wall = ray.at(c.curve.last().map_or(0.0, |p| p.0));
    let xs: Vec<_> = c.collisions.iter().map(|&t| side::zy(ray.at(t))).collect();
    let v = side::view(scene);
    svg("ray", side::size(&v, 900), |root| {
        let title = "The ray of eq. (3): x, the surface point x\u{2202}V = h(x, \u{2212}\u{03C9}), sampled x\u{2032}";
        let mut ch = side::chart(root, title, v)?;
        side::draw_scene(&mut ch, scene)?;
        let line = vec![side::zy(cam.eye), side::zy(wall)];
        ch.draw_series(std::iter::once(PathElement::new(
            line,
            BLACK.stroke_width(2),
        )))?;
        ch.draw_series(xs.iter().map(|&p| {
            EmptyElement::at(p) + Circle::new((0, 0), 5, side::EYE_PATH.stroke_width(2))
        }))?;
        let wall_mark = Rectangle::new([(-6, -6), (6, 6)], BLACK.filled());
        ch.draw_series(std::iter::once(
            EmptyElement::at(side::zy(wall)) + wall_mark,
        ))?;
        let arrow = vec![
            (2.2, 0.0),
            (2.6, 0.0),
            (2.5, 0.05),
            (2.6, 0.0),
            (2.5, -0.05),
        ];
        ch.draw_series(std::iter::once(PathElement::new(
            arrow,
            BLACK.stroke_width(2),
        )))?;
        side::label(&mut ch, (2.4, 0.0), (-6, -26), "\u{03C9}")?;
        side::label(&mut ch, side::zy(cam.eye), (-10, -30), "x")?;
        side::label(&mut ch, side::zy(wall), (8, -28), "x\u{2202}V")?;
        let n = format!(
            "x\u{2032}: {} collisions of {} free flights",
            xs.len(),
            xs.len() + c.passages
        );
        side::label(&mut ch, (0.2, 0.0), (0, 12), &n)
    })
}
