//! The executable specification of the chapter "Measuring a renderer": error metrics against
//! hand-computed values, the least-squares power-law fit on exact power laws, the convergence
//! study's CSV, the order of convergence of the path tracer (an oracle: a white-furnace-like
//! scene whose pixels are exactly albedo x radiance), the variance-based estimate, the heatmap,
//! and the reference's refusal to overwrite another scene's reference.

use crate::common;

use common::stats::{assert_significant, p_mean, Family};
use std::path::{Path, PathBuf};
use std::process::Command;

use approx::assert_relative_eq;
use pathspace::image_io::{self, Image, ImageMeta};
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::measure::convergence::{self, CheckpointRow, ConvergeConfig, CSV_HEADER};
use pathspace::measure::{chart, heatmap, metrics, stats};
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::Rgb;

/// Albedo of the furnace quad and radiance of its environment: every pixel converges to their
/// product (the quad is flat, so it never sees itself, and it fills the view).
const ALBEDO: f32 = 0.5;
const RADIANCE: f32 = 1.0;

/// A 16x16 camera looking at a huge lambert quad under a constant environment: smooth (every
/// pixel has the same exact value ALBEDO x RADIANCE) yet noisy (light sampling of the sky).
fn furnace_toml(albedo: f32) -> String {
    format!(
        r#"
[render]
seed = 7

[camera]
type = "pinhole"
eye = [0.0, 0.0, 1.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [16, 16]

[materials.grey]
type = "lambert"
albedo = {albedo}

[[shapes]]
type = "quad"
origin = [-50.0, -50.0, 0.0]
u = [100.0, 0.0, 0.0]
v = [0.0, 100.0, 0.0]
material = "grey"

[[lights]]
type = "environment"
radiance = {RADIANCE}
"#
    )
}

fn furnace() -> Scene {
    Scene::load(&SceneSource::embedded(
        "furnace.toml",
        &furnace_toml(ALBEDO),
    ))
    .expect("the furnace scene loads")
}

/// The exact image of the furnace scene, times `scale`.
fn exact(scale: f32) -> Image {
    let mut image = Image::new(16, 16);
    image.pixels.fill(Rgb::splat(ALBEDO * RADIANCE * scale));
    image
}

/// A fresh directory under the test target's scratch space.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("measure")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn img(width: u32, height: u32, pixels: &[[f32; 3]]) -> Image {
    Image {
        width,
        height,
        pixels: pixels.iter().map(|p| Rgb::from_array(*p)).collect(),
    }
}

