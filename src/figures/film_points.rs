//! Sixteen film positions in one pixel (book: "Measuring a renderer", "Stratified film
//! positions"): drawn independently from the pixel's stream as the render loop draws them, and
//! as the pixel's first sixteen stratified points, each over the 4 x 4 cells the stratified
//! ones fill once each, with an edge across the pixel and the share of the pixel below it that
//! each set estimates.

use plotters::prelude::*;

use super::side::{EYE_PATH, LIGHT, OLD};
use super::{svg, Area, Drawn};
use crate::math::sampler::{film_shift, stratified_point};
use crate::math::Sampler;
use crate::measure::chart::{ChartError, FAMILY};

/// Points per panel.
const POINTS: u32 = 16;
/// The edge across the pixel: y = EDGE.0 + EDGE.1 x.
const EDGE: (f32, f32) = (0.18, 0.55);

/// Offsets in a pixel, (x, y) in [0, 1)^2.
pub type Offsets = Vec<(f32, f32)>;

/// Pixels over which the figure measures each kind's error.
const PIXELS: u64 = 1000;

/// Pixel `pixel`'s first sixteen offsets under the figures' seed: independent, as the render
/// loop draws them (four a pass from the streams of passes 0 to 3), and stratified.
pub fn film_points(pixel: u64) -> (Offsets, Offsets) {
    let seed = super::SEED;
    let independent = (0..POINTS as u64 / 4)
        .flat_map(|pass| {
            let mut s = Sampler::new(seed, pixel, pass);
            (0..4).map(move |_| {
                let u = s.next_2d();
                (u.x, u.y)
            })
        })
        .collect();
    let shift = film_shift(seed, pixel);
    let stratified = (0..POINTS)
        .map(|k| {
            let u = stratified_point(k, shift);
            (u.x, u.y)
        })
        .collect();
    (independent, stratified)
}

/// The root mean square error of each kind's share below the edge over [`PIXELS`] pixels.
fn rms_errors(exact: f32) -> (f32, f32) {
    let (mut a, mut b) = (0.0, 0.0);
    for pixel in 0..PIXELS {
        let (i, s) = film_points(pixel);
        a += (share(&i) - exact).powi(2);
        b += (share(&s) - exact).powi(2);
    }
    ((a / PIXELS as f32).sqrt(), (b / PIXELS as f32).sqrt())
}

/// The share of the points below the edge.
fn share(points: &[(f32, f32)]) -> f32 {
    let below = points
        .iter()
        .filter(|p| p.1 < EDGE.0 + EDGE.1 * p.0)
        .count();
    below as f32 / points.len() as f32
}

/// The two panels side by side.
pub(super) fn figure() -> Result<String, ChartError> {
    let (independent, stratified) = film_points(0);
    // the exact share of the unit square below the edge (it stays inside the square)
    let exact = EDGE.0 + 0.5 * EDGE.1;
    let (rms_i, rms_s) = rms_errors(exact);
    svg("film-points", (760, 450), |root| {
        let (top, bottom) = root.split_vertically(420);
        let panels = top.split_evenly((1, 2));
        let caption = |name: &str, p: &[(f32, f32)]| {
            format!("{name}: {:.3} below (exact {exact:.3})", share(p))
        };
        panel(
            &panels[0],
            &caption("independent", &independent),
            &independent,
            OLD,
        )?;
        panel(
            &panels[1],
            &caption("stratified", &stratified),
            &stratified,
            EYE_PATH,
        )?;
        let text = format!(
            "rms error of the share over {PIXELS} pixels: independent {rms_i:.3}, stratified {rms_s:.3}"
        );
        bottom.draw(&Text::new(text, (40, 5), (FAMILY, 17).into_font()))?;
        Ok(())
    })
}

/// One panel: the pixel, its 4 x 4 cells, the edge and the points.
fn panel(area: &Area<'_>, caption: &str, points: &[(f32, f32)], colour: RGBColor) -> Drawn {
    let mut c = ChartBuilder::on(area)
        .caption(caption, (FAMILY, 18))
        .margin(20)
        .build_cartesian_2d(0f32..1f32, 0f32..1f32)?;
    let grid = OLD.mix(0.6).stroke_width(1);
    for k in 0..=4 {
        let t = k as f32 / 4.0;
        c.draw_series(std::iter::once(PathElement::new(
            vec![(t, 0.0), (t, 1.0)],
            grid,
        )))?;
        c.draw_series(std::iter::once(PathElement::new(
            vec![(0.0, t), (1.0, t)],
            grid,
        )))?;
    }
    let edge = vec![(0.0, EDGE.0), (1.0, EDGE.0 + EDGE.1)];
    c.draw_series(std::iter::once(PathElement::new(
        edge,
        LIGHT.stroke_width(3),
    )))?;
    c.draw_series(points.iter().map(|&p| Circle::new(p, 5, colour.filled())))?;
    Ok(())
}
