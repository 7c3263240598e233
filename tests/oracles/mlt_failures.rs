//! Where MLT fails (book: "MLT experiments", section "Where MLT fails"): the qualitative claims
//! of the three experiments, each at a size that runs in seconds.
//!
//! - Start-up: b_n, the pre-pass estimate of b (Pauly, Kollig, Keller 2000 sec. 5.1), spreads
//!   over runs like 1/sqrt(n) and its mean over runs is b (unbiased whatever n).
//! - Small light + singular-diffuse-singular chains: paths with a specular chain at both ends
//!   (L S ... S E) are moved by the light-side perturbations (light, propagation, multi-chain)
//!   far less often than the fog box's paths; the multi-chain perturbation's own acceptance
//!   against the light's size is an experiment (ignored test), since it does not collapse.
//! - MLT no better than BDPT on a soft light in a high-albedo medium: at equal samples MLT's
//!   error is not below BDPT's.

use crate::common;

use pathspace::integrator::mlt::acceptance::acceptance;
use pathspace::integrator::mlt::contribution::{
    image_contribution, is_specular, scalar_contribution,
};
use pathspace::integrator::mlt::init::Bootstrap;
use pathspace::integrator::mlt::mutation::{MutationKind, Workspace};
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::math::Sampler;
use pathspace::path::{Vertex, VertexKind};
use pathspace::scene::{Scene, SceneSource};

use common::stats::{runs_mean, student_two_sided, Family};

fn fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

fn scene_file(name: &str, w: u32) -> Scene {
    let path = format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("scene file");
    let text = text.replace("resolution = [64, 64]", &format!("resolution = [{w}, {w}]"));
    Scene::load(&SceneSource::embedded(name, &text)).expect("valid scene")
}

fn engine(scene: &Scene, max_depth: u32) -> Mlt<'_> {
    Mlt::new(
        scene,
        &pathspace::path::PLAIN,
        MltSettings::default(),
        1,
        Some(max_depth),
    )
    .expect("mlt applies")
}

/// Sample mean, standard deviation and kurtosis (fourth central moment over variance squared).
fn moments(x: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let m2 = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    let m4 = x.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / n;
    (mean, (m2 * n / (n - 1.0)).sqrt(), m4 / (m2 * m2))
}

/// Variance of ln(s) for the sample standard deviation s of `runs` values with kurtosis
/// `kurtosis` (delta method: Var(s^2) = sigma^4 (kurtosis - 1 + 2/(R - 1)) / R, and
/// Var(ln s) = Var(s^2) / (4 sigma^4)). For normal data (kurtosis 3) it is about 1/(2R).
fn var_ln_sd(kurtosis: f64, runs: usize) -> f64 {
    let r = runs as f64;
    (kurtosis - 1.0 + 2.0 / (r - 1.0)) / (4.0 * r)
}

const STARTUP_RUNS: u64 = 32;
const STARTUP_DEPTH: u32 = 3;

#[test]
fn startup_spread_of_b_falls_like_one_over_sqrt_n_and_its_mean_is_unbiased() {
    let mut fam = Family::new("mlt_failures: start-up spread and mean of b");
    let scene = fog_box(8);
    let mlt = engine(&scene, STARTUP_DEPTH);
    let (n_small, n_large) = (64u64, 4096u64);
    let b_of = |n: u64| -> Vec<f64> {
        (0..STARTUP_RUNS)
            .map(|r| Bootstrap::run(&scene, &mlt.bdpt, n, 100 + r).b)
            .collect()
    };
    let small = b_of(n_small);
    let large = b_of(n_large);
    let (_, sd_s, k_s) = moments(&small);
    let (_, sd_l, k_l) = moments(&large);
    // the spread shrinks by sqrt(n_large / n_small) = 8: ln of the ratio of the standard
    // deviations against ln 8, with its delta-method standard error (runs - 1 dof)
    let expected = 0.5 * (n_large as f64 / n_small as f64).ln();
    let observed = (sd_s / sd_l).ln();
    let sigma = (var_ln_sd(k_s, small.len()) + var_ln_sd(k_l, large.len())).sqrt();
    fam.mean_is(
        "ln(sd(b_64) / sd(b_4096)) against ln 8",
        observed,
        sigma,
        (STARTUP_RUNS - 1) as f64,
        expected,
    );
    // unbiased over runs, initialization included: the mean of b_n over runs at n = 64 agrees
    // with an independent BDPT estimate (the mean over runs at n = 4096, other seeds)
    let reference: Vec<f64> = (0..8)
        .map(|r| Bootstrap::run(&scene, &mlt.bdpt, n_large, 900 + r).b)
        .collect();
    fam.runs_agree("mean of b_64 over runs against BDPT", &small, &reference);
    fam.runs_agree("mean of b_4096 over runs against BDPT", &large, &reference);
    fam.finish();
}

