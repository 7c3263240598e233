//! Executable specification of `src/medium/heterogeneous.rs`, `grid.rs` and `procedural.rs`
//! (book: "Table 1: inhomogeneous media").
//!
//! Pauly, Kollig, Keller 2000, Table 1 (right column) and sec. 4.1: ray marching converges to
//! the closed-form optical depth as Delta -> 0 with the order of its quadrature rule (2 for the
//! midpoint rule; RMS order 3/2 for stratified and 1 for random offset, both unbiased for tau);
//! delta and ratio tracking are unbiased; a constant grid is the homogeneous medium; bad grid
//! files are rejected with the file, the line or byte offset, and the scene key.

mod common;

use common::*;
use glam::Vec3;
use pathspace::geometry::{Aabb, Ray};
use pathspace::integrator::{IntegratorKind, MeterEstimate, Renderer};
use pathspace::medium::grid::{encode_vol, read_grid_file};
use pathspace::medium::{
    Axis, Density, Fbm, Field, Grid, Heterogeneous, Homogeneous, LineIntegral, Medium, Phase,
};
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::Rgb;

/// How many standard errors a Monte Carlo estimate may lie from the truth.
const K_SIGMA: f64 = 4.0;

fn unit_box() -> Aabb {
    Aabb {
        min: Vec3::ZERO,
        max: Vec3::ONE,
    }
}

fn medium(density: Density, sigma_t: Rgb, li: LineIntegral, step: f32) -> Heterogeneous {
    // all of sigma_t scatters: sigma_a = 0
    Heterogeneous::new(
        density,
        unit_box(),
        Rgb::ZERO,
        sigma_t,
        Phase::Isotropic,
        li,
        step,
    )
    .unwrap()
}

fn linear() -> Density {
    Density::Field(Field::Linear {
        axis: Axis::Y,
        from: 0.2,
        to: 2.0,
    })
}

/// A 3^3 grid with a strong interior bump: trilinear, so piecewise cubic along a ray.
fn bump_grid() -> Density {
    Density::Grid(Grid::bake(3, |u| {
        if u == Vec3::splat(0.5) {
            3.0
        } else {
            0.1 + u.x + 0.5 * u.z
        }
    }))
}

fn cloud() -> Density {
    Density::Field(Field::Cloud(Fbm {
        octaves: 4,
        frequency: 4.0,
        seed: 7,
    }))
}

/// A ray crossing the unit box obliquely, entering through the bottom face.
fn oblique() -> (Ray, f32) {
    let d = Vec3::new(0.3, 1.0, 0.2).normalize();
    let o = Vec3::new(0.2, 0.0, 0.3);
    // it leaves through the top face y = 1
    (Ray::new(o, d), 1.0 / d.y)
}

/// Least-squares slope of log(err) against log(delta), with its standard error.
fn slope(deltas: &[f64], errs: &[f64]) -> (f64, f64) {
    let x: Vec<f64> = deltas.iter().map(|d| d.ln()).collect();
    let y: Vec<f64> = errs.iter().map(|e| e.ln()).collect();
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let b = sxy / sxx;
    let rss: f64 = x
        .iter()
        .zip(&y)
        .map(|(a, c)| (c - my - b * (a - mx)).powi(2))
        .sum();
    (b, (rss / (n - 2.0) / sxx).sqrt())
}

/// The marched optical depth along `ray` (gray sigma_t = 1, so tau = D = -ln T).
fn marched_tau(m: &Heterogeneous, ray: &Ray, t: f32, s: &mut pathspace::math::Sampler) -> f64 {
    -(m.transmittance(ray, t, s).x as f64).ln()
}

/// Steps Delta = L / n for the convergence fits (whole segments, relative to the box side 1).
const STEPS_PER_RAY: [u32; 5] = [4, 8, 16, 32, 64];
/// Tolerance on a fitted order beyond K_SIGMA of its standard error (float noise at small
/// errors, pre-asymptotic terms at large steps).
const ORDER_SLACK: f64 = 0.2;

fn assert_order(what: &str, deltas: &[f64], errs: &[f64], expected: f64) {
    let (b, se) = slope(deltas, errs);
    eprintln!("{what}: order {b:.3} +- {se:.3} (expected {expected}); errors {errs:?}");
    assert!(
        (b - expected).abs() <= K_SIGMA * se + ORDER_SLACK,
        "{what}: fitted order {b} +- {se}, expected {expected}"
    );
}

