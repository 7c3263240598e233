//! The scene seen from the side (z to the right, y up), drawn from the parsed scene: media as
//! filled boxes, surfaces as their outlines (those parallel to the drawing are left out),
//! spheres as circles, lights in orange, the camera with its field of view. Every figure that
//! shows paths draws them over this view.

use std::ops::Range;

use glam::Vec3;
use plotters::coord::types::RangedCoordf32;
use plotters::prelude::*;

use super::{subscript, svg, Area, Drawn};
use crate::geometry::Primitive;
use crate::measure::chart::{ChartError, FAMILY};
use crate::path::Vertex;
use crate::scene::Scene;

/// A side-view chart.
pub(super) type Side<'c, 's> =
    ChartContext<'c, SVGBackend<'s>, Cartesian2d<RangedCoordf32, RangedCoordf32>>;

pub(super) const FOG: RGBColor = RGBColor(205, 222, 238);
pub(super) const LIGHT: RGBColor = RGBColor(230, 120, 0);
pub(super) const EYE_PATH: RGBColor = RGBColor(33, 102, 172);
pub(super) const LIGHT_PATH: RGBColor = RGBColor(200, 90, 0);
pub(super) const OLD: RGBColor = RGBColor(150, 150, 150);
pub(super) const NEW: RGBColor = RGBColor(178, 24, 43);

/// A point's side-view coordinates.
pub(super) fn zy(p: Vec3) -> (f32, f32) {
    (p.z, p.y)
}

/// The (z, y) ranges that hold the scene's bounds and its camera, with a margin.
pub(super) fn view(scene: &Scene) -> (Range<f32>, Range<f32>) {
    let (mut lo, mut hi) = (scene.bounds.min, scene.bounds.max);
    if let Some(c) = &scene.camera {
        lo = lo.min(c.eye);
        hi = hi.max(c.eye);
    }
    let pad = 0.3;
    (lo.z - pad..hi.z + pad, lo.y - pad..hi.y + pad)
}

/// The size of a `width`-pixel figure whose chart of `view` has equal scales on both axes.
pub(super) fn size(view: &(Range<f32>, Range<f32>), width: u32) -> (u32, u32) {
    let (z, y) = view;
    let plot = (width - 40) as f32;
    (
        width,
        (plot * (y.end - y.start) / (z.end - z.start)) as u32 + 80,
    )
}

/// A side-view chart of `view` with `caption`.
pub(super) fn chart<'c, 's>(
    root: &'c Area<'s>,
    caption: &str,
    view: (Range<f32>, Range<f32>),
) -> Result<Side<'c, 's>, Box<dyn std::error::Error>> {
    Ok(ChartBuilder::on(root)
        .caption(caption, (FAMILY, 22))
        .margin(20)
        .build_cartesian_2d(view.0, view.1)?)
}

/// The (z, y) outline of a primitive: a quad's four corners, a sphere's circle.
fn outline(prim: &Primitive) -> Vec<(f32, f32)> {
    match prim {
        Primitive::Quad(q) => {
            let c = [
                q.origin,
                q.origin + q.u,
                q.origin + q.u + q.v,
                q.origin + q.v,
            ];
            c.iter().chain(&c[..1]).map(|&p| zy(p)).collect()
        }
        Primitive::Sphere(s) => (0..=72)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / 72.0;
                (
                    s.center.z + s.radius * a.cos(),
                    s.center.y + s.radius * a.sin(),
                )
            })
            .collect(),
        _ => Vec::new(),
    }
}

/// Quads whose normal is the view direction x lie in the drawing's plane: left out.
fn faces_viewer(prim: &Primitive) -> bool {
    matches!(prim, Primitive::Quad(q) if q.n.x.abs() > 0.9)
}

/// The media (filled boxes of the null boundaries with an interior), then every other
/// surface's outline, lights thick and orange.
pub(super) fn draw_scene(chart: &mut Side, scene: &Scene) -> Drawn {
    for (i, info) in scene.shapes.iter().enumerate() {
        if !(info.is_null() && info.interior.is_some()) {
            continue;
        }
        let prims = scene.prims.iter().zip(&scene.prim_shape);
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for (p, _) in prims.filter(|(_, &s)| s as usize == i) {
            lo = lo.min(p.bounds().min);
            hi = hi.max(p.bounds().max);
        }
        chart.draw_series(std::iter::once(Rectangle::new(
            [zy(lo), zy(hi)],
            FOG.filled(),
        )))?;
    }
    for (prim, &s) in scene.prims.iter().zip(&scene.prim_shape) {
        let info = &scene.shapes[s as usize];
        if info.is_null() || faces_viewer(prim) {
            continue;
        }
        let style = if info.light.is_some() {
            LIGHT.stroke_width(7)
        } else if matches!(prim, Primitive::Sphere(_)) {
            RGBColor(0, 120, 140).stroke_width(3)
        } else {
            BLACK.stroke_width(3)
        };
        chart.draw_series(std::iter::once(PathElement::new(outline(prim), style)))?;
    }
    draw_camera(chart, scene)
}