/// L S+ ... S+ E: paths with a specular chain at both ends (the light's glass ball at the light,
/// the large glass ball at the eye). Strict L S+ D S+ E paths (one diffuse vertex) have no edge
/// between two non-specular vertices, so BDPT's pre-pass finds them only by hitting the 4-cm
/// light through its ball (s = 0) and they are too rare to seed a test; the chains between the
/// two specular ends are what the perturbations must retrace.
fn is_sds(scene: &Scene, x: &[Vertex]) -> bool {
    let k = x.len();
    k >= 5
        && matches!(x[0].kind, VertexKind::Light { .. })
        && is_specular(scene, &x[1])
        && is_specular(scene, &x[k - 2])
}

/// Pre-pass paths drawn proportionally to their contribution, filtered by `keep`.
fn paths(
    scene: &Scene,
    mlt: &Mlt,
    n: u64,
    count: usize,
    keep: impl Fn(&[Vertex]) -> bool,
) -> Vec<Vec<Vertex>> {
    let boot = Bootstrap::run(scene, &mlt.bdpt, n, 7);
    let mut s = Sampler::new(7, 1, 0);
    let mut out = Vec::new();
    for _ in 0..count * 40 {
        let Some(c) = boot.select(s.next_f64()) else {
            break;
        };
        if let Some(x) = Bootstrap::path_of(scene, &mlt.bdpt, 7, c) {
            if image_contribution(scene, &x).is_some() && keep(&x) {
                out.push(x);
            }
        }
        if out.len() == count {
            break;
        }
    }
    out
}

/// Mean acceptance probability alpha of eq. (8) over `tries` attempts of each of `kinds` (equal
/// weights) from each path; alpha = 0 when the mutation does not apply or leaves path space,
/// as the chain experiences it. Returns each path's mean alpha: the paths are independent
/// draws, the attempts from one path are not.
fn mean_alpha(
    scene: &Scene,
    mlt: &Mlt,
    xs: &[Vec<Vertex>],
    kinds: &[MutationKind],
    tries: usize,
) -> Vec<f64> {
    let mut sampler = Sampler::new(5, 0, 0);
    let (mut work, mut y) = (Workspace::default(), Vec::new());
    let mut out = Vec::with_capacity(xs.len());
    for x in xs {
        let (mut path_sum, mut count) = (0.0, 0);
        let fx = scalar_contribution(image_contribution(scene, x).unwrap().0) as f64;
        for &kind in kinds {
            let m = mlt.mutations.get(kind);
            for _ in 0..tries {
                count += 1;
                if m.sample(
                    scene,
                    &pathspace::path::PLAIN,
                    x,
                    &mut sampler,
                    &mut work,
                    &mut y,
                )
                .is_none()
                {
                    continue;
                }
                let Some((fy, _)) = image_contribution(scene, &y) else {
                    continue;
                };
                let t_xy = m.transition_density(scene, &pathspace::path::PLAIN, x, &y, &mut work);
                let t_yx = m.transition_density(scene, &pathspace::path::PLAIN, &y, x, &mut work);
                path_sum += acceptance(fx, scalar_contribution(fy) as f64, t_xy, t_yx);
            }
        }
        out.push(path_sum / count as f64);
    }
    out
}

/// Hoeffding's one-sided bound for a mean of `n` independent values in [0, 1] at level
/// `TEST_ALPHA`, one test's level: P(mean - E > t) <= exp(-2 n t^2), t = sqrt(ln(1 / level) / (2 n)).
fn hoeffding(n: usize) -> f64 {
    ((1.0 / common::stats::TEST_ALPHA).ln() / (2.0 * n as f64)).sqrt()
}

/// The perturbations that must retrace a chain from the light side: the light (caustic)
/// perturbation, the propagation perturbation and the multi-chain perturbation.
const LIGHT_SIDE: [MutationKind; 3] = [
    MutationKind::Light,
    MutationKind::Propagation,
    MutationKind::MultiChain,
];

/// "Far below": the claim of the book is that S-D-S paths are moved at most half as often as
/// the fog box's paths (measured: 0 against 0.30, see the book).
const FAR_BELOW: f64 = 0.5;

