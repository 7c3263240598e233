//! Executable specification of the smooth conductor and Mitsuba 3's named conductors
//! (`src/bsdf/{conductor, named_conductor}.rs`; book: "Surface scattering", "Importing
//! scenes").
//!
//! The smooth conductor's Dirac weight is `specular` times the complex-index Fresnel term,
//! whose identities it must show through the BSDF: with k = 0 the dielectric's reflectance,
//! at normal incidence ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2), at grazing incidence 1; Mitsuba's
//! material `none` (eta 0, k 1) a perfect mirror. The named table holds the f32 values a
//! Mitsuba 3 `conductor` with that `material` holds in its RGB variants.

use crate::common;

use common::*;
use glam::{Vec2, Vec3};
use pathspace::bsdf::named_conductor::{named_conductor, NAMED_CONDUCTORS};
use pathspace::bsdf::{fresnel_dielectric, reflect, Bsdf, Conductor, Lobe, TransportMode};
use pathspace::spectrum::Rgb;

fn conductor(eta: Rgb, k: Rgb, specular: Rgb) -> Bsdf {
    Bsdf::Conductor(Conductor {
        eta,
        k,
        specular,
        one_sided: false,
    })
}

/// The weight value |cos wi| / pdf of the conductor's one sample at incidence cosine `c`,
/// after checking the sample is the mirror direction, a Dirac with probability 1.
fn weight(bsdf: &Bsdf, c: f32) -> Rgb {
    let n = Vec3::Z;
    let wo = Vec3::new((1.0 - c * c).max(0.0).sqrt(), 0.0, c);
    let s = bsdf
        .sample(wo, n, Vec2::new(0.3, 0.7), 0.5, TransportMode::Radiance)
        .expect("a conductor reflects");
    assert_eq!(s.lobe, Lobe::SingularReflection);
    assert_eq!(s.pdf, 1.0);
    assert!((s.wi - reflect(wo, n)).length() < 1e-6, "{:?}", s.wi);
    s.weight(n)
}

#[test]
fn smooth_conductor_with_k_zero_reflects_as_the_dielectric() {
    for eta in [1.33f32, 1.5, 2.4] {
        let b = conductor(Vec3::splat(eta), Vec3::ZERO, Vec3::ONE);
        for i in 1..=20 {
            let c = i as f32 / 20.0;
            let w = weight(&b, c);
            let f = fresnel_dielectric(c, eta);
            for ch in 0..3 {
                assert_close(&format!("eta {eta}, cos {c}"), w[ch] as f64, f as f64, 1e-5);
            }
        }
    }
}

#[test]
fn smooth_conductor_at_normal_incidence_is_the_closed_form_and_at_grazing_one() {
    let eta = Vec3::new(0.2, 1.1, 2.9);
    let k = Vec3::new(3.9, 2.1, 0.4);
    let specular = Vec3::new(0.9, 0.6, 0.3);
    let b = conductor(eta, k, specular);
    let normal = weight(&b, 1.0);
    // reflectance near grazing incidence (cos 1e-4) and its limit
    let grazing = weight(&b, 1e-4);
    for c in 0..3 {
        let (n, k) = (eta[c] as f64, k[c] as f64);
        let exact = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        assert_close(
            "normal incidence",
            normal[c] as f64,
            specular[c] as f64 * exact,
            1e-6,
        );
        assert_close(
            "albedo at 1",
            b.albedo(1.0)[c] as f64,
            specular[c] as f64 * exact,
            1e-6,
        );
        assert_close("grazing", grazing[c] as f64, specular[c] as f64, 2e-3);
        assert_close(
            "albedo at 0",
            b.albedo(0.0)[c] as f64,
            specular[c] as f64,
            1e-6,
        );
    }
}

/// Mitsuba's material `none`: eta 0, k 1 reflects everything at every angle.
#[test]
fn material_none_is_a_perfect_mirror() {
    let b = conductor(Vec3::ZERO, Vec3::ONE, Vec3::ONE);
    for i in 1..=50 {
        let c = i as f32 / 50.0;
        for ch in 0..3 {
            assert_close("F = 1", weight(&b, c)[ch] as f64, 1.0, 1e-6);
        }
    }
}

/// The named table: the f32 values Mitsuba 3.9's `scalar_rgb` conductor holds for gold (read
/// from `mi.traverse(mi.load_dict({"type": "conductor", "material": "Au"}))`), every entry
/// finite and non-negative, unknown names unknown.
#[test]
fn named_conductors_are_mitsubas_rgb_indices() {
    let (eta, k) = named_conductor("Au").unwrap();
    let mitsuba_eta = [0.143036f32, 0.375307, 1.44205];
    let mitsuba_k = [3.983f32, 2.38556, 1.60336];
    for c in 0..3 {
        // traverse prints six significant digits
        assert_close("Au eta", eta[c] as f64, mitsuba_eta[c] as f64, 5e-6);
        assert_close("Au k", k[c] as f64, mitsuba_k[c] as f64, 5e-6);
    }
    assert!(NAMED_CONDUCTORS.len() >= 40, "{}", NAMED_CONDUCTORS.len());
    for (name, eta, k) in NAMED_CONDUCTORS {
        assert!(
            eta.iter()
                .chain(k.iter())
                .all(|x| x.is_finite() && *x >= 0.0),
            "{name}"
        );
        assert_eq!(
            named_conductor(name),
            Some((Vec3::from(eta), Vec3::from(k)))
        );
    }
    for name in ["Ag", "Al", "Cu", "Cr", "W"] {
        assert!(named_conductor(name).is_some(), "{name}");
    }
    assert_eq!(named_conductor("au"), None);
    assert_eq!(named_conductor("none"), None);
}
