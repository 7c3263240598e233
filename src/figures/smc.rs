//! Pegoraro et al.'s structures from a real SMC run in the fog box (default settings, fixed
//! seed): the octree of directional grids (their Fig. 1) as a slice, and the joint domain
//! Omega_t ∪ Omega_s of eq. (9) at one march step, with the masses kappa_t and kappa_s and the
//! cache's directional pdf.

use std::ops::Range;

use glam::{Vec2, Vec3};
use plotters::prelude::*;

use super::side::{self, Side};
use super::{svg, Area, Drawn, SEED};
use crate::geometry::Ray;
use crate::integrator::smc::cache::RadianceCache;
use crate::integrator::smc::{Scratch, Smc, SmcSettings, DEFAULT_MARCH_STEP_MFP};
use crate::math::Sampler;
use crate::measure::chart::{ChartError, FAMILY};
use crate::scene::Scene;

/// Passes of the run, and camera samples per pass (a 64 x 64 film at 1 spp).
const PASSES: u64 = 16;
const SAMPLES: u64 = 4096;
/// The slice x = X_SLICE (off every octree mid-plane, so each leaf it cuts is one box).
const X_SLICE: f32 = 0.1;

/// SMC on `scene` for `PASSES` passes, each pass's records merged (and leaves refined) before
/// the next, as a render does.
pub fn smc_run(scene: &Scene) -> Option<Smc> {
    let cam = scene.camera.as_ref()?;
    let film = Vec2::new(cam.width as f32, cam.height as f32);
    let mut smc = Smc::new(scene, SmcSettings::default(), None).ok()?;
    let mut scratch = Scratch::default();
    for pass in 0..PASSES {
        let mut records = Vec::new();
        for i in 0..SAMPLES {
            let mut sampler = Sampler::new(SEED, i, 100 + pass);
            let ray = cam.generate_ray(sampler.next_2d() * film);
            let m = scene.camera_medium;
            smc.radiance(scene, ray, m, &mut sampler, &mut scratch, &mut records);
        }
        smc.merge(&records);
    }
    Some(smc)
}

/// Fill colours of the directional grids, by refinement level (root 2 x 1 first).
const LEVELS: [RGBColor; 6] = [
    RGBColor(255, 255, 255),
    RGBColor(222, 235, 247),
    RGBColor(198, 219, 239),
    RGBColor(158, 202, 225),
    RGBColor(107, 174, 214),
    RGBColor(66, 146, 198),
];

fn level(c: &RadianceCache) -> usize {
    (c.grid().n_t.max(1).ilog2() as usize).min(LEVELS.len() - 1)
}

/// A leaf in the slice: its (z, y) corners and its cache.
type Cut<'a> = ((f32, f32), (f32, f32), &'a RadianceCache);

/// The leaves cut by the slice, as (z, y) rectangles with their caches.
fn slice(smc: &Smc) -> Vec<Cut<'_>> {
    smc.octree
        .leaves()
        .into_iter()
        .filter(|(lo, hi, _)| lo.x <= X_SLICE && X_SLICE < hi.x)
        .map(|(lo, hi, c)| (side::zy(lo), side::zy(hi), c))
        .collect()
}

/// The octree slice beside the directional grid of the leaf under the light.
pub(super) fn octree_figure(run: &Option<Smc>) -> Result<String, ChartError> {
    let smc = run
        .as_ref()
        .ok_or_else(|| ChartError::Drawing("octree", "no SMC run".into()))?;
    svg("octree", (1200, 640), |root| {
        let (left, right) = root.split_horizontally(640);
        draw_slice(&left, smc)?;
        let p = Vec3::new(X_SLICE, 0.6, 0.0);
        draw_grid(&right, smc.octree.cache(p), p)
    })
}