#[test]
fn light_side_perturbations_do_not_move_paths_specular_at_both_ends() {
    const DEPTH: u32 = 8;
    // paths per scene: Hoeffding's bound at 600 is 0.076, below half the fog box's 0.30
    const SDS_PATHS: usize = 600;
    const TRIES: usize = 4;
    let mut fam = Family::new("mlt_failures: light-side perturbations on S...S paths");
    let sds = scene_file("mlt-sds.toml", 16);
    let mlt_sds = engine(&sds, DEPTH);
    let xs = paths(&sds, &mlt_sds, 20_000, SDS_PATHS, |x| is_sds(&sds, x));
    assert!(xs.len() == SDS_PATHS, "only {} S-D-S paths", xs.len());
    let a_sds = mean_alpha(&sds, &mlt_sds, &xs, &LIGHT_SIDE, TRIES);
    let fog = fog_box(16);
    let mlt_fog = engine(&fog, DEPTH);
    let ys = paths(&fog, &mlt_fog, 20_000, SDS_PATHS, |_| true);
    let a_fog = mean_alpha(&fog, &mlt_fog, &ys, &LIGHT_SIDE, TRIES);
    let (p_sds, se_sds, dof_sds) = runs_mean(&a_sds);
    let (p_fog, se_fog, dof_fog) = runs_mean(&a_fog);
    println!("mean alpha of light-side perturbations: S...S paths {p_sds:.4} +- {se_sds:.4}, fog box {p_fog:.4} +- {se_fog:.4}");
    // the claim p_sds <= FAR_BELOW p_fog, tested one-sided at its boundary: the p-value of a
    // difference p_sds - FAR_BELOW p_fog this far above zero (Welch's degrees of freedom)
    let (va, vb) = (se_sds * se_sds, (FAR_BELOW * se_fog).powi(2));
    let se = (va + vb).sqrt();
    let dof = (va + vb).powi(2) / (va * va / dof_sds + vb * vb / dof_fog);
    let z = (p_sds - FAR_BELOW * p_fog) / se;
    let tail = student_two_sided(z, dof) / 2.0;
    fam.p_value(
        "mean alpha on S...S paths is at most half the fog box's",
        if z > 0.0 { tail } else { 1.0 - tail },
        format!("{p_sds:.4} +- {se_sds:.4} vs {FAR_BELOW} x {p_fog:.4} +- {se_fog:.4}: {z:+.2} se"),
    );
    fam.finish();
}

/// Paths the multi-chain perturbation applies to: the eye sees x_m through a specular chain
/// (x_{k-1} specular), x_m non-specular, and x_{m-1} specular.
fn multichain_class(scene: &Scene, x: &[Vertex]) -> bool {
    let k = x.len() - 1;
    if k < 3 || !is_specular(scene, &x[k - 1]) {
        return false;
    }
    let mut m = k - 1;
    while m > 0 && is_specular(scene, &x[m]) {
        m -= 1;
    }
    m >= 1 && is_specular(scene, &x[m - 1])
}

