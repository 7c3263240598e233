//! Executable specification of `src/medium/heterogeneous.rs`, `grid.rs` and `procedural.rs`
//! (book: "Table 1: inhomogeneous media").
//!
//! Pauly, Kollig, Keller 2000, Table 1 (right column) and sec. 4.1: ray marching converges to
//! the closed-form optical depth as Delta -> 0 with the order of its quadrature rule, checked
//! against the rules' exact error terms (the midpoint rule's -Delta^2 / 24 (f'(L) - f'(0)) on a
//! cubic, order 2; the mean squared errors of stratified and random-offset marching on a linear
//! density, of orders 3 and 2, i.e. RMS orders 3/2 and 1, both unbiased for tau);
//! delta and ratio tracking are unbiased; a constant grid is the homogeneous medium; bad grid
//! files are rejected with the file, the line or byte offset, and the scene key.

use crate::common;

use common::stats::Family;
use common::*;
use glam::Vec3;
use pathspace::geometry::{Aabb, Ray};
use pathspace::integrator::{IntegratorKind, MeterEstimate, Renderer};
use pathspace::medium::grid::{encode_vol, read_grid_file, EmptyCells};
use pathspace::medium::{
    Axis, Density, Fbm, Field, Grid, Heterogeneous, Homogeneous, LineIntegral, Medium, Phase,
    TransmittanceEstimator,
};
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::Rgb;

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

/// The corner values of a one-cell (2^3) grid, x fastest: trilinear over the whole box, so a
/// single cubic along any ray.
const CELL: [f32; 8] = [0.2, 1.5, 0.7, 2.0, 1.1, 0.3, 1.8, 0.6];

/// The one-cell grid of [`CELL`].
fn one_cell() -> Density {
    Density::Grid(Grid::new([2, 2, 2], CELL.to_vec()).unwrap())
}

