//! Enlightened sampling's particles in the fog box (Kristensen 2010, eqs. (5.11), (5.12)):
//! photons from the classical light tracer and importons from the camera, as the guide's
//! preprocessing pass traces them, each drawn with a short stroke along its direction; and
//! one of the guide's direction maps built from them.

use glam::Vec3;
use plotters::prelude::*;

use super::side::{self, EYE_PATH, LIGHT_PATH};
use super::{svg, Area, Drawn, SEED};
use crate::bsdf::TransportMode;
use crate::enlightened::direction_map::DirectionMap;
use crate::enlightened::guide::{build_guide, GuideKind, GuideSettings};
use crate::enlightened::particles::{trace_importons, trace_photons, ImportonSource, Particle};
use crate::integrator::bdpt::{Bdpt, Strategies};
use crate::measure::chart::{ChartError, FAMILY};
use crate::path::PLAIN;
use crate::scene::Scene;

/// Subpaths traced on each side.
const PATHS: u64 = 40;
/// Length of a particle's direction stroke, in scene units.
const STROKE: f32 = 0.12;

/// A particle's stroke: from its position towards where it came from.
fn stroke(p: &Particle) -> Vec<(f32, f32)> {
    vec![
        side::zy(p.position),
        side::zy(p.position + STROKE * p.direction),
    ]
}

/// Photons (orange) and importons (blue) of `PATHS` subpaths each.
pub(super) fn figure(scene: &Scene) -> Result<String, ChartError> {
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let photons = trace_photons(scene, &bdpt, PATHS, SEED);
    let importons = trace_importons(scene, &bdpt, ImportonSource::Camera, PATHS, SEED);
    let v = side::view(scene);
    svg("particles", side::size(&v, 1000), |root| {
        let title = format!(
            "Particles of {PATHS} light and {PATHS} eye subpaths: {} photons, {} importons",
            photons.len(),
            importons.len()
        );
        let mut c = side::chart(root, &title, v)?;
        side::draw_scene(&mut c, scene)?;
        for (set, colour) in [(&photons, LIGHT_PATH), (&importons, EYE_PATH)] {
            c.draw_series(
                set.iter()
                    .map(|p| PathElement::new(stroke(p), colour.stroke_width(2))),
            )?;
            c.draw_series(set.iter().map(|p| {
                EmptyElement::at(side::zy(p.position)) + Circle::new((0, 0), 3, colour.filled())
            }))?;
        }
        side::label(
            &mut c,
            (1.3, -0.5),
            (0, 0),
            "orange: photons, samples of L\u{1D62}",
        )?;
        side::label(
            &mut c,
            (1.3, -0.7),
            (0, 0),
            "blue: importons, samples of W\u{1D62}",
        )?;
        side::label(
            &mut c,
            (1.3, -0.9),
            (0, 0),
            "strokes: the incident direction",
        )
    })
}

/// Photons the guide of the figure traces (the default is 200 000; a figure needs fewer).
const GUIDE_PARTICLES: usize = 20_000;

/// The radiance map that guides eye subpaths at the medium vertex x₂ of Fig. 2's path
/// (volume guiding, default maps and regions): texel weights over (φ, cos θ), with the
/// direction from x₂ to the light's centre marked.
pub(super) fn guide_figure(scene: &Scene) -> Result<String, ChartError> {
    let fail = |s: &str| ChartError::Drawing("guide", s.to_string());
    let x = super::figure_2_path(scene).ok_or_else(|| fail("no path"))?;
    let mut settings = GuideSettings::for_radius(scene.radius);
    settings.kind = GuideKind::Volume;
    settings.particles = GUIDE_PARTICLES;
    settings.seed = SEED;
    let guide = build_guide(scene, &PLAIN, settings);
    let (map, _) = guide
        .map_at(scene, &x[2], TransportMode::Radiance)
        .ok_or_else(|| fail("no map at x2"))?;
    let to_light = (Vec3::new(0.0, 1.0, 0.0) - x[2].p).normalize();
    svg("guide", (1000, 560), |root| {
        draw_map(root, map, map.texel_of(to_light))
    })
}

fn draw_map(root: &Area<'_>, map: &DirectionMap, light: (u32, u32)) -> Drawn {
    let (cols, rows) = (map.cols(), map.rows());
    let title =
        format!("Radiance map at x\u{2082} of Fig. 2: {cols} \u{00D7} {rows} equal-area texels");
    let mut c = ChartBuilder::on(root)
        .caption(title, (FAMILY, 22))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0f32..cols as f32, -1f32..1f32)?;
    c.configure_mesh()
        .disable_mesh()
        .x_desc("\u{03C6} (texel column)")
        .y_desc("cos \u{03B8} (\u{03B8} from +z)")
        .label_style((FAMILY, 15))
        .axis_desc_style((FAMILY, 17))
        .draw()?;
    let top = (0..rows)
        .flat_map(|r| (0..cols).map(move |k| (k, r)))
        .map(|(k, r)| map.weight(k, r))
        .fold(0.0, f32::max);
    let h = 2.0 / rows as f32;
    let texels = (0..rows).flat_map(|r| (0..cols).map(move |k| (k, r)));
    let lit = texels.filter(|&(k, r)| map.weight(k, r) > 0.0);
    c.draw_series(lit.map(|(k, r)| {
        let v = map.weight(k, r) / top;
        let shade = (255.0 * (1.0 - 0.9 * v)) as u8;
        let y = -1.0 + r as f32 * h;
        Rectangle::new(
            [(k as f32, y), (k as f32 + 1.0, y + h)],
            RGBColor(255, shade, shade / 2 + 127).filled(),
        )
    }))?;
    let centre = (light.0 as f32 + 0.5, -1.0 + (light.1 as f32 + 0.5) * h);
    c.draw_series(std::iter::once(Cross::new(
        centre,
        8,
        BLACK.stroke_width(3),
    )))?;
    let font = (FAMILY, 17).into_font();
    c.draw_series(std::iter::once(
        EmptyElement::at(centre) + Text::new("towards the light", (10, -22), font),
    ))?;
    Ok(())
}