#[test]
fn metrics_match_hand_computed_values() {
    let a = img(2, 1, &[[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]);
    let b = img(2, 1, &[[1.0, 1.0, 1.0], [2.0, 0.0, 0.0]]);
    let m = metrics::compare(&a, &b).unwrap();
    // differences (0, 1, 2) and (-2, 0, 0): squared sum 9 over 6 values
    assert_relative_eq!(m.rmse, (9.0f64 / 6.0).sqrt(), max_relative = 1e-12);
    let eps = metrics::RELMSE_EPSILON;
    let rel = (1.0 / (1.0 + eps) + 4.0 / (1.0 + eps) + 4.0 / (4.0 + eps)) / 6.0;
    assert_relative_eq!(m.relmse, rel, max_relative = 1e-12);
    assert_relative_eq!(m.max_abs, 2.0);
    // from 0 to 2: every positive f32 below 2, 2^30 of them
    assert_eq!(m.max_steps, 2.0f32.to_bits() as u64);
    let next = f32::from_bits(1.0f32.to_bits() + 1);
    assert_eq!(metrics::f32_steps(1.0, next), 1);
    assert_eq!(metrics::f32_steps(-0.0, 0.0), 0);
    assert_eq!(metrics::f32_steps(-f32::from_bits(1), f32::from_bits(1)), 2);
    assert!(metrics::compare(&a, &img(1, 1, &[[0.0; 3]]))
        .unwrap_err()
        .to_string()
        .contains("differ in size"));
}

#[test]
fn power_law_fit_recovers_exact_power_laws() {
    let close = |what: &str, got: f64, expected: f64| {
        assert!(
            (got - expected).abs() <= 1e-12 * expected.abs().max(1.0),
            "{what}: got {got}, expected {expected}"
        );
    };
    for (c, s) in [(3.0, -0.5), (0.02, -1.0), (7.0, 0.25)] {
        let x: Vec<f64> = (0..8).map(|k| 2f64.powi(k)).collect();
        let y: Vec<f64> = x.iter().map(|x| c * x.powf(s)).collect();
        let fit = stats::fit_power_law(&x, &y).unwrap();
        let what = format!("y = {c} x^{s}");
        close(&format!("{what}: slope"), fit.slope, s);
        close(
            &format!("{what}: intercept ln C"),
            fit.intercept,
            f64::ln(c),
        );
        assert!(
            fit.slope_stderr < 1e-12,
            "an exact power law has no residual: got standard error {}, expected 0",
            fit.slope_stderr
        );
        close(
            &format!("{what}: predict(3)"),
            fit.predict(3.0),
            c * 3f64.powf(s),
        );
    }
    // by hand: ln x = 0, 1, 2 and ln y = 0, 1, 3: S_xx = 2, S_xy = 3, slope 3/2, residuals
    // (1/6, -1/3, 1/6), SSR = 1/6, se = sqrt(SSR / (n - 2) / S_xx) = sqrt(1/12)
    let x = [1.0, 1f64.exp(), 2f64.exp()];
    let y = [1.0, 1f64.exp(), 3f64.exp()];
    let fit = stats::fit_power_law(&x, &y).unwrap();
    close("by hand: slope", fit.slope, 1.5);
    close("by hand: intercept", fit.intercept, -1.0 / 6.0);
    close(
        "by hand: slope's standard error sqrt(SSR / (n - 2) / S_xx)",
        fit.slope_stderr,
        (1.0f64 / 12.0).sqrt(),
    );
    // independent runs: mean slope, standard error from their spread
    let fits: Vec<stats::PowerLawFit> = [-0.4, -0.5, -0.6]
        .iter()
        .map(|&s| stats::PowerLawFit {
            slope: s,
            slope_stderr: 0.0,
            intercept: 1.0,
            points: 5,
        })
        .collect();
    let combined = stats::combine_fits(&fits).unwrap();
    close("mean slope of three runs", combined.slope, -0.5);
    // sample s.d. 0.1 over 3 runs: se = 0.1 / sqrt(3)
    close(
        "standard error of the mean slope",
        combined.slope_stderr,
        0.1 / 3f64.sqrt(),
    );
    assert_eq!(combined.points, 15);
    assert!(stats::combine_fits(&fits[..1]).is_err());
    // two points: a slope but no standard error
    assert!(stats::fit_power_law(&[1.0, 2.0], &[1.0, 0.5])
        .unwrap()
        .slope_stderr
        .is_nan());
}

#[test]
fn power_law_fit_rejects_bad_input() {
    assert!(stats::fit_power_law(&[1.0], &[1.0])
        .unwrap_err()
        .to_string()
        .contains("at least 2"));
    assert!(stats::fit_power_law(&[1.0, 2.0], &[1.0, 0.0])
        .unwrap_err()
        .to_string()
        .contains("positive"));
    assert!(stats::fit_power_law(&[2.0, 2.0, 2.0], &[1.0, 2.0, 3.0])
        .unwrap_err()
        .to_string()
        .contains("same"));
    assert!(stats::fit_power_law(&[1.0, 2.0], &[1.0]).is_err());
}

#[test]
fn mean_and_standard_error_by_hand() {
    let m = stats::mean_stderr(&[1.0, 2.0, 3.0, 4.0]);
    assert_relative_eq!(m.mean, 2.5);
    // sample variance 5/3, standard error sqrt(5/3 / 4)
    assert_relative_eq!(m.stderr, (5.0f64 / 12.0).sqrt(), epsilon = 1e-12);
    assert_eq!(stats::mean_stderr(&[4.0]).stderr, 0.0);
}

#[test]
fn checkpoints_are_geometric_up_to_the_budget() {
    let t = convergence::checkpoint_times(10.0, 5).unwrap();
    assert_eq!(t.len(), 5);
    assert_relative_eq!(
        t[0],
        10.0 * convergence::FIRST_CHECKPOINT_FRACTION,
        epsilon = 1e-12
    );
    assert_relative_eq!(t[4], 10.0, epsilon = 1e-12);
    for w in t.windows(3) {
        assert_relative_eq!(w[1] / w[0], w[2] / w[1], epsilon = 1e-12);
    }
    assert_eq!(convergence::checkpoint_times(3.0, 1).unwrap(), vec![3.0]);
    assert!(convergence::checkpoint_times(0.0, 4).is_err());
    assert!(convergence::checkpoint_times(f64::NAN, 4).is_err());
    assert!(convergence::checkpoint_times(1.0, 0).is_err());
}

fn rows_of(csv: &str) -> Vec<Vec<String>> {
    csv.lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn converge_writes_the_csv_and_charts() {
    let scene = furnace();
    let dir = scratch("converge");
    let config = ConvergeConfig {
        budget: 0.2,
        checkpoints: 6,
        runs: 2,
        seed: 1,
        max_depth: None,
        shard: None,
    };
    let mut runs_heard = 0;
    let settings = pathspace::integrator::RenderSettings::for_scene(&scene);
    let rows = convergence::converge(
        &scene,
        &SceneSource::embedded("furnace.toml", &furnace_toml(ALBEDO)),
        &settings,
        &exact(1.0),
        &[IntegratorKind::Path],
        &config,
        &mut |_| runs_heard += 1,
    )
    .unwrap();
    assert_eq!(runs_heard, 2);
    let csv_path = dir.join("convergence.csv");
    convergence::write_csv(&csv_path, &rows).unwrap();
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    assert_eq!(
        csv.lines().next(),
        Some("integrator,run,checkpoint,seconds,samples,rmse,relmse,efficiency")
    );
    assert_eq!(
        CSV_HEADER,
        "integrator,run,checkpoint,seconds,samples,rmse,relmse,efficiency"
    );
    let table = rows_of(&csv);
    assert_eq!(table.len(), rows.len());
    for run in ["0", "1"] {
        let mine: Vec<&Vec<String>> = table
            .iter()
            .filter(|r| r[0] == "path" && r[1] == run)
            .collect();
        assert!(
            mine.len() >= 2,
            "run {run} recorded {} checkpoints",
            mine.len()
        );
        let seconds: Vec<f64> = mine.iter().map(|r| r[3].parse().unwrap()).collect();
        let samples: Vec<u64> = mine.iter().map(|r| r[4].parse().unwrap()).collect();
        let ks: Vec<usize> = mine.iter().map(|r| r[2].parse().unwrap()).collect();
        assert!(
            seconds.windows(2).all(|w| w[0] < w[1]),
            "time must increase: {seconds:?}"
        );
        assert!(
            samples.windows(2).all(|w| w[0] < w[1]),
            "samples must increase: {samples:?}"
        );
        assert!(
            ks.windows(2).all(|w| w[0] < w[1]),
            "checkpoints must increase: {ks:?}"
        );
        assert_eq!(*ks.last().unwrap(), 5, "the last checkpoint is the budget");
        assert!(*seconds.last().unwrap() >= 0.2);
        for r in &mine {
            let (relmse, secs, eff): (f64, f64, f64) = (
                r[6].parse().unwrap(),
                r[3].parse().unwrap(),
                r[7].parse().unwrap(),
            );
            assert_relative_eq!(eff, 1.0 / (relmse * secs), max_relative = 1e-4);
        }
    }
    let curves = convergence::summarize(&rows);
    assert_eq!(curves.len(), 1);
    assert!(curves[0].relmse_vs_time.is_some());
    let written = chart::write_charts(&dir, &curves, Some(1e-5)).unwrap();
    assert_eq!(written.len(), 4);
    for name in [
        "error-vs-time.svg",
        "error-vs-time.png",
        "efficiency.svg",
        "efficiency.png",
    ] {
        assert!(
            dir.join(name).metadata().unwrap().len() > 1000,
            "{name} is missing or empty"
        );
    }
    assert_eq!(png_size(&dir.join("error-vs-time.png")), chart::CHART_SIZE);
    let svg = std::fs::read_to_string(dir.join("error-vs-time.svg")).unwrap();
    assert!(
        svg.contains("relMSE (dimensionless)")
            && svg.contains("slope")
            && svg.contains("reference noise"),
        "axis label or legend missing"
    );
}

/// Runs of the order-of-convergence test; the slope's standard error comes from their spread
/// (Student-t with ORDER_RUNS - 1 degrees of freedom).
const ORDER_RUNS: usize = 16;
/// The checkpoints of the order-of-convergence test, in samples per pixel: seven doublings.
/// Counted in samples, not seconds, so that the test measures the same thing on any machine
/// and under any load.
const ORDER_CHECKPOINTS: [u64; 8] = [4, 8, 16, 32, 64, 128, 256, 512];

/// A convergence study counted in samples: each run renders passes of 1 sample per pixel (seed
/// `convergence::run_seed(seed, run)`, as `converge` seeds its runs) and is compared with the
/// reference at every checkpoint. The clock is not read: the rows' seconds and efficiency are
/// NaN (so `summarize` fits no time slope), their samples, RMSE and relMSE are measured.
fn sample_study(scene: &Scene, reference: &Image, seed: u64) -> Vec<CheckpointRow> {
    let mut rows = Vec::new();
    for run in 0..ORDER_RUNS {
        let mut renderer = Renderer::new(
            scene,
            IntegratorKind::Path,
            convergence::run_seed(seed, run),
            None,
        );
        for (k, &spp) in ORDER_CHECKPOINTS.iter().enumerate() {
            while renderer.film.as_ref().unwrap().spp < spp {
                renderer.pass(1, &|| {});
            }
            let film = renderer.film.as_ref().unwrap();
            let m = metrics::compare(&film.image(), reference).unwrap();
            rows.push(CheckpointRow {
                integrator: "path".into(),
                run,
                checkpoint: k,
                seconds: f64::NAN,
                samples: film.spp,
                rmse: m.rmse,
                relmse: m.relmse,
                efficiency: f64::NAN,
            });
        }
    }
    rows
}

/// The fitted order of RMSE against samples, over the runs: (mean slope, its standard error
/// from the runs' spread, degrees of freedom).
fn rmse_order(rows: &[CheckpointRow]) -> (f64, f64, f64) {
    let curve = &convergence::summarize(rows)[0];
    assert!(curve.relmse_vs_time.is_none(), "no clock was read");
    let fit = curve.rmse_vs_samples.expect("enough checkpoints to fit");
    assert_eq!(fit.points, ORDER_RUNS * ORDER_CHECKPOINTS.len());
    (fit.slope, fit.slope_stderr, (ORDER_RUNS - 1) as f64)
}

#[test]
fn path_tracer_rmse_falls_as_samples_to_the_minus_one_half() {
    let scene = furnace();
    let rows = sample_study(&scene, &exact(1.0), 3);
    let (slope, se, dof) = rmse_order(&rows);
    eprintln!("unbiased: RMSE ~ samples^{slope:.3} +- {se:.3}");
    let mut fam = Family::new("measure: RMSE order of the path tracer");
    fam.mean_is("RMSE order", slope, se, dof, -0.5);
    fam.finish();

    // the check can fail: against a reference 2 % off (as a biased estimator would be), the
    // error stalls at the bias and the fitted order is far from 1/2
    let rows = sample_study(&scene, &exact(1.02), 3);
    let (slope, se, dof) = rmse_order(&rows);
    eprintln!("2 % off: RMSE ~ samples^{slope:.3} +- {se:.3}");
    assert_significant(
        "the order against a 2 % biased reference",
        p_mean(slope, se, dof, -0.5),
    );
}

#[test]
fn variance_estimate_predicts_the_measured_relmse() {
    let scene = furnace();
    let mut renderer = Renderer::new(&scene, IntegratorKind::Path, 11, None);
    for _ in 0..16 {
        renderer.pass(4, &|| {});
    }
    let film = renderer.film.as_ref().unwrap();
    let (image, variance) = (film.image(), film.variance_of_mean());
    let estimated = stats::estimated_relmse(&image, &variance).unwrap();
    let measured = metrics::compare(&image, &exact(1.0)).unwrap().relmse;
    eprintln!("measured relMSE {measured:.3e}, estimated {estimated:.3e}");
    // the estimate by hand: mean over pixels and channels of Var[mean] / (mean^2 + eps), in f64
    // on the f32 images (only summation order differs)
    let by_hand = image
        .pixels
        .iter()
        .zip(&variance.pixels)
        .flat_map(|(m, v)| {
            (0..3).map(move |c| v[c] as f64 / ((m[c] as f64).powi(2) + metrics::RELMSE_EPSILON))
        })
        .sum::<f64>()
        / (3 * image.pixels.len()) as f64;
    assert_relative_eq!(estimated, by_hand, max_relative = 1e-12);
    // What makes it a prediction: the per-pixel variance of the mean is an unbiased estimate of
    // the pixel's squared error against the exact value r = ALBEDO x RADIANCE, so the terms
    // ((x - r)^2 - Var[mean]) / (r^2 + eps) of the 256 independent pixels (the furnace is gray:
    // one channel) have mean zero exactly.
    let r = (ALBEDO * RADIANCE) as f64;
    let w = 1.0 / (r * r + metrics::RELMSE_EPSILON);
    let terms: Vec<f64> = image
        .pixels
        .iter()
        .zip(&variance.pixels)
        .map(|(x, v)| ((x.x as f64 - r).powi(2) - v.x as f64) * w)
        .collect();
    let (mean, se) = common::mean_and_stderr(&terms);
    let mut fam = Family::new("measure: the variance estimate predicts relMSE");
    fam.mean_is(
        "squared error minus estimated variance",
        mean,
        se,
        (terms.len() - 1) as f64,
        0.0,
    );
    fam.finish();
}

fn png_size(path: &Path) -> (u32, u32) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let reader = decoder.read_info().unwrap();
    let info = reader.info();
    (info.width, info.height)
}

fn png_pixels(path: &Path) -> Vec<u8> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    buf
}

