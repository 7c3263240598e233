//! The figure of the GGX lobes in the book's chapter "Surface scattering" (section "Rough
//! surfaces"): f_s(wo, wi) |cos theta_i| over the plane of incidence, as a polar plot (the
//! radius in a direction is the value there), each curve scaled to its own maximum.
//! Run with `cargo run --release --example bsdf_lobes -- book/src/figures/bsdf/ggx-lobes.svg`.

use std::f32::consts::PI;

use glam::Vec3;
use pathspace::bsdf::{
    Bsdf, ConductorFresnel, Distribution, RoughConductor, RoughDielectric, TransportMode,
};
use pathspace::measure::chart::{register_font, FAMILY};
use plotters::prelude::*;

/// The angle of incidence, from the normal (degrees).
const THETA_O_DEG: f32 = 50.0;
/// Directions sampled over the full circle of the plane of incidence.
const STEPS: usize = 2000;

/// The lobe f_s(wo, wi) |cos theta_i| (first channel) at the angle `phi` from the normal
/// (the plane of incidence is x-y, the normal +y), as a point of the polar plot.
fn lobe(bsdf: &Bsdf, wo: Vec3) -> Vec<(f32, f32)> {
    let n = Vec3::Y;
    (0..=STEPS)
        .map(|k| {
            let phi = 2.0 * PI * k as f32 / STEPS as f32;
            let wi = Vec3::new(phi.sin(), phi.cos(), 0.0);
            let v = bsdf.eval(wo, wi, n, TransportMode::Radiance).x * wi.dot(n).abs();
            (v * wi.x, v * wi.y)
        })
        .collect()
}

/// The curve scaled so that its farthest point is at radius 1.
fn unit(points: Vec<(f32, f32)>) -> Vec<(f32, f32)> {
    let r = points
        .iter()
        .map(|(x, y)| x.hypot(*y))
        .fold(0.0f32, f32::max);
    points.into_iter().map(|(x, y)| (x / r, y / r)).collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).ok_or("usage: bsdf_lobes OUT.svg")?;
    register_font()?;
    let t = THETA_O_DEG.to_radians();
    // wo on the left of the normal, so the mirror direction is on the right
    let wo = Vec3::new(-t.sin(), t.cos(), 0.0);
    let conductor = |alpha| {
        Bsdf::RoughConductor(RoughConductor {
            distribution: Distribution::Ggx,
            alpha,
            fresnel: ConductorFresnel::Schlick(Vec3::ONE),
            specular: Vec3::ONE,
            one_sided: false,
            anisotropy: None,
        })
    };
    let root = SVGBackend::new(&out, (900, 720)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("GGX lobes, incidence {THETA_O_DEG} degrees (each scaled to its maximum)"),
            (FAMILY, 22),
        )
        .margin(20)
        .build_cartesian_2d(-1.3f32..1.3f32, -1.0f32..0.95f32)?;
    let style = |c: RGBColor| c.stroke_width(3);
    let grey = RGBColor(120, 120, 120);
    chart.draw_series(LineSeries::new(
        [(-1.3, 0.0), (1.3, 0.0)],
        grey.stroke_width(2),
    ))?;
    chart.draw_series(LineSeries::new(
        [(wo.x, wo.y), (0.0, 0.0)],
        BLACK.stroke_width(2),
    ))?;
    let curves = [
        (
            "conductor, alpha 0.05",
            conductor(0.05),
            RGBColor(230, 97, 1),
        ),
        (
            "conductor, alpha 0.15",
            conductor(0.15),
            RGBColor(94, 60, 153),
        ),
        (
            "conductor, alpha 0.4",
            conductor(0.4),
            RGBColor(27, 158, 119),
        ),
        (
            "dielectric 1.5, alpha 0.15",
            Bsdf::RoughDielectric(RoughDielectric {
                ior: 1.5,
                distribution: Distribution::Ggx,
                alpha: 0.15,
                specular: pathspace::bsdf::Specular::ONE,
                anisotropy: None,
            }),
            RGBColor(33, 102, 172),
        ),
    ];
    for (name, bsdf, colour) in curves {
        chart
            .draw_series(LineSeries::new(unit(lobe(&bsdf, wo)), style(colour)))?
            .label(name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], style(colour)));
    }
    chart
        .configure_series_labels()
        .label_font((FAMILY, 18))
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE)
        .border_style(grey)
        .draw()?;
    root.present()?;
    Ok(())
}