#[test]
fn equidistant_marching_is_second_order_and_exact_for_linear_densities() {
    let (ray, len) = oblique();
    let mut s = sampler(1, 0);
    // linear: the midpoint rule is exact
    let lin = medium(linear(), Rgb::ONE, LineIntegral::Equidistant, 1.0 / 7.0);
    let exact = lin.density_integral(&ray, len) as f64;
    let got = marched_tau(&lin, &ray, len, &mut s);
    assert_close("midpoint rule on a linear density", got, exact, 1e-5);
    // the bump grid: error O(Delta^2)
    let (mut deltas, mut errs) = (vec![], vec![]);
    for n in STEPS_PER_RAY {
        let step = len / n as f32;
        let m = medium(bump_grid(), Rgb::ONE, LineIntegral::Equidistant, step);
        let exact = m.density_integral(&ray, len) as f64;
        deltas.push(step as f64);
        errs.push((marched_tau(&m, &ray, len, &mut s) - exact).abs());
    }
    assert_order("equidistant", &deltas, &errs, 2.0);
}

/// Stratified and random-offset marching: unbiased for tau at every Delta (the mean of the
/// marched tau is within 4 standard errors of the closed form), RMS error of order 3/2 and 1.
#[test]
fn randomized_marching_is_unbiased_for_tau_with_orders_three_halves_and_one() {
    const N: usize = 4000;
    let (ray, len) = oblique();
    for (li, order) in [
        (LineIntegral::Stratified, 1.5),
        (LineIntegral::RandomOffset, 1.0),
    ] {
        let (mut deltas, mut rms) = (vec![], vec![]);
        for (i, n) in STEPS_PER_RAY.into_iter().enumerate() {
            let step = len / n as f32;
            let m = medium(linear(), Rgb::ONE, li, step);
            let exact = m.density_integral(&ray, len) as f64;
            let mut s = sampler(2, i as u64);
            let taus: Vec<f64> = (0..N).map(|_| marched_tau(&m, &ray, len, &mut s)).collect();
            let (mean, se) = mean_and_stderr(&taus);
            assert_within_sigma(
                &format!("{} tau, n = {n}", li.name()),
                mean,
                se,
                exact,
                K_SIGMA,
            );
            let mse = taus.iter().map(|t| (t - exact).powi(2)).sum::<f64>() / N as f64;
            // measured, not asserted: the transmittance exp(-tau-hat) is biased (Jensen)
            let t_hat: Vec<f64> = taus.iter().map(|t| (-t).exp()).collect();
            let (t_mean, t_se) = mean_and_stderr(&t_hat);
            eprintln!(
                "{} n = {n}: E[T-hat] - T = {:.2e} +- {t_se:.1e}",
                li.name(),
                t_mean - (-exact).exp()
            );
            deltas.push(step as f64);
            rms.push(mse.sqrt());
        }
        assert_order(li.name(), &deltas, &rms, order);
    }
}

/// Delta tracking: passage with probability exp(-tau) (binomial), collision distances with
/// the CDF (1 - exp(-tau(t))) / (1 - exp(-tau(L))) (KS); on the linear and the grid medium.
#[test]
fn delta_tracking_samples_table_1_exactly() {
    const N: usize = 40_000;
    let (ray, len) = oblique();
    for (k, density) in [linear(), bump_grid()].into_iter().enumerate() {
        let m = medium(density, Rgb::ONE, LineIntegral::DeltaTracking, 1.0);
        let tau = |t: f64| m.density_integral(&ray, t as f32) as f64;
        let tau_l = tau(len as f64);
        let mut s = sampler(3, k as u64);
        let mut ts = vec![];
        let mut passed = 0u64;
        for _ in 0..N {
            let ff = m.sample_free_flight(&ray, len, &mut s);
            if ff.scattered {
                ts.push(ff.t as f64);
            } else {
                passed += 1;
            }
        }
        assert_binomial("delta tracking passage", passed, N as u64, (-tau_l).exp());
        assert_ks("delta tracking collision distance", &mut ts, |t| {
            (1.0 - (-tau(t)).exp()) / (1.0 - (-tau_l).exp())
        });
    }
}

/// Ratio tracking and the delta-tracking passage indicator are unbiased estimates of
/// exp(-tau) for every channel of a chromatic medium, on analytic, grid and procedural fields.
#[test]
fn ratio_and_delta_tracking_transmittance_are_unbiased() {
    const N: usize = 20_000;
    let (ray, len) = oblique();
    let sigma_t = Vec3::new(0.5, 1.0, 2.5);
    for (k, density) in [linear(), bump_grid(), cloud()].into_iter().enumerate() {
        let m = medium(density, sigma_t, LineIntegral::DeltaTracking, 1.0);
        let truth = m.transmittance_exact(&ray, len);
        let mut s = sampler(4, k as u64);
        let mut ratio = [vec![], vec![], vec![]];
        let mut passage = [vec![], vec![], vec![]];
        for _ in 0..N {
            let tr = m.transmittance(&ray, len, &mut s);
            let ff = m.sample_free_flight(&ray, len, &mut s);
            // the passage weight transmittance / pdf, zero on a collision: E = exp(-tau_c)
            let w = if ff.scattered { Rgb::ZERO } else { ff.weight() };
            for c in 0..3 {
                ratio[c].push(tr[c] as f64);
                passage[c].push(w[c] as f64);
            }
        }
        for c in 0..3 {
            for (what, v) in [
                ("ratio tracking", &ratio[c]),
                ("delta passage", &passage[c]),
            ] {
                let (mean, se) = mean_and_stderr(v);
                assert_within_sigma(
                    &format!("{what}, field {k}, channel {c}"),
                    mean,
                    se,
                    truth[c] as f64,
                    K_SIGMA,
                );
            }
        }
    }
}

