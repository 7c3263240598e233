//! Executable specification of `src/math/warp.rs` and `src/math/distribution.rs`.
//!
//! Every warp from the unit square is checked by a chi-square test of its samples against the
//! density its documentation states; `Distribution1D` by its sample frequencies against its
//! pmf, and by the uniformity of the random number it hands back for reuse.

use crate::common;

use common::stats::Family;
use common::*;
use glam::Vec3;
use pathspace::math::{warp, Distribution1D, Frame};
use std::f64::consts::{PI, TAU};

/// Samples per chi-square test: with 640 bins that is over 300 per bin for uniform densities.
const N_SAMPLES: u64 = 200_000;

/// The canonical frame: warps produce local directions around +z.
fn z_frame() -> Frame {
    Frame::from_normal(Vec3::Z)
}

#[test]
fn uniform_sphere_has_density_one_over_four_pi() {
    let mut fam = Family::new("warp: uniform sphere");
    let grid = SphereGrid::new(z_frame(), 40, 16);
    let mut s = sampler(200, 0);
    chi_square_sphere(
        &mut fam,
        "uniform sphere",
        &grid,
        || Some(warp::uniform_sphere(s.next_2d())),
        |_| warp::INV_FOUR_PI as f64,
        N_SAMPLES,
    );
    fam.finish();
}

#[test]
fn cosine_hemisphere_has_density_cos_over_pi() {
    // the whole sphere is binned: the lower hemisphere expects nothing
    let mut fam = Family::new("warp: cosine hemisphere");
    let grid = SphereGrid::new(z_frame(), 40, 16);
    let mut s = sampler(201, 0);
    chi_square_sphere(
        &mut fam,
        "cosine hemisphere",
        &grid,
        || Some(warp::cosine_hemisphere(s.next_2d())),
        |w| warp::cosine_hemisphere_pdf(w) as f64,
        N_SAMPLES,
    );
    fam.finish();
    // and the stated density is the normalized cos / pi
    let mut s = sampler(201, 1);
    for _ in 0..1000 {
        let w = warp::cosine_hemisphere(s.next_2d());
        assert!(w.z >= 0.0);
        assert_close(
            "pdf",
            warp::cosine_hemisphere_pdf(w) as f64,
            w.z as f64 / PI,
            1e-6,
        );
    }
}

#[test]
fn uniform_cone_has_density_one_over_its_solid_angle() {
    // 40 bins in cos theta put every cos_max below on a bin edge (multiples of 0.05), so the
    // density's jump is not inside a bin. A quadrature node on the edge counts as outside: it
    // then misses 1/768 of the first inside bin's mass (a few counts of thousands), whereas
    // counting it inside would give the empty bin below the edge a spurious expectation.
    const N_COS: usize = 40;
    const EDGE: f32 = 1e-6;
    let mut fam = Family::new("warp: uniform cone");
    for (i, cos_max) in [0.9f32, 0.0, -0.5].into_iter().enumerate() {
        let grid = SphereGrid::new(z_frame(), N_COS, 16);
        let mut s = sampler(202, i as u64);
        let density = 1.0 / (TAU * (1.0 - cos_max as f64));
        chi_square_sphere(
            &mut fam,
            &format!("cone cos_max {cos_max}"),
            &grid,
            || Some(warp::uniform_cone(s.next_2d(), cos_max)),
            |w| if w.z > cos_max + EDGE { density } else { 0.0 },
            N_SAMPLES,
        );
    }
    fam.finish();
}

#[test]
fn concentric_disk_is_uniform_on_the_unit_disk() {
    // uniform on the disk <=> r^2 and phi independent and uniform: equal expected counts in
    // an (r^2, phi) grid
    const N_R2: usize = 20;
    const N_PHI: usize = 24;
    let mut s = sampler(203, 0);
    let mut counts = vec![0u64; N_R2 * N_PHI];
    for _ in 0..N_SAMPLES {
        let p = warp::concentric_disk(s.next_2d());
        let r2 = p.length_squared() as f64;
        assert!(r2 <= 1.0 + 1e-6, "outside the disk: {p}");
        let phi = (p.y as f64).atan2(p.x as f64).rem_euclid(TAU);
        let i = ((r2 * N_R2 as f64) as usize).min(N_R2 - 1);
        let j = ((phi / TAU * N_PHI as f64) as usize).min(N_PHI - 1);
        counts[i * N_PHI + j] += 1;
    }
    let expected = vec![N_SAMPLES as f64 / (N_R2 * N_PHI) as f64; N_R2 * N_PHI];
    let mut fam = Family::new("warp: concentric disk");
    fam.chi_square("concentric disk", &counts, &expected);
    fam.finish();
}

