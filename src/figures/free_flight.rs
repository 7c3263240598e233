//! Table 1's outcome space: a free flight along a medium segment of length d ends at a
//! collision t in [0, d), with density sigma_t(t) T(t), or at the surface, with probability
//! T(d): a continuous part and a Dirac. Drawn from the medium's own sigma_t and exact
//! transmittance, with a histogram of flights drawn by `Medium::sample_free_flight`.

use plotters::prelude::*;

use super::side::Side;
use super::{svg, Area, Drawn, SEED};
use crate::geometry::Ray;
use crate::math::Sampler;
use crate::measure::chart::{ChartError, FAMILY};
use crate::path::distance::RayMedia;
use crate::scene::Scene;

/// Flights drawn for the histogram.
const FLIGHTS: u64 = 4000;
/// Histogram bins over [0, d).
const BINS: usize = 40;

/// The outcome space of one segment: the density curve, the mass at d, and the sampled flights.
struct Outcomes {
    d: f32,
    density: Vec<(f32, f32)>,
    surface_mass: f32,
    histogram: Vec<f32>,
    passed: f32,
}

/// The first medium segment of the camera's central ray, sampled `FLIGHTS` times.
fn outcomes(scene: &Scene) -> Option<Outcomes> {
    let cam = scene.camera.as_ref()?;
    let ray = Ray::new(cam.eye, cam.forward);
    let media = RayMedia::collect(scene, ray, scene.camera_medium);
    let s = *media.spans().first()?;
    let med = &scene.media[s.medium as usize];
    let seg = Ray::new(ray.at(s.t0), ray.d);
    let d = s.t1 - s.t0;
    let density = (0..=400)
        .map(|k| {
            let t = d * k as f32 / 400.0;
            (
                t,
                med.sigma_t(seg.at(t)).x * med.transmittance_exact(&seg, t).x,
            )
        })
        .collect();
    let mut histogram = vec![0.0; BINS];
    let mut passed = 0.0;
    let w = d / BINS as f32;
    for k in 0..FLIGHTS {
        let ff = med.sample_free_flight(&seg, d, &mut Sampler::new(SEED, k, 3));
        if ff.scattered {
            histogram[((ff.t / w) as usize).min(BINS - 1)] += 1.0 / (FLIGHTS as f32 * w);
        } else {
            passed += 1.0 / FLIGHTS as f32;
        }
    }
    Some(Outcomes {
        d,
        density,
        surface_mass: med.transmittance_exact(&seg, d).x,
        histogram,
        passed,
    })
}

/// The outcome space of the central ray's first medium segment in `scene`.
pub(super) fn figure(scene: &Scene) -> Result<String, ChartError> {
    let o = outcomes(scene)
        .ok_or_else(|| ChartError::Drawing("free-flight", "no medium on the central ray".into()))?;
    svg("free-flight", (900, 480), |root| draw(root, &o))
}

fn draw(root: &Area<'_>, o: &Outcomes) -> Drawn {
    let top = o.density.iter().map(|p| p.1).fold(o.surface_mass, f32::max);
    let top = o.histogram.iter().copied().fold(top, f32::max) * 1.15;
    let mut chart = ChartBuilder::on(root)
        .caption(
            "Outcomes of a free flight over [0, d]: density \u{03C3}t \u{03C4}(t) and the Dirac \u{03C4}(d) at the surface",
            (FAMILY, 20),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0f32..o.d * 1.12, 0f32..top)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("distance t along the segment (d = its length)")
        .y_desc("density (mass at t = d)")
        .label_style((FAMILY, 16))
        .axis_desc_style((FAMILY, 18))
        .draw()?;
    let w = o.d / BINS as f32;
    let grey = RGBColor(190, 190, 190);
    chart
        .draw_series(o.histogram.iter().enumerate().map(|(i, &h)| {
            let x = i as f32 * w;
            Rectangle::new([(x, 0.0), (x + w, h)], grey.filled())
        }))?
        .label(format!(
            "collisions of {FLIGHTS} sampled flights (histogram)"
        ))
        .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 20, y + 6)], grey.filled()));
    let blue = RGBColor(33, 102, 172);
    chart
        .draw_series(LineSeries::new(o.density.clone(), blue.stroke_width(3)))?
        .label("\u{03C3}t(t) \u{03C4}(t), from the medium's \u{03C3}t and exact \u{03C4}")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue.stroke_width(3)));
    draw_dirac(&mut chart, o, top)?;
    chart
        .configure_series_labels()
        .label_font((FAMILY, 16))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

/// The point mass at t = d: an arrow of height T(d), and the fraction of flights that passed.
fn draw_dirac(chart: &mut Side, o: &Outcomes, top: f32) -> Drawn {
    let red = RGBColor(178, 24, 43);
    let (d, m) = (o.d, o.surface_mass);
    let head = o.d * 0.015;
    let arrow = vec![
        (d, 0.0),
        (d, m),
        (d - head, m * 0.96),
        (d, m),
        (d + head, m * 0.96),
    ];
    chart
        .draw_series(std::iter::once(PathElement::new(
            arrow,
            red.stroke_width(3),
        )))?
        .label(format!(
            "surface: \u{03C4}(d) = {m:.3}; flights that passed: {:.3}",
            o.passed
        ))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(3)));
    let font = (FAMILY, 17).into_font().color(&red);
    chart.draw_series(std::iter::once(Text::new(
        "\u{03C4}(d) \u{03B4}(t \u{2212} d)",
        (d * 0.78, m + 0.05 * top),
        font,
    )))?;
    Ok(())
}
