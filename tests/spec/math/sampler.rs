//! The samplers' stratified film positions (`pathspace::math::sampler::stratified_point`,
//! `[render] pixel_samples`; the PCG streams' derivation from seed, pixel and pass is
//! `tests/invariants/determinism.rs`'s): the nets of the (0, 2)-sequence, the uniformity of
//! each point over the pixels' shifts, a render across an edge, whose mean they keep and whose
//! variance they lower, and passes that continue one sequence. Book: "Measuring a renderer"
//! (stratified film positions).

use pathspace::integrator::{IntegratorKind, PixelSamples, Renderer};
use pathspace::math::sampler::{film_shift, stratified_point};
use pathspace::scene::{Scene, SceneSource};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::common::stats::{assert_significant, Family};

/// Every run of 2^m points that starts at a multiple of 2^m puts exactly one point in each
/// elementary interval of area 2^-m, of every shape 2^-i x 2^-(m-i), whatever the shift: the
/// property that makes the pixel's first 2^m samples a stratified sample of it.
#[test]
fn every_aligned_run_of_two_to_the_m_points_is_a_net() {
    for (seed, pixel) in [(1, 0), (1, 4095), (7, 123), (u64::MAX, 1 << 40)] {
        let shift = film_shift(seed, pixel);
        for m in 0..=10u32 {
            let n = 1u32 << m;
            for run in [0u32, 1, 2, 37] {
                let points: Vec<_> = (0..n)
                    .map(|j| stratified_point(run * n + j, shift))
                    .collect();
                for p in &points {
                    assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                }
                for i in 0..=m {
                    // scaling by a power of two is exact: the cell of each point is exact too
                    let (cols, rows) = (1u32 << i, 1u32 << (m - i));
                    let mut count = vec![0u32; n as usize];
                    for p in &points {
                        let (a, b) = ((p.x * cols as f32) as u32, (p.y * rows as f32) as u32);
                        count[(b * cols + a) as usize] += 1;
                    }
                    assert!(
                        count.iter().all(|&c| c == 1),
                        "seed {seed}, pixel {pixel}: points {}..{} in {cols} x {rows} cells: {count:?}",
                        run * n,
                        (run + 1) * n
                    );
                }
            }
        }
    }
}

/// Over the pixels' shifts, each point of the sequence is uniform in the unit square (a
/// chi-square test on 16 x 16 cells, 25,600 pixels, for points at both ends of the index
/// range): what makes an estimate from stratified positions unbiased.
#[test]
fn each_point_is_uniform_over_the_pixels_shifts() {
    let mut family = Family::new("stratified points over the shifts");
    let (side, pixels) = (16usize, 25_600u64);
    for k in [0u32, 1, 6, 1000, u32::MAX] {
        let mut observed = vec![0u64; side * side];
        for pixel in 0..pixels {
            let p = stratified_point(k, film_shift(3, pixel));
            let (a, b) = ((p.x * side as f32) as usize, (p.y * side as f32) as usize);
            observed[b * side + a] += 1;
        }
        let expected = vec![pixels as f64 / (side * side) as f64; side * side];
        family.chi_square(&format!("point {k}"), &observed, &expected);
    }
    family.finish();
}

/// An emitting quad seen face on whose edge crosses the 8 x 8 image at 20 degrees to its rows,
/// nothing else: each pixel's value is the share of it the quad covers.
fn edge_scene() -> String {
    let (c, s) = (20f32.to_radians().cos(), 20f32.to_radians().sin());
    format!(
        r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 20.0
resolution = [8, 8]

[[shapes]]
type = "quad"
origin = [{}, {}, 0.0]
u = [{}, {}, 0.0]
v = [{}, {}, 0.0]
emission = 1.0
"#,
        -3.0 * c + 0.05,
        -3.0 * s,
        6.0 * c,
        6.0 * s,
        -3.0 * s,
        3.0 * c
    )
}

/// The red value of every pixel of a 16-spp render of `scene` with `seed` and `mode`.
fn pixels(scene: &Scene, seed: u64, mode: PixelSamples) -> Vec<f64> {
    let mut r = Renderer::new(scene, IntegratorKind::Path, seed, None);
    r.pixel_samples = mode;
    r.pass(16, &|| {});
    let film = r.film.expect("the scene has a camera");
    film.sum.iter().map(|s| s[0] / film.spp as f64).collect()
}

/// Across the edge of an emitter, stratified film positions keep every pixel's mean (Welch
/// tests against independent positions, 64 seeds each) and lower the variance of the pixels
/// the edge crosses, summed over them (a one-sided F test of the independent positions'
/// variance over the stratified ones').
#[test]
fn stratified_film_positions_keep_the_mean_and_lower_the_variance_at_an_edge() {
    let scene = Scene::load(&SceneSource::embedded("edge.toml", &edge_scene())).unwrap();
    let seeds = 64u64;
    let runs = |mode| -> Vec<Vec<f64>> { (1..=seeds).map(|s| pixels(&scene, s, mode)).collect() };
    let (strat, indep) = (
        runs(PixelSamples::Stratified),
        runs(PixelSamples::Independent),
    );
    let column = |runs: &[Vec<f64>], i: usize| -> Vec<f64> { runs.iter().map(|r| r[i]).collect() };
    let variance = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64
    };
    let mut family = Family::new("stratified against independent film positions");
    let (mut var_s, mut var_i, mut edge) = (0.0, 0.0, 0usize);
    for i in 0..64 {
        let (s, d) = (column(&strat, i), column(&indep, i));
        family.runs_agree(&format!("pixel {i}"), &s, &d);
        if variance(&d) > 0.0 {
            edge += 1;
            var_s += variance(&s);
            var_i += variance(&d);
        }
    }
    family.finish();
    assert!(edge >= 8, "the edge crosses only {edge} pixels");
    let dof = (edge * (seeds as usize - 1)) as f64;
    let ratio = var_i / var_s;
    let p = 1.0 - FisherSnedecor::new(dof, dof).unwrap().cdf(ratio);
    assert_significant(
        &format!("edge pixels' variance, independent / stratified = {ratio:.2}"),
        p,
    );
}

/// A pass continues its pixels' sequences where the last pass left them: in the edge scene,
/// where a sample's value depends on its film position alone (the emitter ends every path),
/// four passes of 4 samples give each pixel the sum one pass of 16 gives, bit for bit. A
/// sequence restarted at every pass would give four passes the same four positions.
#[test]
fn passes_continue_one_sequence() {
    let scene = Scene::load(&SceneSource::embedded("edge.toml", &edge_scene())).unwrap();
    for seed in 1..=4 {
        let sums = |passes: u32| {
            let mut r = Renderer::new(&scene, IntegratorKind::Path, seed, None);
            for _ in 0..passes {
                r.pass(16 / passes, &|| {});
            }
            r.film.expect("a camera").sum
        };
        assert_eq!(sums(1), sums(4), "seed {seed}");
    }
}