/// The recorded pdf is the one `free_flight_pdf` recomputes (BDPT/MLT rely on it).
#[test]
fn delta_tracking_pdf_is_reproducible() {
    let (ray, len) = oblique();
    let m = Medium::Heterogeneous(Box::new(medium(
        bump_grid(),
        Vec3::new(0.5, 1.0, 2.5),
        LineIntegral::DeltaTracking,
        1.0,
    )));
    let mut s = sampler(5, 0);
    for _ in 0..2000 {
        let ff = m.sample_free_flight(&ray, len, &mut s);
        let p = m.free_flight_pdf(&ray, ff.t, ff.scattered);
        assert_close("recomputed pdf", p as f64, ff.pdf as f64, 1e-4);
    }
}

/// A constant density is the homogeneous medium: identical pdfs and transmittances.
#[test]
fn constant_density_matches_the_homogeneous_medium() {
    let sigma_t = Vec3::new(0.4, 1.2, 3.0);
    let h = Homogeneous::new(Rgb::ZERO, sigma_t, Phase::Isotropic).unwrap();
    let grid = Density::Grid(Grid::new([2, 2, 2], vec![1.0; 8]).unwrap());
    for density in [Density::Field(Field::Constant), grid] {
        let m = medium(density, sigma_t, LineIntegral::DeltaTracking, 1.0);
        let (ray, len) = oblique();
        for t in [0.1f32, 0.5, len * 0.99] {
            for scattered in [true, false] {
                assert_close(
                    "pdf",
                    m.free_flight_pdf(&ray, t, scattered) as f64,
                    h.free_flight_pdf(t, scattered) as f64,
                    1e-5,
                );
            }
        }
    }
}

