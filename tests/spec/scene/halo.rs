//! The halo cone (`src/scene/halo.rs`): a light's halo is its bounding sphere, the cone from a
//! point outside it is drawn uniformly, and the path tracer's mixture of that cone with the
//! phase function (or a BSDF's own sampling) draws its directions by exactly the density
//! [`HaloMixture::pdf`] gives, which every MIS weight of the walk takes. The checks are
//! identities of importance sampling: E[g / p] = the integral of g over the sphere, for g = 1
//! and for g the indicator of a cone, with the mixture's own samples.
//! Book: "Sampling toward lights", section "The scattering direction: a cone toward the halo".

use crate::common;

use super::light_point::{lamp_with, CAMERA};
use common::stats::Family;
use glam::Vec3;
use pathspace::math::{warp, Frame, Sampler};
use pathspace::medium::phase::Phase;
use pathspace::scene::halo::{Halo, HaloMixture};
use pathspace::scene::light_tree::{LightBounds, LightSelection};
use pathspace::scene::{LightSelectionKind, Scene, SceneSource};
use std::f64::consts::PI;

/// A second, smaller quad lamp on the wall x = -2, facing +x.
const SECOND: &str = r#"
[[shapes]]
type = "quad"
origin = [-2.0, -0.2, -0.2]
u = [0.0, 0.4, 0.0]
v = [0.0, 0.0, 0.4]
emission = [30.0, 30.0, 30.0]
"#;

/// A point light, which has no halo: its share of the selection falls back to the vertex's own
/// sampling.
const POINT: &str = r#"
[[lights]]
type = "point"
position = [0.5, 0.0, 0.5]
intensity = [5.0, 5.0, 5.0]
"#;

fn halo_of(scene: &Scene, l: usize) -> Option<Halo> {
    LightBounds::of(&scene.lights[l], &scene.prims, 1.0).and_then(|b| Halo::of(&b))
}

/// The solid angle of a ball of radius r whose centre is at distance d: 2 pi (1 - cos),
/// sin = r / d.
fn cone_solid_angle(d: f64, r: f64) -> f64 {
    2.0 * PI * (1.0 - (1.0 - (r / d).powi(2)).sqrt())
}

