//! The light a medium point receives from the fog box's quad light, estimated the three ways
//! the book's "Sampling toward lights", section "The light point", compares: the light sample
//! drawn by area alone, that sample weighed against an isotropic phase sample by the power
//! heuristic (the path tracer with `light_point = "area"`), and the light sample drawn by solid
//! angle near the quad in the same pairing (the default). Each estimator's variance over its
//! squared mean, at points below the light's centre, against their height under it; the
//! transmittance is left out (1) so that only the light's geometry is seen.

use glam::Vec3;
use plotters::prelude::*;

use super::side::{EYE_PATH, NEW, OLD};
use super::{svg, Area, Drawn};
use crate::geometry::{Primitive, Ray};
use crate::integrator::path::power_heuristic;
use crate::math::{warp, Sampler};
use crate::measure::chart::{ChartError, FAMILY};
use crate::scene::light::LightPointDraw;
use crate::scene::{Light, Scene};

/// Heights below the light at which the estimators are sampled (log-spaced, metres).
const HEIGHTS: std::ops::Range<i32> = -30..1;
/// Samples per estimator and height.
const SAMPLES: u64 = 20_000;
/// The isotropic phase function's value and density.
const F_P: f32 = warp::INV_FOUR_PI;

/// One estimator's curve: its name, colour and (height, variance over squared mean) points.
struct Curve {
    name: &'static str,
    colour: RGBColor,
    points: Vec<(f64, f64)>,
}

/// The fog box's area light and its (only) quad.
fn the_light(scene: &Scene) -> Option<(&Light, u32, &Primitive)> {
    scene.lights.iter().find_map(|l| match l {
        Light::Area { prims, .. } if prims.len() == 1 => {
            Some((l, prims[0], &scene.prims[prims[0] as usize]))
        }
        _ => None,
    })
}

/// One sample of the light arriving at `x` (per unit radiance): `mis` pairs the light
/// sample drawn by `draw` with a phase sample by the power heuristic; without it, the light
/// sample alone.
fn estimate(scene: &Scene, x: Vec3, draw: LightPointDraw, mis: bool, s: &mut Sampler) -> f64 {
    let (light, prim, shape) = the_light(scene).expect("the fog box has a quad light");
    let mut sum = 0.0;
    let u = (s.next_2d(), s.next_f32());
    if let Some(ls) = light.sample_li(&scene.prims, x, u, draw) {
        let w = if mis {
            power_heuristic(ls.pdf, F_P)
        } else {
            1.0
        };
        sum += (F_P * w / ls.pdf) as f64;
    }
    if mis {
        let wi = warp::uniform_sphere(s.next_2d());
        if let Some((_, p, n)) = shape.intersect(&Ray::new(x, wi), f32::INFINITY) {
            let pdf_light = light.pdf_li(&scene.prims, x, (p, n, prim), draw);
            if pdf_light > 0.0 {
                sum += (F_P * power_heuristic(F_P, pdf_light) / F_P) as f64;
            }
        }
    }
    sum
}

/// The variance over the squared mean of `SAMPLES` estimates at each height.
fn curve(scene: &Scene, draw: LightPointDraw, mis: bool, stream: u64) -> Vec<(f64, f64)> {
    let (_, _, shape) = the_light(scene).expect("the fog box has a quad light");
    let Primitive::Quad(q) = shape else {
        return Vec::new();
    };
    let centre = q.origin + 0.5 * (q.u + q.v);
    HEIGHTS
        .map(|k| {
            let h = 10f64.powf(k as f64 / 10.0);
            let x = centre + q.n * h as f32;
            let mut s = Sampler::new(super::SEED, stream, (k - HEIGHTS.start) as u64);
            let (mut m1, mut m2) = (0.0, 0.0);
            for _ in 0..SAMPLES {
                let e = estimate(scene, x, draw, mis, &mut s);
                (m1, m2) = (m1 + e, m2 + e * e);
            }
            let mean = m1 / SAMPLES as f64;
            (
                h,
                (m2 / SAMPLES as f64 - mean * mean).max(1e-6 * mean * mean) / (mean * mean),
            )
        })
        .collect()
}

/// The three curves on log-log axes, the near region's edge marked.
pub(super) fn figure(scene: &Scene) -> Result<String, ChartError> {
    let curves = [
        Curve {
            name: "light sample by area, alone",
            colour: OLD,
            points: curve(scene, LightPointDraw::Area, false, 0),
        },
        Curve {
            name: "by area, with a phase sample (MIS)",
            colour: EYE_PATH,
            points: curve(scene, LightPointDraw::Area, true, 1),
        },
        Curve {
            name: "by solid angle near the quad, with a phase sample (MIS)",
            colour: NEW,
            points: curve(scene, LightPointDraw::SolidAngleNear, true, 2),
        },
    ];
    let edge = the_light(scene).map_or(0.0, |(_, _, p)| {
        (crate::scene::light::NEAR_AREA_FACTOR * p.area()).sqrt() as f64
    });
    svg("light-point", (1000, 560), |root| draw(root, &curves, edge))
}

fn draw(root: &Area<'_>, curves: &[Curve], edge: f64) -> Drawn {
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Light reaching a point below the fog box's lamp: variance / mean\u{00B2} of one sample",
            (FAMILY, 22),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((1e-3f64..1.0f64).log_scale(), (1e-4f64..1e4f64).log_scale())?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("height h of the point below the lamp's centre (m)")
        .y_desc("variance / mean\u{00B2}")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style((FAMILY, 16))
        .axis_desc_style((FAMILY, 18))
        .draw()?;
    for c in curves {
        let colour = c.colour;
        chart
            .draw_series(LineSeries::new(c.points.clone(), colour.stroke_width(3)))?
            .label(c.name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
    }
    let dashed = BLACK.mix(0.5).stroke_width(1);
    chart.draw_series(DashedLineSeries::new(
        vec![(edge, 1e-4), (edge, 1e4)],
        6,
        4,
        dashed,
    ))?;
    chart.draw_series(std::iter::once(Text::new(
        "near: by solid angle \u{2190}",
        (edge * 0.22, 3e3),
        (FAMILY, 15).into_font(),
    )))?;
    chart
        .configure_series_labels()
        .label_font((FAMILY, 16))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()?;
    Ok(())
}