/// The pinhole and the edges of its vertical field of view, as far as the look-at distance.
fn draw_camera(chart: &mut Side, scene: &Scene) -> Drawn {
    let Some(c) = &scene.camera else {
        return Ok(());
    };
    let reach = (c.eye - scene.center).length() * 1.1;
    let grey = RGBColor(120, 120, 120).stroke_width(1);
    for sign in [-1.0, 1.0] {
        let d = (c.forward + sign * c.tan_half_y * c.up).normalize();
        let edge = vec![zy(c.eye), zy(c.eye + reach * d)];
        chart.draw_series(DashedLineSeries::new(edge, 6, 4, grey))?;
    }
    let p = zy(c.eye);
    chart.draw_series(std::iter::once(
        EmptyElement::at(p) + TriangleMarker::new((0, 0), 9, BLACK.filled()),
    ))?;
    Ok(())
}

/// Text at data point `p`, shifted by `off` pixels.
pub(super) fn label(chart: &mut Side, p: (f32, f32), off: (i32, i32), s: &str) -> Drawn {
    label_in(chart, p, off, s, BLACK)
}

/// Text in `colour` at data point `p`, shifted by `off` pixels.
fn label_in(chart: &mut Side, p: (f32, f32), off: (i32, i32), s: &str, colour: RGBColor) -> Drawn {
    let font = (FAMILY, 17).into_font().color(&colour);
    chart.draw_series(std::iter::once(
        EmptyElement::at(p) + Text::new(s.to_string(), off, font),
    ))?;
    Ok(())
}

/// Where a vertex's label goes, in pixels from the vertex: right of it, or left of it (for a
/// second path drawn over the first).
pub(super) const RIGHT: (i32, i32) = (8, 4);
pub(super) const LEFT: (i32, i32) = (-30, 4);

/// A path as a polyline with its vertices marked (circles in a medium, squares elsewhere) and,
/// if `name` is given, labelled name₀, name₁, ... (at offset `off`) at the vertices `labelled`
/// allows.
pub(super) fn draw_path(
    chart: &mut Side,
    path: &[Vertex],
    (colour, off): (RGBColor, (i32, i32)),
    name: Option<&str>,
    labelled: impl Fn(usize) -> bool,
) -> Drawn {
    let pts: Vec<(f32, f32)> = path.iter().map(|v| zy(v.p)).collect();
    chart.draw_series(std::iter::once(PathElement::new(
        pts.clone(),
        colour.stroke_width(3),
    )))?;
    for (i, (v, &p)) in path.iter().zip(&pts).enumerate() {
        if v.is_medium() {
            chart.draw_series(std::iter::once(
                EmptyElement::at(p) + Circle::new((0, 0), 6, colour.stroke_width(3)),
            ))?;
        } else if !v.is_sensor() {
            chart.draw_series(std::iter::once(
                EmptyElement::at(p) + Rectangle::new([(-5, -5), (5, 5)], colour.filled()),
            ))?;
        }
        if let Some(n) = name.filter(|_| labelled(i)) {
            label_in(chart, p, off, &format!("{n}{}", subscript(i)), colour)?;
        }
    }
    Ok(())
}

/// The fog box once: its walls, its light, its medium and its camera, from the scene file.
pub(super) fn fog_box_figure(scene: &Scene) -> Result<String, ChartError> {
    let v = view(scene);
    svg("fog-box", size(&v, 900), |root| {
        let mut c = chart(
            root,
            "The fog box seen from the side (x towards the viewer)",
            v,
        )?;
        draw_scene(&mut c, scene)?;
        let m = scene.media.first().ok_or("the fog box has no medium")?;
        let (s, t) = (m.sigma_s(Vec3::ZERO).x, m.sigma_t(Vec3::ZERO).x);
        let fog = format!("fog: \u{03C3}s = {s:.2}, \u{03C3}a = {:.2}", t - s);
        label(&mut c, (0.9, 0.35), (0, 0), &fog)?;
        label(&mut c, (0.9, 0.15), (0, 0), "phase function: isotropic")?;
        label(&mut c, (0.25, 1.05), (0, -22), "area light")?;
        label(&mut c, (-0.2, -1.0), (0, 6), "floor")?;
        label(&mut c, (-1.0, 0.0), (8, 0), "back wall")?;
        label(&mut c, (-0.95, 1.0), (0, 6), "ceiling")?;
        label(&mut c, (1.0, -0.9), (6, 0), "open face (null boundary)")?;
        let eye = scene.camera.as_ref().map_or(Vec3::ZERO, |c| c.eye);
        label(&mut c, zy(eye), (-120, 16), "pinhole camera")?;
        label(&mut c, (-0.95, -0.6), (0, 0), "red wall x = \u{2212}1,")?;
        label(&mut c, (-0.95, -0.75), (0, 0), "green wall x = +1")?;
        Ok(())
    })
}