/// [`CELL`]'s trilinear interpolant in f64, extended beyond the box as the same polynomial.
fn one_cell_f64(u: [f64; 3]) -> f64 {
    let mut sum = 0.0;
    for (i, v) in CELL.iter().enumerate() {
        let w = |bit: usize, x: f64| if bit == 1 { x } else { 1.0 - x };
        sum += *v as f64 * w(i & 1, u[0]) * w((i >> 1) & 1, u[1]) * w((i >> 2) & 1, u[2]);
    }
    sum
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

/// Steps Delta = L / n for the convergence studies (whole segments, relative to the box side 1).
const STEPS_PER_RAY: [u32; 5] = [4, 8, 16, 32, 64];

/// The relative rounding of one f32 operation.
const EPS: f64 = f32::EPSILON as f64;

/// The midpoint rule on n steps of Delta: on each step int f = Delta f(m) + Delta^3 f''(m) / 24
/// exactly for a cubic (the odd terms cancel about m, the fourth derivative is zero), and f''
/// is affine, so its midpoint sum is its integral: the error of the march is exactly
/// -Delta^2 / 24 (f'(L) - f'(0)), second order with a known constant. The one-cell grid is a
/// cubic along the ray; the f32 march may differ from it only by rounding, bounded by a few
/// roundings per step of an optical depth of order one.
#[test]
fn equidistant_marching_is_second_order_and_exact_for_linear_densities() {
    let (ray, len) = oblique();
    let mut s = sampler(1, 0);
    // linear: the midpoint rule is exact
    let lin = medium(linear(), Rgb::ONE, LineIntegral::Equidistant, 1.0 / 7.0);
    let exact = lin.density_integral(&ray, len) as f64;
    let got = marched_tau(&lin, &ray, len, &mut s);
    assert_close("midpoint rule on a linear density", got, exact, 1e-5);
    // the cubic: f(t) = trilinear(o + t d) on the unit box, its derivative by the five-point
    // stencil (exact for polynomials up to degree four) in f64
    let (o, d) = (ray.o.as_dvec3(), ray.d.as_dvec3());
    let f = |t: f64| one_cell_f64((o + d * t).to_array());
    let h = 1e-3;
    let df =
        |t: f64| (8.0 * (f(t + h) - f(t - h)) - (f(t + 2.0 * h) - f(t - 2.0 * h))) / (12.0 * h);
    let l = len as f64;
    let (mut deltas, mut errs) = (vec![], vec![]);
    for n in [2u32, 4, 8, 16] {
        let step = len / n as f32;
        let m = medium(one_cell(), Rgb::ONE, LineIntegral::Equidistant, step);
        let exact = m.density_integral(&ray, len) as f64;
        let err = marched_tau(&m, &ray, len, &mut s) - exact;
        let delta = step as f64;
        let predicted = -delta * delta / 24.0 * (df(l) - df(0.0));
        // the sum's accumulation (n roundings of the running sum), a few roundings of each
        // term (the lerps of the trilinear interpolant, the product), of the exact integral
        // and of exp and ln: (n + 24) roundings of an optical depth of order one
        let rounding = (n as f64 + 24.0) * EPS * exact.max(1.0);
        eprintln!("equidistant n = {n}: error {err:.4e}, predicted {predicted:.4e}");
        assert!(
            (err - predicted).abs() <= rounding,
            "n = {n}: midpoint error {err:e}, exact error term {predicted:e} (rounding {rounding:e})"
        );
        assert!(
            predicted.abs() > 4.0 * rounding,
            "the test cubic is too flat"
        );
        deltas.push(delta);
        errs.push(err.abs());
    }
    let (order, se) = slope(&deltas, &errs);
    eprintln!("equidistant: fitted order {order:.3} +- {se:.3}");
}

/// Stratified and random-offset marching on the linear density f(t) = 0.2 + 1.8 y(t): each
/// is unbiased for tau at every Delta, and its mean squared error has a closed form. With one
/// uniform offset u for the whole ray (random offset), tau-hat - tau = (u - 1/2) Delta
/// (f(L) - f(0)), so MSE = (1.8 Delta)^2 / 12 (RMS order 1); with an independent jitter per
/// step (stratified), tau-hat - tau = sum_i (u_i - 1/2) f' Delta^2, so
/// MSE = f'^2 Delta^3 L / 12 (RMS order 3/2), f' = 1.8 d_y. Both are means of independent
/// squared errors, tested with their own spread.
#[test]
fn randomized_marching_is_unbiased_for_tau_with_orders_three_halves_and_one() {
    const N: usize = 4000;
    let (ray, len) = oblique();
    let (slope_f, l) = (1.8 * ray.d.y as f64, len as f64);
    let mut fam = Family::new("media: randomized marching");
    for (li, order) in [
        (LineIntegral::Stratified, 1.5),
        (LineIntegral::RandomOffset, 1.0),
    ] {
        let (mut deltas, mut rms) = (vec![], vec![]);
        for (i, n) in STEPS_PER_RAY.into_iter().enumerate() {
            let step = len / n as f32;
            let delta = step as f64;
            let m = medium(linear(), Rgb::ONE, li, step);
            let exact = m.density_integral(&ray, len) as f64;
            let mut s = sampler(2, i as u64);
            let taus: Vec<f64> = (0..N).map(|_| marched_tau(&m, &ray, len, &mut s)).collect();
            let (mean, se) = mean_and_stderr(&taus);
            let dof = (N - 1) as f64;
            fam.mean_is(&format!("{} tau, n = {n}", li.name()), mean, se, dof, exact);
            let sq: Vec<f64> = taus.iter().map(|t| (t - exact).powi(2)).collect();
            let (mse, mse_se) = mean_and_stderr(&sq);
            let mse_truth = match li {
                LineIntegral::Stratified => slope_f * slope_f * delta.powi(3) * l / 12.0,
                _ => (slope_f * l * delta).powi(2) / 12.0,
            };
            fam.mean_is(
                &format!("{} MSE, n = {n}", li.name()),
                mse,
                mse_se,
                dof,
                mse_truth,
            );
            // measured, not asserted: the transmittance exp(-tau-hat) is biased (Jensen)
            let t_hat: Vec<f64> = taus.iter().map(|t| (-t).exp()).collect();
            let (t_mean, t_se) = mean_and_stderr(&t_hat);
            eprintln!(
                "{} n = {n}: E[T-hat] - T = {:.2e} +- {t_se:.1e}",
                li.name(),
                t_mean - (-exact).exp()
            );
            deltas.push(delta);
            rms.push(mse.sqrt());
        }
        let (b, se) = slope(&deltas, &rms);
        eprintln!(
            "{}: fitted RMS order {b:.3} +- {se:.3} (exact {order})",
            li.name()
        );
    }
    fam.finish();
}

/// Delta tracking: passage with probability exp(-tau) (binomial), collision distances with
/// the CDF (1 - exp(-tau(t))) / (1 - exp(-tau(L))) (KS); on the linear and the grid medium.
#[test]
fn delta_tracking_samples_table_1_exactly() {
    const N: usize = 40_000;
    let (ray, len) = oblique();
    let mut fam = Family::new("media: delta tracking");
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
        fam.binomial(
            &format!("density {k}: passage"),
            passed,
            N as u64,
            (-tau_l).exp(),
        );
        fam.ks(&format!("density {k}: collision distance"), &mut ts, |t| {
            (1.0 - (-tau(t)).exp()) / (1.0 - (-tau_l).exp())
        });
    }
    fam.finish();
}