#[test]
fn heatmap_is_a_png_of_the_image_size_with_the_documented_colours() {
    let dir = scratch("heatmap");
    let (w, h) = (5, 3);
    let b = img(w, h, &[[1.0; 3]; 15]);
    let mut a = b.clone();
    a.pixels[1] = Rgb::splat(3.0); // relative error ~2: past the top of the scale
    a.pixels[2] = Rgb::splat(1.0 + 1e-1 * (1.0 + metrics::RELMSE_EPSILON).sqrt() as f32); // 10 %
    let out = dir.join("heat.png");
    heatmap::write_heatmap(&out, &a, &b).unwrap();
    let (cw, ch) = png_size(&out);
    assert_eq!(
        (cw, ch),
        (w + heatmap::BAR_PANEL, heatmap::BAR_MIN_HEIGHT),
        "the heatmap and its colour bar's panel"
    );
    let all = png_pixels(&out);
    let at = |x: u32, y: u32| {
        let i = ((y * cw + x) * 3) as usize;
        all[i..i + 3].to_vec()
    };
    // the colour bar: the top colour at its top, the bottom colour at its bottom
    let bar_x = w + heatmap::BAR_X + heatmap::BAR_W / 2;
    assert_eq!(at(bar_x, heatmap::BAR_MARGIN), heatmap::VIRIDIS[8]);
    assert_eq!(at(bar_x, ch - heatmap::BAR_MARGIN - 1), heatmap::VIRIDIS[0]);
    // the heatmap itself, pixel for pixel in the top-left corner
    let px: Vec<u8> = (0..h)
        .flat_map(|y| (0..w).flat_map(move |x| at(x, y)))
        .collect();
    assert_eq!(
        &px[0..3],
        &heatmap::VIRIDIS[0],
        "no error: the bottom colour"
    );
    assert_eq!(
        &px[3..6],
        &heatmap::VIRIDIS[8],
        "error past 100 %: the top colour"
    ); // 10 % = 10^-1 sits at 2/3 of the log scale from 10^-3 to 10^0
    assert_eq!(&px[6..9], &heatmap::viridis(2.0 / 3.0));
    let errors = heatmap::relative_error(&a, &b).unwrap();
    assert_relative_eq!(errors[2], 0.1, max_relative = 1e-5);
    assert!(heatmap::write_heatmap(&out, &a, &img(1, 1, &[[0.0; 3]])).is_err());
}