/// The light of `mlt-sds.toml` replaced by a square of side `side` at the same power, centred
/// where the 4-cm light is (for the 30-cm light: at the ball's centre, so it fits inside).
fn sds_with_light(side: f32) -> Scene {
    let path = format!("{}/scenes/mlt-sds.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(path).expect("scene file");
    let (cx, cz) = if side > 0.1 {
        (0.1, -0.1)
    } else {
        (0.15, -0.11)
    };
    let emission = 2500.0 * (0.04 / side).powi(2);
    let light = format!(
        "origin = [{}, 0.7, {}]\nu = [{side}, 0.0, 0.0]\nv = [0.0, 0.0, {side}]\nemission = [{emission}, {emission}, {emission}]",
        cx - side / 2.0,
        cz - side / 2.0
    );
    let text = text.replace(
        "origin = [0.13, 0.7, -0.13]\nu = [0.04, 0.0, 0.0]\nv = [0.0, 0.0, 0.04]\nemission = [2500.0, 2500.0, 2500.0]",
        &light,
    );
    assert!(text.contains(&format!("u = [{side}")), "light replaced");
    Scene::load(&SceneSource::embedded("mlt-sds-light", &text)).expect("valid scene")
}

/// EXPERIMENT, not a test (it asserts nothing; run with `--ignored --nocapture`): the
/// multi-chain perturbation's mean alpha on the paths it applies to, for lights of 4 mm, 4 cm
/// and 30 cm at equal power. The numbers are in the book ("Where MLT fails").
#[test]
#[ignore]
fn experiment_multichain_acceptance_against_light_size() {
    for side in [0.004f32, 0.04, 0.3] {
        let sc = sds_with_light(side);
        let mlt = engine(&sc, 12);
        let xs = paths(&sc, &mlt, 20_000, 600, |x| multichain_class(&sc, x));
        let m = mlt.mutations.get(MutationKind::MultiChain);
        let mut s = Sampler::new(5, 0, 0);
        let (mut work, mut y) = (Workspace::default(), Vec::new());
        let (mut none, mut a, mut n) = (0, 0.0, 0);
        for x in &xs {
            let fx = scalar_contribution(image_contribution(&sc, x).unwrap().0) as f64;
            for _ in 0..4 {
                n += 1;
                if m.sample(&sc, &pathspace::path::PLAIN, x, &mut s, &mut work, &mut y)
                    .is_none()
                {
                    none += 1;
                    continue;
                }
                let Some((fy, _)) = image_contribution(&sc, &y) else {
                    continue;
                };
                let t_xy = m.transition_density(&sc, &pathspace::path::PLAIN, x, &y, &mut work);
                let t_yx = m.transition_density(&sc, &pathspace::path::PLAIN, &y, x, &mut work);
                a += acceptance(fx, scalar_contribution(fy) as f64, t_xy, t_yx);
            }
        }
        println!(
            "light {side} m: {} paths, no proposal {:.3}, mean alpha {:.3} (+- {:.3})",
            xs.len(),
            none as f64 / n as f64,
            a / n as f64,
            hoeffding(xs.len())
        );
    }
}

/// Luminance of every pixel of an image.
fn luminances(img: &pathspace::image_io::Image) -> Vec<f64> {
    let mut out = Vec::new();
    for y in 0..img.height {
        for x in 0..img.width {
            let p = img.get(x, y);
            out.push(0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64);
        }
    }
    out
}

/// Total variance over runs, sum over pixels of the per-pixel sample variance, with the
/// standard error of its logarithm: V = sum_r D_r / (R - 1) with D_r = sum_j (I_rj - mean_j)^2,
/// and SE(ln V) from the spread of the D_r (a mean of R terms) divided by their mean.
fn total_variance(runs: &[Vec<f64>]) -> (f64, f64) {
    let r = runs.len() as f64;
    let pixels = runs[0].len();
    let mean: Vec<f64> = (0..pixels)
        .map(|j| runs.iter().map(|i| i[j]).sum::<f64>() / r)
        .collect();
    let d: Vec<f64> = runs
        .iter()
        .map(|i| i.iter().zip(&mean).map(|(a, m)| (a - m).powi(2)).sum())
        .collect();
    let (m, sd, _) = moments(&d);
    (m * r / (r - 1.0), sd / r.sqrt() / m)
}

const SOFT_RUNS: u64 = 16;
const SOFT_RES: u32 = 8;
const SOFT_SAMPLES: u64 = 16;
const SOFT_DEPTH: u32 = 12;

#[test]
fn mlt_is_no_better_than_bdpt_under_a_soft_light_in_a_high_albedo_medium() {
    let mut fam = Family::new("mlt_failures: MLT no better than BDPT under a soft light");
    let scene = scene_file("mlt-soft-fog.toml", SOFT_RES);
    let bdpt: Vec<Vec<f64>> = (0..SOFT_RUNS)
        .map(|r| {
            let mut rd = pathspace::integrator::Renderer::new(
                &scene,
                pathspace::integrator::IntegratorKind::Bdpt,
                300 + r,
                Some(SOFT_DEPTH),
            );
            rd.pass(SOFT_SAMPLES as u32, &|| {});
            luminances(&rd.film.as_ref().unwrap().image())
        })
        .collect();
    let mlt: Vec<Vec<f64>> = (0..SOFT_RUNS)
        .map(|r| {
            let settings = MltSettings {
                bootstrap: 4096,
                chains: 4,
                ..MltSettings::default()
            };
            let mut m = Mlt::new(
                &scene,
                &pathspace::path::PLAIN,
                settings,
                500 + r,
                Some(SOFT_DEPTH),
            )
            .unwrap();
            let mut film = pathspace::film::Film::new(SOFT_RES, SOFT_RES);
            m.run(
                &scene,
                &mut film,
                (SOFT_RES * SOFT_RES) as u64 * SOFT_SAMPLES,
            );
            luminances(&film.image())
        })
        .collect();
    let (v_mlt, se_mlt) = total_variance(&mlt);
    let (v_bdpt, se_bdpt) = total_variance(&bdpt);
    println!("total variance at {SOFT_SAMPLES} samples per pixel: mlt {v_mlt:.4e} (ln +- {se_mlt:.3}), bdpt {v_bdpt:.4e} (ln +- {se_bdpt:.3})");
    // both are unbiased, so their MSE is their variance: the claim "MLT's is not below BDPT's"
    // tested one-sided at its boundary (ln ratio 0) with the standard error of the log ratio
    // (runs - 1 dof)
    let sigma = (se_mlt * se_mlt + se_bdpt * se_bdpt).sqrt();
    let z = (v_mlt / v_bdpt).ln() / sigma;
    let tail = student_two_sided(z, (SOFT_RUNS - 1) as f64) / 2.0;
    fam.p_value(
        "MLT's total variance is not below BDPT's",
        if z < 0.0 { tail } else { 1.0 - tail },
        format!("mlt {v_mlt:.4e}, bdpt {v_bdpt:.4e}: ln ratio {z:+.2} se"),
    );
    fam.finish();
}