/// Ratio tracking and the delta-tracking passage indicator are unbiased estimates of
/// exp(-tau) for every channel of a chromatic medium, on analytic, grid and procedural fields.
#[test]
fn ratio_and_delta_tracking_transmittance_are_unbiased() {
    const N: usize = 20_000;
    let (ray, len) = oblique();
    let sigma_t = Vec3::new(0.5, 1.0, 2.5);
    let mut fam = Family::new("media: ratio and delta tracking transmittance");
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
                fam.mean_is(
                    &format!("{what}, field {k}, channel {c}"),
                    mean,
                    se,
                    (N - 1) as f64,
                    truth[c] as f64,
                );
            }
        }
    }
    fam.finish();
}

/// Delta tracking as a transmittance estimator (`[render] transmittance = "delta-tracking"`)
/// gives 1 or 0 per channel, with mean exp(-tau_c) for every channel of a chromatic medium
/// (each channel thins the shared tentative collisions by its own sigma_t / sigma_bar).
#[test]
fn delta_tracking_transmittance_is_a_binary_unbiased_estimate() {
    const N: usize = 20_000;
    let (ray, len) = oblique();
    let sigma_t = Vec3::new(0.5, 1.0, 2.5);
    let mut fam = Family::new("media: delta tracking transmittance");
    for (k, density) in [linear(), bump_grid(), cloud()].into_iter().enumerate() {
        let mut m = medium(density, sigma_t, LineIntegral::DeltaTracking, 1.0);
        m.transmittance_estimator = TransmittanceEstimator::DeltaTracking;
        let truth = m.transmittance_exact(&ray, len);
        let mut s = sampler(6, k as u64);
        let mut est = [vec![], vec![], vec![]];
        for _ in 0..N {
            let tr = m.transmittance(&ray, len, &mut s);
            for c in 0..3 {
                assert!(
                    tr[c] == 0.0 || tr[c] == 1.0,
                    "field {k}, channel {c}: got {}, expected 0 or 1",
                    tr[c]
                );
                est[c].push(tr[c] as f64);
            }
        }
        for (c, v) in est.iter().enumerate() {
            let (mean, se) = mean_and_stderr(v);
            let what = format!("field {k}, channel {c}");
            fam.mean_is(&what, mean, se, (N - 1) as f64, truth[c] as f64);
        }
    }
    fam.finish();
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
        origin: None,
        inputs: Default::default(),
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
/// the homogeneous slab's (Welch's test on the meters' own standard errors).
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
    let mut fam = Family::new("media: constant grid slab");
    for (ma, mb) in a.iter().zip(&b) {
        fam.means_agree(
            &format!("meter {}: homogeneous vs constant grid", ma.name),
            meter_mean(ma, 0),
            meter_mean(mb, 0),
        );
    }
    fam.finish();
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
            "density = \"plume\"\naxis = \"x\"\nfrom = 0.0",
            "media.slab.from",
            "only to density = linear",
        ),
        (
            "density = \"plume\"\naxis = \"w\"",
            "media.slab.axis",
            "unknown variant",
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

/// The procedural fields and their block majorants (deterministic): fBm is normalized to
/// [0, 1) and is not constant; the cloud is dense somewhere near its centre and zero beyond
/// its radius; and `max_in` bounds the field in every block of an 8^3 partition of the unit
/// box, at a lattice of points of each block including its corners. Delta and ratio tracking
/// are unbiased only under a true bound, so a majorant below the field anywhere is an error
/// (the tracking tests above cannot see it where the field happens to be thin).
#[test]
fn procedural_majorants_bound_their_fields() {
    let fbm = Fbm {
        octaves: 5,
        frequency: 4.0,
        seed: 7,
    };
    let (mut lo_v, mut hi_v) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..4096u32 {
        let u = Vec3::new(
            (i % 16) as f32 / 15.0,
            (i / 16 % 16) as f32 / 15.0,
            (i / 256) as f32 / 15.0,
        ) * 0.97
            + Vec3::splat(0.013);
        let v = fbm.eval(u);
        lo_v = lo_v.min(v);
        hi_v = hi_v.max(v);
    }
    assert!(
        lo_v >= 0.0 && hi_v < 1.0 && hi_v - lo_v > 0.3,
        "fBm over the box spans [{lo_v}, {hi_v}]: normalized to [0, 1) and not flat"
    );
    let plume = |axis| Field::Plume { fbm, axis };
    for field in [
        Field::Cloud(fbm),
        plume(Axis::X),
        plume(Axis::Y),
        plume(Axis::Z),
    ] {
        let n = 8;
        let mut peak = 0.0f32;
        for b in 0..n * n * n {
            let lo = Vec3::new((b % n) as f32, (b / n % n) as f32, (b / (n * n)) as f32) / n as f32;
            let hi = lo + Vec3::splat(1.0 / n as f32);
            let bound = field.max_in(lo, hi);
            for k in 0..125 {
                let f = Vec3::new((k % 5) as f32, (k / 5 % 5) as f32, (k / 25) as f32) / 4.0;
                let u = lo + (hi - lo) * f;
                let v = field.eval(u);
                peak = peak.max(v);
                assert!(
                    v <= bound,
                    "{field:?}: density {v} at {u} above the block majorant {bound} of [{lo}, {hi}]"
                );
            }
        }
        assert!(peak > 0.3, "{field:?}: peak density {peak}");
    }
    // a plume streams along its axis: the rising plume with the local coordinates permuted
    // (noise included), densest at the centre of the face it starts from
    let swap = |u: Vec3, axis| match axis {
        Axis::X => Vec3::new(u.y, u.x, u.z),
        Axis::Y => u,
        Axis::Z => Vec3::new(u.x, u.z, u.y),
    };
    for axis in [Axis::X, Axis::Z] {
        for k in 0..343 {
            let u = Vec3::new((k % 7) as f32, (k / 7 % 7) as f32, (k / 49) as f32) / 6.0;
            assert_eq!(
                plume(axis).eval(u),
                plume(Axis::Y).eval(swap(u, axis)),
                "{axis:?} {u}"
            );
        }
        let along = |h: f32, off: f32| swap(Vec3::new(0.5 + off, h, 0.5), axis);
        let source = plume(axis).eval(along(0.05, 0.0));
        assert!(
            source > 2.0 * plume(axis).eval(along(0.9, 0.0)),
            "{axis:?}: fades"
        );
        assert!(
            source > 2.0 * plume(axis).eval(along(0.05, 0.3)),
            "{axis:?}: narrow"
        );
    }
    // the cloud is dense in the middle and thins out towards its radius (the radial falloff
    // beats the noise), and beyond the radius (0.48 around the centre) there is nothing
    let cloud = Field::Cloud(fbm);
    let (mut inner, mut outer) = ((0.0f64, 0u32), (0.0f64, 0u32));
    for i in 0..32768u32 {
        let u = Vec3::new(
            (i % 32) as f32 + 0.5,
            (i / 32 % 32) as f32 + 0.5,
            (i / 1024) as f32 + 0.5,
        ) / 32.0;
        let r = (u - Vec3::splat(0.5)).length();
        let shell = if r < 0.2 {
            &mut inner
        } else if (0.36..0.48).contains(&r) {
            &mut outer
        } else {
            continue;
        };
        shell.0 += cloud.eval(u) as f64;
        shell.1 += 1;
    }
    let (inner, outer) = (inner.0 / inner.1 as f64, outer.0 / outer.1 as f64);
    assert!(
        inner > 2.0 * outer,
        "cloud: mean density {inner} within r < 0.2, {outer} in 0.36 <= r < 0.48"
    );
    for u in [
        Vec3::ZERO,
        Vec3::new(0.99, 0.5, 0.5),
        Vec3::new(0.5, 0.01, 0.5),
    ] {
        assert_eq!(cloud.eval(u), 0.0, "cloud density at {u}");
    }
}

/// Two estimators of exp(-tau) where the tests above are blind:
/// - ratio tracking in a medium denser than one (a constant grid of density 2.5, sigma_t 2, 0.25
///   deep: tau = 1.25), where the majorant rate is sigma_t times the block's density bound and
///   a smaller rate makes the factors 1 - sigma_t f / rate negative;
/// - the marched free flight (equidistant, Delta = 0.05) on the affine field, whose midpoint
///   sum is its exact optical depth: a flight passes the segment with probability exp(-tau)
///   exactly (the exact binomial tail).
#[test]
fn dense_ratio_tracking_and_marched_free_flight_are_exp_minus_tau() {
    const N: usize = 20_000;
    let mut fam = Family::new("media: dense ratio tracking, marched free flight");
    let dense = medium(
        Density::Grid(Grid::bake(3, |_| 2.5)),
        Vec3::splat(2.0),
        LineIntegral::DeltaTracking,
        1.0,
    );
    let ray = Ray::new(Vec3::new(0.5, 0.5, 0.0), Vec3::Z);
    let truth = dense.transmittance_exact(&ray, 0.25).x as f64;
    assert!(
        (truth - (-1.25f64).exp()).abs() < 1e-5,
        "exact transmittance {truth}"
    );
    let mut s = sampler(12, 0);
    let tr: Vec<f64> = (0..N)
        .map(|_| dense.transmittance(&ray, 0.25, &mut s).x as f64)
        .collect();
    let (mean, se) = mean_and_stderr(&tr);
    fam.mean_is(
        "ratio tracking, density 2.5",
        mean,
        se,
        (N - 1) as f64,
        truth,
    );

    let marched = medium(linear(), Vec3::ONE, LineIntegral::Equidistant, 0.05);
    let (ray, len) = oblique();
    let truth = marched.transmittance_exact(&ray, len).x as f64;
    let mut s = sampler(12, 1);
    let passed = (0..N)
        .filter(|_| !marched.sample_free_flight(&ray, len, &mut s).scattered)
        .count();
    fam.binomial(
        "marched free flight: passage",
        passed as u64,
        N as u64,
        truth,
    );
    fam.finish();
}

/// Ratio tracking's Russian roulette (pbrt-v4's rule: below `RR_THRESHOLD` in every channel, a
/// walk ends with probability `RR_Q` = 0.75 at each tentative collision and a survivor's
/// estimate is divided by 1 - `RR_Q`) keeps the estimate's mean exp(-tau): in media dense
/// enough that the running estimate falls below the threshold on most walks (exp(-tau) below
/// 2e-2 in every channel), against the exact optical depth, for the affine field, a grid and
/// the fBm cloud.
/// Most walks must end in the roulette (an estimate of exactly 0, which plain ratio tracking
/// gives only where the density meets its majorant), or the test would not test it.
#[test]
fn ratio_tracking_with_russian_roulette_keeps_exp_minus_tau() {
    const N: usize = 20_000;
    let (ray, len) = oblique();
    let mut fam = Family::new("media: ratio tracking with Russian roulette");
    for (k, (density, scale)) in [(linear(), 4.0), (bump_grid(), 3.0), (cloud(), 17.0)]
        .into_iter()
        .enumerate()
    {
        let sigma_t = Vec3::new(1.0, 1.5, 2.0) * scale;
        let m = medium(density, sigma_t, LineIntegral::DeltaTracking, 1.0);
        let truth = m.transmittance_exact(&ray, len);
        assert!(
            truth.max_element() < 0.02 && truth.min_element() > 1e-5,
            "field {k}: exact transmittance {truth} outside the roulette's range"
        );
        let mut s = sampler(14, k as u64);
        let mut est = [vec![], vec![], vec![]];
        let mut ended = 0;
        for _ in 0..N {
            let tr = m.transmittance(&ray, len, &mut s);
            ended += usize::from(tr == Rgb::ZERO);
            for c in 0..3 {
                est[c].push(tr[c] as f64);
            }
        }
        assert!(
            ended > N / 2,
            "field {k}: {ended} of {N} walks ended with 0, expected most (the roulette)"
        );
        for (c, v) in est.iter().enumerate() {
            let (mean, se) = mean_and_stderr(v);
            let what = format!("field {k}, channel {c}");
            fam.mean_is(&what, mean, se, (N - 1) as f64, truth[c] as f64);
        }
    }
    fam.finish();
}

/// A baked grid samples its function on the lattice u = (i, j, k) / (n - 1) of the unit box,
/// so trilinear interpolation reproduces an affine function exactly everywhere in the box.
#[test]
fn a_baked_affine_function_is_reproduced_exactly() {
    let f = |u: Vec3| 0.3 + 0.5 * u.x + 1.25 * u.y + 0.75 * u.z;
    for n in [2usize, 3, 5] {
        let g = Grid::bake(n, f);
        for i in 0..64u32 {
            let u = Vec3::new(
                (i % 4) as f32 / 3.0,
                (i / 4 % 4) as f32 / 3.0,
                (i / 16) as f32 / 3.0,
            ) * 0.9
                + Vec3::new(0.03, 0.07, 0.05);
            let (got, expect) = (g.eval(u), f(u));
            assert!(
                (got - expect).abs() < 1e-5,
                "n = {n}, u = {u}: {got} vs {expect}"
            );
        }
    }
}

/// The grid's line integral is exact cell by cell (two-point Gauss on the cubic of each cell)
/// along rays in every octant of directions, starting inside a cell: against composite Simpson
/// on 20000 pieces of the interpolated density itself (whose kinks at the cell faces cost it
/// about 1e-9). A DDA piece that straddles a cell face breaks the exactness.
#[test]
fn grid_line_integrals_are_exact_in_every_direction() {
    let g = Grid::bake(5, |u| {
        let k = (u * 4.0).round();
        0.1 + 0.45 * ((k.x * 7.0 + k.y * 3.0 + k.z * 5.0) % 4.0)
    });
    let u0 = Vec3::new(0.52, 0.47, 0.56);
    for sx in [-1.0f32, 1.0] {
        for sy in [-1.0f32, 1.0] {
            for sz in [-1.0f32, 1.0] {
                let du = Vec3::new(0.31 * sx, 0.27 * sy, 0.22 * sz);
                let tb = 1.4;
                let got = g.integrate(u0, du, 0.0, tb) as f64;
                let n = 20_000;
                let h = tb as f64 / n as f64;
                let simpson: f64 = (0..=n)
                    .map(|i| {
                        let w = if i == 0 || i == n {
                            1.0
                        } else if i % 2 == 1 {
                            4.0
                        } else {
                            2.0
                        };
                        w * g.eval(u0 + du * (i as f64 * h) as f32) as f64
                    })
                    .sum::<f64>()
                    * h
                    / 3.0;
                assert!(
                    (got - simpson).abs() < 2e-5 * simpson,
                    "direction {du}: the grid integrates {got}, Simpson {simpson}"
                );
            }
        }
    }
}

/// An edge's two free-flight pdfs from one optical depth (`Medium::free_flight_pdfs`, which
/// BDPT's and MLT's edges use): the forward one is `free_flight_pdf` bit for bit, the backward
/// one the pdf of the walk from the far end back to the origin (a collision density there when
/// asked), equal up to the f32 rounding of the two integrals (a few dozen cells, each adding
/// 2^-24 relative); in a homogeneous medium both are bit for bit.
#[test]
fn both_directions_of_an_edge_share_one_optical_depth() {
    let (ray, len) = oblique();
    let sigma_t = Vec3::new(0.5, 1.0, 2.5);
    let het = Medium::Heterogeneous(Box::new(medium(
        bump_grid(),
        sigma_t,
        LineIntegral::DeltaTracking,
        1.0,
    )));
    let hom = Medium::Homogeneous(Homogeneous::new(Rgb::ZERO, sigma_t, Phase::Isotropic).unwrap());
    for t in [0.1f32, 0.5, len * 0.99] {
        let back = Ray::new(ray.at(t), -ray.d);
        for (end, start) in [(false, false), (true, false), (false, true), (true, true)] {
            let (ab, ba) = het.free_flight_pdfs(&ray, t, end, start);
            let forward = het.free_flight_pdf(&ray, t, end);
            assert_eq!(ab.to_bits(), forward.to_bits(), "forward pdf at t = {t}");
            let backward = het.free_flight_pdf(&back, t, start) as f64;
            assert_close("backward pdf", ba as f64, backward, 1e-5);
            let (ab, ba) = hom.free_flight_pdfs(&ray, t, end, start);
            assert_eq!(ab.to_bits(), hom.free_flight_pdf(&ray, t, end).to_bits());
            assert_eq!(ba.to_bits(), hom.free_flight_pdf(&back, t, start).to_bits());
        }
    }
}

/// `Grid::eval_pair` (the two Gauss points of a span) is two `Grid::eval` calls bit for bit,
/// whether the points share a cell or not, inside the box and clamped outside it.
#[test]
fn paired_grid_lookups_equal_single_ones() {
    let g = Grid::bake(5, |u| (7.0 * u.x).sin().abs() + u.y * u.z + 0.1);
    let mut s = sampler(3, 0);
    let point = |s: &mut pathspace::math::Sampler| {
        Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 1.2 - Vec3::splat(0.1)
    };
    let (mut shared, mut apart) = (0, 0);
    for i in 0..20_000 {
        let a = point(&mut s);
        // every other pair a short step apart, mostly in one cell
        let b = if i % 2 == 0 {
            a + (point(&mut s) - Vec3::splat(0.5)) * 0.05
        } else {
            point(&mut s)
        };
        let (fa, fb) = g.eval_pair(a, b);
        assert_eq!(fa.to_bits(), g.eval(a).to_bits(), "at {a}");
        assert_eq!(
            fb.to_bits(),
            g.eval(b).to_bits(),
            "at {b} (paired with {a})"
        );
        let cell = |p: Vec3| {
            (p.clamp(Vec3::ZERO, Vec3::ONE) * 4.0)
                .floor()
                .min(Vec3::splat(3.0))
        };
        if cell(a) == cell(b) {
            shared += 1;
        } else {
            apart += 1;
        }
    }
    assert!(
        shared > 5000 && apart > 5000,
        "{shared} pairs in one cell, {apart} apart"
    );
}

/// `Grid::integrate_skipping` (the line integral that leaves out the cells whose eight vertices
/// are zero) is `Grid::integrate` bit for bit, on random lines through a grid with empty
/// corners, a lone non-zero vertex (its eight cells are not empty) and lines starting outside
/// the box (clamped lookups); and the lines cross both empty and non-empty cells.
#[test]
fn skipping_empty_cells_leaves_line_integrals_bit_for_bit() {
    let g = Grid::bake(9, |u| {
        let k = (u * 8.0).round();
        if k == Vec3::new(1.0, 6.0, 2.0) {
            return 0.75;
        }
        (0.3 - (u - Vec3::splat(0.5)).length()).max(0.0) * (1.0 + k.x)
    });
    let empty = EmptyCells::new(&g);
    let mut s = sampler(11, 0);
    let mut point = || Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 1.4 - Vec3::splat(0.2);
    let (mut zero, mut positive) = (0, 0);
    for _ in 0..20_000 {
        let (u0, u1) = (point(), point());
        let (ta, tb) = (0.1, 1.0);
        let want = g.integrate(u0, u1 - u0, ta, tb);
        let got = g.integrate_skipping(&empty, u0, u1 - u0, ta, tb);
        assert_eq!(got.to_bits(), want.to_bits(), "from {u0} to {u1}");
        if want > 0.0 {
            positive += 1;
        } else {
            zero += 1;
        }
    }
    assert!(
        zero > 1000 && positive > 1000,
        "{zero} empty lines, {positive} not"
    );
}

/// The distance between two positive finite floats in units in the last place.
fn ulps(a: f32, b: f32) -> u32 {
    (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
}

/// `Medium::sample_free_flight_weight` (the path tracer's walk, which needs only the weight):
/// in a grey tracked grid medium it skips the exact optical depth, and its weight is the full
/// flight's (sigma_s f / (sigma_t f) for a collision, 1 for passage) to rounding: a few ulps
/// (the full flight's weight has about ten roundings, each within half an ulp, the skipped
/// one three), with the same outcome and the same random numbers, on random rays through a
/// grid with empty cells, starting inside, outside and ending inside the box. A chromatic or a
/// marched medium computes the depth: there the weight is the full flight's bit for bit.
#[test]
fn weight_only_free_flights_weigh_like_full_ones() {
    /// Rounding bound of the grey case, in ulps of each channel.
    const MAX_ULPS: u32 = 8;
    let g = Grid::bake(9, |u| {
        (0.35 - (u - Vec3::splat(0.5)).length()).max(0.0) * 20.0 * u.y
    });
    let grey = Rgb::splat(0.6);
    let cases = [
        (grey, LineIntegral::DeltaTracking, false),
        (Vec3::new(0.6, 0.3, 1.2), LineIntegral::DeltaTracking, true),
        (grey, LineIntegral::RandomOffset, true),
    ];
    for (sigma_a, li, exact) in cases {
        let h = Heterogeneous::new(
            Density::Grid(g.clone()),
            unit_box(),
            sigma_a,
            Rgb::splat(2.4),
            Phase::Isotropic,
            li,
            0.01,
        )
        .unwrap();
        let m = Medium::Heterogeneous(Box::new(h));
        let mut rays = sampler(17, 0);
        let (mut collisions, mut passages, mut worst) = (0, 0, 0);
        for i in 0..20_000 {
            let mut u = || rays.next_f32();
            let o = Vec3::new(u(), u(), u()) * 2.0 - Vec3::splat(0.5);
            // toward a point of the sphere the density fills
            let d = (Vec3::new(u(), u(), u()) * 0.5 + Vec3::splat(0.25) - o).normalize();
            let (ray, t_max) = (Ray::new(o, d), 3.0 * u());
            let (mut s_full, mut s_weight) = (sampler(19, i), sampler(19, i));
            let full = m.sample_free_flight(&ray, t_max, &mut s_full);
            let w = m.sample_free_flight_weight(&ray, t_max, &mut s_weight);
            let at = format!("{li:?} sigma_a {sigma_a}, ray {i} from {o} along {d}, t_max {t_max}");
            assert_eq!(
                (w.t().to_bits(), w.scattered()),
                (full.t.to_bits(), full.scattered),
                "{at}"
            );
            assert_eq!(
                s_weight.next_f32(),
                s_full.next_f32(),
                "random numbers, {at}"
            );
            assert_eq!(w.sigma_s(), full.sigma_s, "{at}");
            let (a, b) = (w.weight().to_array(), full.weight().to_array());
            for c in 0..3 {
                let d = ulps(a[c], b[c]);
                assert!(
                    if exact { d == 0 } else { d <= MAX_ULPS },
                    "weight {a:?} vs the full flight's {b:?} ({d} ulps), {at}"
                );
                worst = worst.max(d);
            }
            if full.scattered {
                collisions += 1;
            } else if full.transmittance.x < 0.9 {
                passages += 1;
            }
        }
        eprintln!("{li:?} sigma_a {sigma_a}: worst {worst} ulps");
        // both outcomes, passages through real depth among them
        assert!(
            collisions > 1000 && passages > 1000,
            "{collisions} collisions, {passages} attenuated passages"
        );
    }
}
