//! The fog box from the side with the solid angle its lamp subtends at each point of the plane
//! through the lamp's centre (log scale; the lamp's direct light into the fog is proportional
//! to it, before transmittance), the lamp's halo as `HaloMixture` builds it, and the cone a
//! vertex on the floor draws into with `halo_cone` (book: "Sampling toward lights", section
//! "The scattering direction: a cone toward the halo").

use glam::Vec3;
use plotters::prelude::*;

use super::side::{chart, label, size, zy, EYE_PATH, LIGHT, NEW};
use super::{svg, Drawn};
use crate::geometry::Primitive;
use crate::math::spherical::SphericalParallelogram;
use crate::measure::chart::ChartError;
use crate::scene::halo::{Halo, HaloMixture};
use crate::scene::{Light, Scene};

/// Cells of the solid-angle map per side.
const CELLS: usize = 72;
/// The decades of solid angle the colours span, down from 2 pi.
const DECADES: f64 = 4.0;
/// The vertex whose cone is drawn, (z, y) in the plane of the lamp's centre.
const VERTEX: (f32, f32) = (0.45, -0.75);

/// The fog box's lamp: its one quad, and its halo.
fn lamp(scene: &Scene) -> Option<(crate::geometry::shape::Quad, Halo)> {
    let mixture = HaloMixture::new(scene, 0.5)?;
    scene.lights.iter().enumerate().find_map(|(l, light)| {
        let Light::Area { prims, .. } = light else {
            return None;
        };
        match scene.prims.get(*prims.first()? as usize)? {
            Primitive::Quad(q) => Some((*q, mixture.halo(l)?)),
            _ => None,
        }
    })
}

/// The solid angle of the quad at `x` (0 behind it).
fn solid_angle(q: &crate::geometry::shape::Quad, x: Vec3) -> f64 {
    if (x - q.origin).dot(q.n) <= 0.0 {
        return 0.0;
    }
    SphericalParallelogram::new(x, q.origin, q.u, q.v).map_or(0.0, |s| s.solid_angle())
}

/// Blue DECADES below 2 pi, white halfway, the lamp's orange at 2 pi, by the logarithm.
fn colour(omega: f64) -> RGBColor {
    let t = ((omega / std::f64::consts::TAU).log10() / DECADES + 1.0).clamp(0.0, 1.0);
    let white = RGBColor(245, 245, 245);
    let (a, b, t) = if t < 0.5 {
        (EYE_PATH, white, 2.0 * t)
    } else {
        (white, LIGHT, 2.0 * t - 1.0)
    };
    let mix = |a: u8, b: u8| (a as f64 + t * (b as f64 - a as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The map, the halo's circle and the vertex's cone over the side view.
pub(super) fn figure(scene: &Scene) -> Result<String, ChartError> {
    let (q, halo) =
        lamp(scene).ok_or_else(|| ChartError::Drawing("halo", "no quad lamp".into()))?;
    let v = (-1.1f32..2.0f32, -1.1f32..1.7f32);
    svg("halo", size(&v, 760), |root| {
        let caption = "The lamp's solid angle in the fog (log), its halo, and a vertex's cone";
        let mut c = chart(root, caption, v.clone())?;
        let x0 = (q.origin + 0.5 * (q.u + q.v)).x;
        let step = 2.0 / CELLS as f32;
        let cells = (0..CELLS * CELLS).map(|k| {
            let (i, j) = ((k % CELLS) as f32, (k / CELLS) as f32);
            let (z, y) = (-1.0 + i * step, -1.0 + j * step);
            let centre = Vec3::new(x0, y + 0.5 * step, z + 0.5 * step);
            let fill = colour(solid_angle(&q, centre)).filled();
            Rectangle::new([(z, y), (z + step, y + step)], fill)
        });
        c.draw_series(cells)?;
        // the walls and the lamp again over the map (the open face at z = +1 has none)
        let walls = [
            [(-1.0, -1.0), (1.0, -1.0)],
            [(-1.0, 1.0), (1.0, 1.0)],
            [(-1.0, -1.0), (-1.0, 1.0)],
        ];
        for w in walls {
            c.draw_series(std::iter::once(PathElement::new(
                w.to_vec(),
                BLACK.stroke_width(3),
            )))?;
        }
        let corners = [
            q.origin,
            q.origin + q.u,
            q.origin + q.u + q.v,
            q.origin + q.v,
        ];
        let lamp = corners.iter().map(|&p| zy(p)).collect::<Vec<_>>();
        c.draw_series(std::iter::once(PathElement::new(
            lamp,
            LIGHT.stroke_width(7),
        )))?;
        draw_halo(&mut c, &halo, x0)?;
        draw_legend(&mut c)
    })
}

/// The halo's circle in the drawing's plane, the vertex and the two edges of its cone.
fn draw_halo(c: &mut super::side::Side, halo: &Halo, x0: f32) -> Drawn {
    let (hz, hy) = zy(halo.centre);
    let circle = (0..=96).map(|k| {
        let a = std::f32::consts::TAU * k as f32 / 96.0;
        (hz + halo.radius * a.cos(), hy + halo.radius * a.sin())
    });
    c.draw_series(std::iter::once(PathElement::new(
        circle.collect::<Vec<_>>(),
        NEW.stroke_width(3),
    )))?;
    let at = (hz + halo.radius + 0.05, hy + 0.35);
    label(c, at, (0, 0), "halo: the lamp's bounding sphere")?;
    let x = Vec3::new(x0, VERTEX.1, VERTEX.0);
    let to = halo.centre - x;
    let (d, r) = (to.length(), halo.radius);
    let half = (r / d).asin();
    let axis = (to.z).atan2(to.y);
    for s in [-1.0, 1.0] {
        let a = axis + s * half;
        // to the point where the edge touches the halo
        let t = (d * d - r * r).sqrt();
        let end = (VERTEX.0 + t * a.sin(), VERTEX.1 + t * a.cos());
        let edge = vec![VERTEX, end];
        c.draw_series(DashedLineSeries::new(edge, 8, 5, EYE_PATH.stroke_width(2)))?;
    }
    c.draw_series(std::iter::once(Circle::new(VERTEX, 6, EYE_PATH.filled())))?;
    label(c, VERTEX, (10, 4), "vertex x and its cone")?;
    Ok(())
}

/// Swatches of the map's colours right of the open face, a decade apart.
fn draw_legend(c: &mut super::side::Side) -> Drawn {
    label(c, (1.2, 0.35), (0, 0), "solid angle of the lamp")?;
    let names = [
        "2\u{03C0}",
        "2\u{03C0}/10",
        "2\u{03C0}/10\u{00B2}",
        "2\u{03C0}/10\u{00B3}",
        "2\u{03C0}/10\u{2074}",
    ];
    for (k, name) in names.iter().enumerate() {
        let y = 0.15 - 0.22 * k as f32;
        let omega = std::f64::consts::TAU * 10f64.powi(-(k as i32));
        let swatch = [(1.2, y - 0.16), (1.38, y)];
        c.draw_series(std::iter::once(Rectangle::new(
            swatch,
            colour(omega).filled(),
        )))?;
        label(c, (1.42, y - 0.02), (0, 0), name)?;
    }
    Ok(())
}