fn draw_slice(area: &Area<'_>, smc: &Smc) -> Drawn {
    let view = (-1.05f32..1.05f32, -1.05f32..1.05f32);
    let s = smc.stats();
    let title = format!(
        "Octree slice x = {X_SLICE}: {} leaves, depth {}",
        s.leaves, s.max_depth
    );
    let mut c = side::chart(area, &title, view)?;
    for (lo, hi, cache) in slice(smc) {
        let fill = LEVELS[level(cache)];
        c.draw_series(std::iter::once(Rectangle::new([lo, hi], fill.filled())))?;
        let edge = RGBColor(60, 60, 60).stroke_width(1);
        c.draw_series(std::iter::once(Rectangle::new([lo, hi], edge)))?;
    }
    let marker = Cross::new(
        side::zy(Vec3::new(X_SLICE, 0.6, 0.0)),
        7,
        BLACK.stroke_width(3),
    );
    c.draw_series(std::iter::once(marker))?;
    // each leaf's directional grid n_s x n_t, where the leaf is wide enough for the text
    for (lo, hi, cache) in slice(smc)
        .into_iter()
        .filter(|(lo, hi, _)| hi.0 - lo.0 > 0.2)
    {
        let g = cache.grid();
        let centre = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
        side::label(
            &mut c,
            centre,
            (-18, -8),
            &format!("{}\u{00D7}{}", g.n_s, g.n_t),
        )?;
    }
    Ok(())
}

/// A cache's grid over (s, t), each cell shaded by its pdf coefficient (darker: more).
fn draw_grid(area: &Area<'_>, cache: &RadianceCache, p: Vec3) -> Drawn {
    let g = cache.grid();
    let title = format!(
        "Its directional grid at ({}, {}, {}): {} \u{00D7} {}",
        p.x, p.y, p.z, g.n_s, g.n_t
    );
    let mut c = ChartBuilder::on(area)
        .caption(title, (FAMILY, 20))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(50)
        .build_cartesian_2d(0f32..1f32, 0f32..1f32)?;
    c.configure_mesh()
        .disable_mesh()
        .x_desc("s (azimuth)")
        .y_desc("t (polar)")
        .label_style((FAMILY, 15))
        .axis_desc_style((FAMILY, 17))
        .draw()?;
    let n = g.cells();
    let top = (0..n).map(|i| cache.pdf_coefficient(i)).fold(0.0, f64::max);
    for i in 0..n {
        let (cs, ct) = ((i as u32 % g.n_s) as f32, (i as u32 / g.n_s) as f32);
        let (ws, wt) = (1.0 / g.n_s as f32, 1.0 / g.n_t as f32);
        let v = if top > 0.0 {
            cache.pdf_coefficient(i) / top
        } else {
            0.0
        };
        let shade = (255.0 * (1.0 - 0.85 * v)) as u8;
        let cell = [(cs * ws, ct * wt), ((cs + 1.0) * ws, (ct + 1.0) * wt)];
        c.draw_series(std::iter::once(Rectangle::new(
            cell,
            RGBColor(shade, shade, 255).filled(),
        )))?;
        c.draw_series(std::iter::once(Rectangle::new(cell, BLACK.stroke_width(1))))?;
    }
    Ok(())
}

/// The march step the joint-domain figure shows: the first one on the camera's central ray,
/// from where the ray enters the medium: (its start, its length, kappa_t, kappa_s).
fn first_step(scene: &Scene) -> Option<(Ray, f32, f32, f32)> {
    let cam = scene.camera.as_ref()?;
    let ray = Ray::new(cam.eye, cam.forward);
    let media = crate::path::distance::RayMedia::collect(scene, ray, scene.camera_medium);
    let span = *media.spans().first()?;
    let med = &scene.media[span.medium as usize];
    let here = Ray::new(ray.at(span.t0), ray.d);
    let sigma = med.sigma_t(here.o).x;
    let dx = (DEFAULT_MARCH_STEP_MFP / sigma).min(span.t1 - span.t0);
    let kappa_t = (-med.optical_depth(&here, dx).x).exp();
    let kappa_s = (1.0 - kappa_t) * med.albedo().x;
    Some((here, dx, kappa_t, kappa_s))
}