#[test]
fn external_images_are_read_in_time_order() {
    let dir = scratch("external");
    let reference = exact(1.0);
    image_io::write_exr(&dir.join("2.5.exr"), &exact(1.1), &ImageMeta::default()).unwrap();
    let mut meta = ImageMeta::default();
    meta.set("seconds", 0.5).set("spp", 16);
    image_io::write_exr(&dir.join("early.exr"), &exact(1.2), &meta).unwrap();
    let rows = convergence::external_rows("peer", &dir, &reference).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (rows[0].seconds, rows[0].samples, rows[0].checkpoint),
        (0.5, 16, 0)
    );
    assert_eq!(
        (rows[1].seconds, rows[1].samples, rows[1].checkpoint),
        (2.5, 0, 1)
    );
    assert!(rows[0].relmse > rows[1].relmse);
    image_io::write_exr(&dir.join("unnamed.exr"), &exact(1.0), &ImageMeta::default()).unwrap();
    let err = convergence::external_rows("peer", &dir, &reference)
        .unwrap_err()
        .to_string();
    assert!(err.contains("seconds"), "{err}");
}

fn pathspace(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .args(args)
        .output()
        .expect("the binary runs")
}

#[test]
fn a_reference_of_another_scene_is_refused() {
    let dir = scratch("refuse");
    let a = dir.join("a.toml");
    let b = dir.join("b.toml");
    std::fs::write(&a, furnace_toml(0.5)).unwrap();
    std::fs::write(&b, furnace_toml(0.8)).unwrap();
    let reference = dir.join("ref.exr");
    let (a, b, r) = (
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        reference.to_str().unwrap(),
    );

    let out = pathspace(&["reference", a, "--spp", "4", "-o", r, "--threads", "1"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (_, meta) = image_io::read_exr(&reference).unwrap();
    assert_eq!(meta.get("spp"), Some("4"));
    assert_eq!(meta.get("integrator"), Some("path"));
    assert_eq!(meta.get("scene_hash").map(str::len), Some(16));
    // the same scene may refresh its own reference
    let out = pathspace(&["reference", a, "--spp", "8", "-o", r, "--seed", "5"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        image_io::read_exr(&reference).unwrap().1.get("seed"),
        Some("5")
    );

    let out = pathspace(&["reference", b, "--spp", "4", "-o", r]);
    assert!(
        !out.status.success(),
        "another scene's reference was overwritten"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("refusing to overwrite") && stderr.contains("another scene"),
        "{stderr}"
    );
    assert_eq!(
        image_io::read_exr(&reference).unwrap().1.get("spp"),
        Some("8"),
        "the file was touched"
    );

    // and converge will not measure scene b against it
    let out = pathspace(&[
        "converge",
        b,
        "--reference",
        r,
        "--budget",
        "0.01",
        "-o",
        dir.join("c").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("another scene"));

    // bad numbers are errors, not panics
    let c = dir.join("c");
    let c = c.to_str().unwrap();
    for bad in [
        &["converge", a, "--reference", r, "--budget", "-1", "-o", c][..],
        &[
            "converge",
            a,
            "--reference",
            r,
            "--budget",
            "1",
            "--checkpoints",
            "0",
            "-o",
            c,
        ],
        &[
            "converge",
            a,
            "--reference",
            r,
            "--budget",
            "1",
            "--integrators",
            "nope",
            "-o",
            c,
        ],
        &["reference", a, "--spp", "0", "-o", r],
    ] {
        let out = pathspace(bad);
        assert_eq!(
            out.status.code(),
            Some(1),
            "{bad:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn diff_writes_a_heatmap_and_render_reports_its_estimated_relmse() {
    let dir = scratch("cli");
    let scene = dir.join("f.toml");
    std::fs::write(&scene, furnace_toml(0.5)).unwrap();
    let (s, x) = (scene.to_str().unwrap(), dir.join("x.exr"));
    let out = pathspace(&[
        "render",
        s,
        "--spp",
        "8",
        "--json",
        "-o",
        x.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["estimated_relmse"].as_f64().unwrap() > 0.0, "{json}");

    let reference = dir.join("exact.exr");
    image_io::write_exr(&reference, &exact(1.0), &ImageMeta::default()).unwrap();
    let heat = dir.join("heat.png");
    let out = pathspace(&[
        "diff",
        x.to_str().unwrap(),
        reference.to_str().unwrap(),
        "--heatmap",
        heat.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        png_size(&heat),
        (16 + heatmap::BAR_PANEL, heatmap::BAR_MIN_HEIGHT)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("#440154") && stdout.contains("#fde725"),
        "the legend is printed: {stdout}"
    );
}

/// mdBook prints an empty listing when an anchor is missing: every include of the chapter must
/// name an existing, non-empty anchor.
#[test]
fn the_chapter_includes_existing_anchors() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let chapter = std::fs::read_to_string(root.join("book/src/measuring.md")).unwrap();
    let mut count = 0;
    for part in chapter.split("{{#include ").skip(1) {
        let spec = part.split("}}").next().unwrap();
        let (file, anchor) = spec.rsplit_once(':').expect("includes name an anchor");
        let source = std::fs::read_to_string(root.join("book/src").join(file))
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let start = format!("// ANCHOR: {anchor}\n");
        let end = format!("// ANCHOR_END: {anchor}");
        let body = source
            .split_once(&start)
            .and_then(|(_, rest)| rest.split_once(&end))
            .map(|(body, _)| body)
            .unwrap_or_else(|| panic!("{file} has no anchor {anchor}"));
        assert!(body.trim().len() > 20, "{file}:{anchor} is empty");
        count += 1;
    }
    assert!(count >= 4, "the chapter includes only {count} listings");
}

/// `converge --propagation` compares the strategies of an inhomogeneous medium on one scene and
/// one reference, one line per integrator and strategy; a scene without such a medium is refused.
#[test]
fn converge_compares_propagation_strategies() {
    let dir = scratch("propagation");
    let scene = dir.join("linear.toml");
    std::fs::write(
        &scene,
        r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 30.0
resolution = [8, 8]
[media.ramp]
type = "procedural"
density = "linear"
axis = "y"
from = 0.0
to = 2.0
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
sigma_a = 0.2
sigma_s = 0.5
propagation = "delta-tracking"
[[shapes]]
type = "box"
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
material = "null"
interior = "ramp"
[[lights]]
type = "environment"
radiance = 1.0
"#,
    )
    .unwrap();
    let reference = dir.join("ref.exr");
    let out = pathspace(&[
        "reference",
        scene.to_str().unwrap(),
        "--spp",
        "64",
        "-o",
        reference.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let conv = dir.join("conv");
    let out = pathspace(&[
        "converge",
        scene.to_str().unwrap(),
        "--reference",
        reference.to_str().unwrap(),
        "--integrators",
        "path",
        "--propagation",
        "equidistant,delta-tracking",
        "--budget",
        "0.2",
        "--checkpoints",
        "3",
        "-o",
        conv.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(conv.join("convergence.csv")).unwrap();
    assert!(
        csv.lines().any(|l| l.starts_with("path/equidistant,")),
        "{csv}"
    );
    assert!(
        csv.lines().any(|l| l.starts_with("path/delta-tracking,")),
        "{csv}"
    );
    // the same option on a scene without an inhomogeneous medium is an error, not a silent no-op
    let plain = dir.join("plain.toml");
    std::fs::write(&plain, furnace_toml(0.5)).unwrap();
    let plain_ref = dir.join("plain-ref.exr");
    assert!(pathspace(&[
        "reference",
        plain.to_str().unwrap(),
        "--spp",
        "4",
        "-o",
        plain_ref.to_str().unwrap()
    ])
    .status
    .success());
    let out = pathspace(&[
        "converge",
        plain.to_str().unwrap(),
        "--reference",
        plain_ref.to_str().unwrap(),
        "--propagation",
        "stratified",
        "--budget",
        "0.1",
        "-o",
        dir.join("c2").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no inhomogeneous medium"));
}

/// The twin estimate of relMSE's variance part: two renders with independent noise of known
/// variance around the same image give mean(sigma^2 / (r^2 + eps)) (a mean of its independent
/// per-pixel terms, tested with their own spread), whatever a (biased) reference says; a biased
/// reference moves relMSE but not the twin estimate.
#[test]
fn twin_variance_recovers_the_noise_of_independent_renders() {
    let (w, h) = (64u32, 64u32);
    let truth: Vec<Rgb> = (0..w * h)
        .map(|i| Rgb::splat(0.05 + 0.5 * (i % 17) as f32 / 17.0))
        .collect();
    let half = 0.05f32; // uniform noise on [-half, half]: variance half^2 / 3
    let noisy = |seed: u64| Image {
        width: w,
        height: h,
        pixels: truth
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let mut s = pathspace::math::Sampler::new(seed, i as u64, 0);
                *t + Rgb::new(s.next_f32(), s.next_f32(), s.next_f32()) * (2.0 * half)
                    - Rgb::splat(half)
            })
            .collect(),
    };
    let (a1, a2) = (noisy(1), noisy(2));
    // a reference 10% too bright: relMSE grows, the twin estimate only reweights pixels
    let reference = Image {
        width: w,
        height: h,
        pixels: truth.clone(),
    };
    let v = metrics::twin_variance(&a1, &a2, &reference).unwrap();
    let var = (half as f64).powi(2) / 3.0;
    let terms: Vec<f64> = truth
        .iter()
        .flat_map(|t| (0..3).map(move |c| var / ((t[c] as f64).powi(2) + metrics::RELMSE_EPSILON)))
        .collect();
    let expected = terms.iter().sum::<f64>() / terms.len() as f64;
    // the twin estimate is the mean of the per-term (a1 - a2)^2 / 2 / (r^2 + eps), independent
    // terms whose own spread gives its standard error
    let twin_terms: Vec<f64> = a1
        .pixels
        .iter()
        .zip(&a2.pixels)
        .zip(&reference.pixels)
        .flat_map(|((p, q), r)| {
            (0..3).map(move |c| {
                let d = p[c] as f64 - q[c] as f64;
                d * d / 2.0 / ((r[c] as f64).powi(2) + metrics::RELMSE_EPSILON)
            })
        })
        .collect();
    let (t, t_se) = common::mean_and_stderr(&twin_terms);
    assert!(
        (t - v).abs() <= 1e-9 * v,
        "twin variance {v} is the mean of its terms {t}"
    );
    let mut fam = Family::new("measure: twin variance");
    let dof = (twin_terms.len() - 1) as f64;
    fam.mean_is("twin variance", v, t_se, dof, expected);
    let biased = Image {
        width: w,
        height: h,
        pixels: truth.iter().map(|t| *t * 1.1).collect(),
    };
    let m = metrics::compare(&a1, &biased).unwrap().relmse;
    let vb = metrics::twin_variance(&a1, &a2, &biased).unwrap();
    // per pixel and channel, (a1 - b)^2 w - (a1 - a2)^2 w / 2 has mean bias^2 w: its sample
    // standard error bounds how far m - vb may lie from the squared bias
    let mut diffs = Vec::new();
    let mut bias = 0.0;
    for (((p, q), t), b) in a1
        .pixels
        .iter()
        .zip(&a2.pixels)
        .zip(&truth)
        .zip(&biased.pixels)
    {
        for c in 0..3 {
            let (x, y, r, b) = (p[c] as f64, q[c] as f64, t[c] as f64, b[c] as f64);
            let w = 1.0 / (b * b + metrics::RELMSE_EPSILON);
            diffs.push((x - b).powi(2) * w - (x - y).powi(2) * w / 2.0);
            bias += (b - r).powi(2) * w;
        }
    }
    bias /= diffs.len() as f64;
    let (d, se) = common::mean_and_stderr(&diffs);
    assert!(
        (d - (m - vb)).abs() < 1e-9 * m,
        "relMSE {m} minus twin {vb} is the mean of the per-term differences {d}"
    );
    fam.mean_is(
        "relMSE minus twin variance is the squared bias",
        d,
        se,
        (diffs.len() - 1) as f64,
        bias,
    );
    fam.finish();
}

/// A row of a hypothetical study: `run`'s last checkpoint at relMSE `relmse`.
fn last_row(run: usize, relmse: f64) -> CheckpointRow {
    CheckpointRow {
        integrator: "path".into(),
        run,
        checkpoint: 0,
        seconds: 1.0,
        samples: 16,
        rmse: relmse.sqrt(),
        relmse,
        efficiency: 1.0 / relmse,
    }
}

/// One run has no spread: the summary says so instead of printing an error bar of zero; two
/// runs get their standard error.
#[test]
fn a_single_runs_summary_has_no_error_bar() {
    use pathspace::cli::converge::summary_line;
    let one = convergence::summarize(&[last_row(0, 2e-3)]);
    let line = summary_line(&one[0]);
    assert!(
        line.contains("relMSE 2.000e-3 (one run: no error bar"),
        "{line}"
    );
    assert!(!line.contains('±'), "{line}");
    let two = convergence::summarize(&[last_row(0, 2e-3), last_row(1, 4e-3)]);
    let line = summary_line(&two[0]);
    assert!(line.contains("relMSE 3.000e-3 ± 1.0e-3"), "{line}");
}

/// The curves flatten at the reference's own relMSE (E[(a-b)^2] = var a + var b): the study
/// warns when that floor is more than a tenth of the least error a line reached, with the
/// factor of samples that brings it below, and keeps quiet below.
#[test]
fn converge_warns_when_the_reference_is_nearly_as_noisy_as_the_runs() {
    use pathspace::cli::converge::{noisy_reference_warning, REFERENCE_NOISE_SHARE};
    let curves = convergence::summarize(&[last_row(0, 1e-3), last_row(1, 1e-3)]);
    let w = noisy_reference_warning(5e-4, &curves).expect("a reference at half the error");
    assert!(w.contains("is 50% of the error path reached"), "{w}");
    assert!(w.contains("about 5 times its samples"), "{w}");
    assert!(noisy_reference_warning(0.5 * REFERENCE_NOISE_SHARE * 1e-3, &curves).is_none());
    assert!(noisy_reference_warning(2.0 * REFERENCE_NOISE_SHARE * 1e-3, &curves).is_some());
}

/// An image with a NaN (or infinite) pixel has no error metric: `compare` refuses it naming
/// the pixel, where the sums would give an RMSE of NaN beside a maximum difference of 0
/// (`f64::max` passes over a NaN).
#[test]
fn a_non_finite_pixel_is_refused_not_averaged() {
    let good = Image::new(3, 2);
    for (bad_value, which) in [(f32::NAN, "the image"), (f32::INFINITY, "the reference")] {
        let mut bad = Image::new(3, 2);
        bad.pixels[4].y = bad_value;
        let e = match which {
            "the image" => metrics::compare(&bad, &good),
            _ => metrics::compare(&good, &bad),
        }
        .unwrap_err()
        .to_string();
        assert!(
            e.contains(&format!("pixel (1, 1) of {which} is not finite")),
            "{e}"
        );
    }
    assert_eq!(metrics::compare(&good, &good).unwrap().rmse, 0.0);
}