/// Builds a scene whose relative paths resolve in `dir`.
fn load_in(dir: &std::path::Path, text: &str) -> Result<Scene, String> {
    let src = SceneSource {
        name: "test.toml".into(),
        text: text.into(),
        base_dir: dir.to_path_buf(),
    };
    Scene::load(&src).map_err(|e| e.to_string())
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("pathspace-media-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A slab z in [-1, 0] (optical thickness 1, albedo 0.8) under a directional light, with a
/// transmission and a reflection meter; `medium` is the body of `[media.slab]`.
fn slab_scene(medium: &str) -> String {
    common::slab_scene(medium, 50.0)
}

fn meters(scene: &Scene, spp: u32, seed: u64) -> Vec<MeterEstimate> {
    let mut r = Renderer::new(scene, IntegratorKind::Path, seed, None);
    r.pass(spp, &|| {});
    r.meter_estimates()
}

/// A grid filled with a constant density, scene-level: the path tracer's meters agree with
/// the homogeneous slab's within 4 combined standard errors.
#[test]
fn constant_grid_slab_measures_like_the_homogeneous_slab() {
    let dir = temp_dir("slab");
    std::fs::write(dir.join("ones.txt"), "2 2 2\n1 1 1 1 1 1 1 1\n").unwrap();
    let coeffs = "sigma_a = 0.2\nsigma_s = 0.8";
    let homogeneous = load_in(
        &dir,
        &slab_scene(&format!("type = \"homogeneous\"\n{coeffs}")),
    )
    .unwrap();
    let grid = load_in(
        &dir,
        &slab_scene(&format!(
            "type = \"grid\"\nfile = \"ones.txt\"\nmin = [-50.0, -50.0, -1.0]\nmax = [50.0, 50.0, 0.0]\n{coeffs}"
        )),
    )
    .unwrap();
    let a = meters(&homogeneous, 4, 21);
    let b = meters(&grid, 4, 22);
    for (ma, mb) in a.iter().zip(&b) {
        let (va, vb) = (ma.value.x as f64, mb.value.x as f64);
        let se = ((ma.stderr.x as f64).powi(2) + (mb.stderr.x as f64).powi(2)).sqrt();
        eprintln!("{}: homogeneous {va:.5} grid {vb:.5} +- {se:.5}", ma.name);
        assert!(
            (va - vb).abs() <= K_SIGMA * se,
            "meter {}: homogeneous {va} vs constant grid {vb} (combined stderr {se})",
            ma.name
        );
    }
}

/// A `.vol` written by `encode_vol` reads back identically, with its bounding box.
#[test]
fn mitsuba_vol_round_trips() {
    let dir = temp_dir("vol");
    let g = Grid::bake(4, |u| u.x + 2.0 * u.y * u.z);
    let path = dir.join("g.vol");
    std::fs::write(&path, encode_vol(&g, Vec3::splat(-1.0), Vec3::ONE)).unwrap();
    let back = read_grid_file(&path).unwrap();
    assert_eq!(back.grid, g);
    assert_eq!(back.bounds, Some((Vec3::splat(-1.0), Vec3::ONE)));
}

/// Bad grid files: the error names the scene file, the key, the grid file and where in it.
#[test]
fn bad_grid_files_are_rejected_with_file_location_and_key() {
    let dir = temp_dir("bad");
    let good = Grid::bake(2, |_| 1.0);
    let mut short_vol = encode_vol(&good, Vec3::ZERO, Vec3::ONE);
    short_vol.truncate(short_vol.len() - 4);
    let mut nan_vol = encode_vol(&good, Vec3::ZERO, Vec3::ONE);
    let n = nan_vol.len();
    nan_vol[n - 4..].copy_from_slice(&f32::NAN.to_le_bytes());
    let cases: [(&str, &[u8], &[&str]); 6] = [
        (
            "few.txt",
            b"2 2 2\n1 1 1\n1 1 1\n",
            &["few.txt", "line 3", "needs 8 values"],
        ),
        (
            "many.txt",
            b"2 2 2\n1 1 1 1 1 1 1 1\n1\n",
            &["many.txt", "line 3", "more than"],
        ),
        (
            "nan.txt",
            b"2 2 2\n1 1 1 1\n1 nan 1 1\n",
            &["nan.txt", "line 3", "nan"],
        ),
        (
            "neg.txt",
            b"# header\n2 2 2\n1 1 1 1 1 1 -0.5 1\n",
            &["neg.txt", "line 3", "-0.5"],
        ),
        (
            "short.vol",
            &short_vol,
            &["short.vol", "byte offset 48", "needs 80 bytes"],
        ),
        ("nan.vol", &nan_vol, &["nan.vol", "byte offset 76", "NaN"]),
    ];
    for (name, bytes, expect) in cases {
        std::fs::write(dir.join(name), bytes).unwrap();
        let text = slab_scene(&format!(
            "type = \"grid\"\nsigma_a = 0.1\nsigma_s = 0.5\nfile = \"{name}\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]"
        ));
        let err = load_in(&dir, &text)
            .err()
            .expect("a bad grid must be rejected");
        eprintln!("{err}");
        assert!(err.contains("test.toml:"), "{err}");
        assert!(err.contains("media.slab.file"), "{err}");
        for e in expect {
            assert!(err.contains(e), "`{err}` should mention `{e}`");
        }
    }
}

/// Scene-file validation of the new keys.
#[test]
fn procedural_media_keys_are_validated() {
    let dir = temp_dir("keys");
    let base = "type = \"procedural\"\nsigma_a = 0.1\nsigma_s = 0.5\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]";
    for (extra, key, msg) in [
        (
            "density = \"linear\"\naxis = \"y\"\nfrom = 0.0",
            "media.slab",
            "needs `to`",
        ),
        (
            "density = \"linear\"\naxis = \"y\"\nfrom = -1.0\nto = 1.0",
            "media.slab.from",
            ">= 0",
        ),
        (
            "density = \"cloud\"\naxis = \"y\"",
            "media.slab.axis",
            "only to density = linear",
        ),
        (
            "density = \"constant\"\nstep = 0.0",
            "media.slab.step",
            "(0, 1]",
        ),
        (
            "density = \"cloud\"\nresolution = 1",
            "media.slab.resolution",
            "2..=",
        ),
        (
            "density = \"smoke\"",
            "media.slab.density",
            "unknown variant",
        ),
        (
            "density = \"constant\"\npropagation = \"marching\"",
            "media.slab.propagation",
            "unknown variant",
        ),
    ] {
        let err = load_in(&dir, &slab_scene(&format!("{base}\n{extra}")))
            .err()
            .expect("must be rejected");
        eprintln!("{err}");
        assert!(err.contains(&format!("key `{key}`")), "{err}");
        assert!(err.contains(msg), "{err}");
    }
    // the defaults: delta tracking, Delta = 1/64 of the box
    let scene = load_in(&dir, &slab_scene(&format!("{base}\ndensity = \"cloud\""))).unwrap();
    let Medium::Heterogeneous(h) = &scene.media[0] else {
        panic!("a procedural medium is heterogeneous")
    };
    assert_eq!(h.line_integral, LineIntegral::DeltaTracking);
    assert_close("default Delta", h.delta as f64, 1.0 / 64.0, 1e-7);
}