#[test]
fn uniform_triangle_is_uniform_on_the_triangle() {
    // barycentrics (b0, b1) are uniform on {b0, b1 >= 0, b0 + b1 <= 1} (density 2). On an
    // n x n grid the diagonal b0 + b1 = 1 runs through cell corners: cells with i + j < n - 1
    // are inside, cells with i + j = n - 1 are cut in half, the rest are outside.
    const N: usize = 24;
    let mut s = sampler(204, 0);
    let mut counts = vec![0u64; N * N];
    for _ in 0..N_SAMPLES {
        let b = warp::uniform_triangle(s.next_2d());
        assert!(
            b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6,
            "got barycentrics {b}, expected b0, b1 >= 0 and b0 + b1 <= 1 (inside the triangle)"
        );
        let i = ((b.x as f64 * N as f64) as usize).min(N - 1);
        let j = ((b.y as f64 * N as f64) as usize).min(N - 1);
        counts[i * N + j] += 1;
    }
    let cell = 2.0 * N_SAMPLES as f64 / (N * N) as f64;
    let expected: Vec<f64> = (0..N * N)
        .map(|k| {
            let (i, j) = (k / N, k % N);
            match (i + j).cmp(&(N - 1)) {
                std::cmp::Ordering::Less => cell,
                std::cmp::Ordering::Equal => 0.5 * cell,
                std::cmp::Ordering::Greater => 0.0,
            }
        })
        .collect();
    let mut fam = Family::new("warp: uniform triangle");
    fam.chi_square("uniform triangle", &counts, &expected);
    fam.finish();
}

/// Weights with zeros at both ends and in the middle, and a dominant entry.
const WEIGHTS: [f32; 9] = [0.0, 1.0, 0.0, 3.0, 0.5, 2.0, 0.25, 7.0, 0.0];

#[test]
fn distribution_samples_indices_with_their_pmf() {
    let dist = Distribution1D::new(&WEIGHTS);
    let total: f64 = WEIGHTS.iter().map(|&w| w as f64).sum();
    assert_close("total", dist.total() as f64, total, 1e-6);
    let mut s = sampler(205, 0);
    let mut counts = vec![0u64; WEIGHTS.len()];
    for _ in 0..N_SAMPLES {
        let (i, p, _) = dist.sample(s.next_f32());
        assert_eq!(p, dist.pmf(i));
        counts[i] += 1;
    }
    let expected: Vec<f64> = (0..WEIGHTS.len())
        .map(|i| {
            assert_close("pmf", dist.pmf(i) as f64, WEIGHTS[i] as f64 / total, 1e-6);
            dist.pmf(i) as f64 * N_SAMPLES as f64
        })
        .collect();
    // zero-weight entries expect nothing, so one sample there fails the test
    let mut fam = Family::new("warp: Distribution1D pmf");
    fam.chi_square("Distribution1D", &counts, &expected);
    fam.finish();
}

#[test]
fn distribution_remaps_u_uniformly_within_the_chosen_bin() {
    // given the chosen index, the remapped number must be uniform on [0, 1) (KS per index)
    let dist = Distribution1D::new(&WEIGHTS);
    let mut s = sampler(206, 0);
    let mut rems: Vec<Vec<f64>> = vec![Vec::new(); WEIGHTS.len()];
    for _ in 0..N_SAMPLES {
        let (i, _, rem) = dist.sample(s.next_f32());
        assert!((0.0..1.0).contains(&rem), "remapped u = {rem}");
        rems[i].push(rem as f64);
    }
    let mut fam = Family::new("warp: Distribution1D remapped u");
    for (i, r) in rems.iter_mut().enumerate() {
        if WEIGHTS[i] > 0.0 {
            fam.ks(&format!("bin {i}"), r, |x| x.clamp(0.0, 1.0));
        } else {
            assert!(r.is_empty());
        }
    }
    fam.finish();
}

#[test]
fn distribution_with_zero_weights_falls_back_to_uniform() {
    let dist = Distribution1D::new(&[0.0, 0.0, 0.0, 0.0]);
    for i in 0..4 {
        assert_eq!(dist.pmf(i), 0.25);
    }
    let mut s = sampler(207, 0);
    let mut counts = [0u64; 4];
    for _ in 0..N_SAMPLES {
        counts[dist.sample(s.next_f32()).0] += 1;
    }
    let mut fam = Family::new("warp: Distribution1D of zero weights");
    fam.chi_square("zero weights", &counts, &[N_SAMPLES as f64 / 4.0; 4]);
    fam.finish();
}