/// A quad light's halo is its bounding sphere: the box's centre and half its diagonal; a point
/// light has none, and a scene of point lights gets no mixture (the phase function alone).
#[test]
fn a_halo_is_the_bounding_sphere_of_an_area_light() {
    let scene = lamp_with("");
    let h = halo_of(&scene, 0).expect("a quad light has a halo");
    assert!(
        (h.centre - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6,
        "{h:?}"
    );
    let half_diagonal = 0.5 * (1.0f32 + 0.36).sqrt();
    assert!((h.radius - half_diagonal).abs() < 1e-6, "{h:?}");
    let point = format!(
        "{CAMERA}{}",
        "\n[[lights]]\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = [1.0, 1.0, 1.0]\n"
    );
    let point = Scene::load(&SceneSource::embedded("point.toml", &point)).unwrap();
    assert_eq!(halo_of(&point, 0), None);
    assert!(HaloMixture::new(&point, 0.5).is_none());
    assert!(HaloMixture::new(&scene, 0.0).is_none());
    assert!(HaloMixture::new(&scene, 0.1).is_some());
}

/// From points outside the halo, the cone's directions all meet the ball, their cosines to
/// the axis are uniform in [cos_max, 1] and their azimuths uniform (Kolmogorov-Smirnov), and
/// the density is one over the closed-form solid angle; inside the ball there is no cone.
#[test]
fn cone_directions_are_uniform_over_the_halo() {
    let scene = lamp_with("");
    let h = halo_of(&scene, 0).unwrap();
    let mut fam = Family::new("halo cone");
    let mut s = Sampler::new(3, 0, 0);
    for (k, p) in [Vec3::new(0.3, 0.0, 0.2), Vec3::new(-3.0, -2.0, 5.0)]
        .into_iter()
        .enumerate()
    {
        let cone = h.cone(p).expect("p is outside the halo");
        let to = (h.centre - p).as_dvec3();
        let (d, r) = (to.length(), h.radius as f64);
        let omega = cone_solid_angle(d, r);
        let rel = (cone.pdf_inside() as f64 * omega - 1.0).abs();
        assert!(rel < 1e-4, "density x solid angle - 1 = {rel}");
        let cos_max = (1.0 - (r / d).powi(2)).sqrt();
        let frame = Frame::from_normal((to / d).as_vec3());
        let (mut cosines, mut azimuths) = (Vec::new(), Vec::new());
        for _ in 0..20_000 {
            let w = cone.sample(s.next_2d());
            assert!(cone.pdf(w) > 0.0, "a drawn direction is inside its cone");
            // the ray p + t w meets the ball: the distance of the centre to the line <= r
            let w64 = w.as_dvec3();
            let miss = (to - w64 * to.dot(w64)).length();
            assert!(
                miss <= r * (1.0 + 1e-4) && to.dot(w64) > 0.0,
                "{miss} > {r}"
            );
            let local = frame.to_local(w).as_dvec3();
            cosines.push(local.z);
            azimuths.push(local.y.atan2(local.x).rem_euclid(2.0 * PI));
        }
        let uniform_cos = |c: f64| ((c - cos_max) / (1.0 - cos_max)).clamp(0.0, 1.0);
        fam.ks(&format!("point {k}: cosines"), &mut cosines, uniform_cos);
        fam.ks(&format!("point {k}: azimuths"), &mut azimuths, |a| {
            (a / (2.0 * PI)).clamp(0.0, 1.0)
        });
    }
    assert!(h.cone(h.centre + Vec3::new(0.1, -0.2, 0.0)).is_none());
    fam.finish();
}

/// One direction of the mixture at `p` (normal `n`), drawn as the path tracer draws it: the
/// cone, or else the vertex's own sampling (the phase function in a medium, the cosine lobe
/// about `n` at a surface); with its density and the own density's support.
fn mixture_sample(
    m: &HaloMixture,
    (scene, sel): (&Scene, &LightSelection),
    (p, n): (Vec3, Option<Vec3>),
    phase: &Phase,
    s: &mut Sampler,
) -> (Vec3, f64) {
    let wo = Vec3::new(0.0, 0.0, 1.0);
    let own_pdf = |wi: Vec3| match n {
        None => phase.eval(wo, wi),
        Some(n) => (wi.dot(n).max(0.0)) / std::f32::consts::PI,
    };
    let wi = match m.draw(scene, sel, (p, n), s) {
        Ok(wi) => wi,
        Err(u) => match n {
            None => phase.sample(wo, u).wi,
            Some(n) => Frame::from_normal(n).to_world(warp::cosine_hemisphere(u)),
        },
    };
    let pdf = m.pdf(scene, sel, (p, n), own_pdf(wi), wi);
    (wi, pdf as f64)
}

/// The mixture draws by the density it reports, for the quad lamp of `light_point` alone, with
/// a second quad (the two chosen by the light tree) and with a point light (which has no
/// halo), in a medium (Henyey-Greenstein, g = 0.6) and at a surface (the cosine lobe), from
/// points near a halo, far from it and inside it: over the mixture's own samples the mean of
/// 1 / p is the measure of the support (4 pi in a medium, 2 pi at a surface) and the mean of
/// 1[w in the first light's cone] / p is that cone's solid angle. A density without the
/// selection's probability, without the phase share or with the cone's density off by any
/// factor fails one of them.
#[test]
fn the_mixture_draws_by_the_density_it_reports() {
    let phase = Phase::henyey_greenstein(0.6).unwrap();
    let mut fam = Family::new("halo mixture");
    let mut s = Sampler::new(17, 0, 0);
    let n_up = Some(Vec3::Y);
    let cases = [
        ("", Vec3::new(0.2, 0.2, 0.1), None),
        ("", Vec3::new(0.1, 0.8, 0.0), None),
        (SECOND, Vec3::new(-1.0, -0.5, 0.4), None),
        (SECOND, Vec3::new(-0.5, -1.0, 0.0), n_up),
        (SECOND, Vec3::new(3.0, -2.0, 1.0), None),
        (POINT, Vec3::new(0.3, -0.4, 0.2), None),
        (POINT, Vec3::new(-0.5, -1.0, 0.0), n_up),
    ];
    for (k, (more, p, n)) in cases.into_iter().enumerate() {
        let scene = lamp_with(more);
        let sel = LightSelection::build(LightSelectionKind::Tree, &scene);
        let m = HaloMixture::new(&scene, 0.3).unwrap();
        let h = halo_of(&scene, 0).unwrap();
        let cone = h.cone(p);
        let (mut inv, mut ind) = ((0.0, 0.0), (0.0, 0.0));
        let runs = 200_000u64;
        for _ in 0..runs {
            let (wi, pdf) = mixture_sample(&m, (&scene, &sel), (p, n), &phase, &mut s);
            assert!(pdf > 0.0, "case {k}: a drawn direction has a density");
            let x = 1.0 / pdf;
            inv = (inv.0 + x, inv.1 + x * x);
            let y = match cone {
                Some(c) if c.pdf(wi) > 0.0 && n.is_none_or(|n| wi.dot(n) > 0.0) => x,
                _ => 0.0,
            };
            ind = (ind.0 + y, ind.1 + y * y);
        }
        let stats = |(sum, sum2): (f64, f64)| {
            let mean = sum / runs as f64;
            (mean, sum2 / runs as f64 - mean * mean)
        };
        let support = if n.is_some() { 2.0 * PI } else { 4.0 * PI };
        let (mean, var) = stats(inv);
        fam.samples_are(
            &format!("case {k}: mean of 1 / p"),
            mean,
            var,
            runs,
            support,
        );
        if let (Some(_), None) = (cone, n) {
            let to = (h.centre - p).as_dvec3();
            let omega = cone_solid_angle(to.length(), h.radius as f64);
            let (mean, var) = stats(ind);
            let what = format!("case {k}: the cone's solid angle");
            fam.samples_are(&what, mean, var, runs, omega);
        }
    }
    fam.finish();
}

/// The density at a point inside the only halo is the phase function's: every light's share
/// falls back to it.
#[test]
fn inside_the_halo_the_density_is_the_phase_functions() {
    let scene = lamp_with("");
    let sel = LightSelection::build(LightSelectionKind::Tree, &scene);
    let m = HaloMixture::new(&scene, 0.4).unwrap();
    let phase = Phase::henyey_greenstein(0.3).unwrap();
    let p = Vec3::new(0.1, 0.9, 0.0);
    let wo = Vec3::new(0.0, 0.0, 1.0);
    let mut s = Sampler::new(5, 0, 0);
    for _ in 0..100 {
        let wi = warp::uniform_sphere(s.next_2d());
        let f = phase.eval(wo, wi);
        let pdf = m.pdf(&scene, &sel, (p, None), f, wi);
        assert!((pdf - f).abs() <= 1e-6 * f, "{pdf} against {f}");
    }
}