/// The joint domain at the first march step: the step on the ray, then Omega_t (the
/// transmission direction, mass kappa_t) and Omega_s (the sphere, mass kappa_s spread by the
/// cache's pdf, drawn in the plane x = const).
pub(super) fn joint_domain_figure(scene: &Scene, run: &Option<Smc>) -> Result<String, ChartError> {
    let smc = run
        .as_ref()
        .ok_or_else(|| ChartError::Drawing("joint", "no SMC run".into()))?;
    let (here, dx, kt, ks) = first_step(scene)
        .ok_or_else(|| ChartError::Drawing("joint", "no medium on the central ray".into()))?;
    let cache = smc.octree.cache(here.at(0.5 * dx));
    svg("joint", (1200, 560), |root| {
        let (left, right) = root.split_horizontally(640);
        let v = side::view(scene);
        let mut c = side::chart(&left, "One march step of \u{0394}x = 1 mean free path", v)?;
        side::draw_scene(&mut c, scene)?;
        let step = vec![side::zy(here.o), side::zy(here.at(dx))];
        c.draw_series(std::iter::once(PathElement::new(
            step,
            BLACK.stroke_width(4),
        )))?;
        side::label(&mut c, side::zy(here.o), (-6, -28), "x")?;
        side::label(&mut c, side::zy(here.at(dx)), (-20, -28), "x + \u{0394}x")?;
        draw_domain(&right, cache, here.d, kt, ks)
    })
}

/// Omega_s as the curve r(w) = kappa_s 4 pi p(w) around the circle of directions, Omega_t as
/// a spike of length kappa_t along the ray's direction.
fn draw_domain(area: &Area<'_>, cache: &RadianceCache, d: Vec3, kt: f32, ks: f32) -> Drawn {
    let r: Range<f32> = -1.6..1.6;
    let title = "Its joint domain \u{03A9}t \u{222A} \u{03A9}s";
    let mut c: Side = ChartBuilder::on(area)
        .caption(title, (FAMILY, 22))
        .margin(20)
        .build_cartesian_2d(r.clone(), r)?;
    let ring: Vec<(f32, f32)> = (0..=180)
        .map(|k| {
            let a = std::f32::consts::TAU * k as f32 / 180.0;
            let w = Vec3::new(0.0, a.sin(), a.cos());
            let p = if cache.pdf_is_positive() {
                cache.pdf(w)
            } else {
                0.25 / std::f32::consts::PI
            };
            let rho = ks * 4.0 * std::f32::consts::PI * p;
            (rho * a.cos(), rho * a.sin())
        })
        .collect();
    let unit: Vec<(f32, f32)> = (0..=90)
        .map(|k| std::f32::consts::TAU * k as f32 / 90.0)
        .map(|a| (a.cos(), a.sin()))
        .collect();
    c.draw_series(DashedLineSeries::new(
        unit,
        5,
        5,
        RGBColor(150, 150, 150).stroke_width(1),
    ))?;
    c.draw_series(std::iter::once(PathElement::new(
        ring,
        side::EYE_PATH.stroke_width(3),
    )))?;
    let tip = (d.z * kt, d.y * kt);
    c.draw_series(std::iter::once(PathElement::new(
        vec![(0.0, 0.0), tip],
        side::NEW.stroke_width(5),
    )))?;
    let s_text = format!(
        "\u{03A9}s: mass \u{03BA}s = {ks:.3}, radius \u{221D} \u{03BA}s 4\u{03C0} p(\u{03C9})"
    );
    let t_text = format!("\u{03A9}t: mass \u{03BA}t = e\u{207B}\u{03C3}t\u{0394}x = {kt:.3}");
    side::label(&mut c, (-1.55, -1.25), (0, 0), &s_text)?;
    side::label(&mut c, (-1.55, -1.45), (0, 0), &t_text)?;
    side::label(&mut c, tip, (-10, -26), "\u{03A9}t")?;
    side::label(
        &mut c,
        (-1.55, 1.5),
        (0, 0),
        "directions in the plane x = 0 (dashed: radius 1)",
    )
}
