//! Shared statistical helpers of the executable specification (`tests/*.rs`).
//!
//! Every statistical test in pathspace uses a fixed seed and judges its comparisons as one
//! [`stats::Family`] (p-values, Holm's correction, a level shared out over the suite), so a
//! failure is reproducible and means "a correct renderer does this less than once in 1/alpha
//! runs". The helpers here compute statistics; only a `Family` decides:
//!
//! - [`chi_square_p_value`]: Pearson's goodness-of-fit test of binned counts against expected
//!   counts, pooling bins whose expectation is below [`CHI2_MIN_EXPECTED`];
//! - [`chi_square_sphere`]: the same test for directions, binned over (cos theta, phi) of a
//!   frame, with expected counts from quadrature of a solid-angle density;
//! - [`ks_p_value`]: the one-sample Kolmogorov-Smirnov test against a continuous CDF;
//! - [`mean_and_stderr`], [`film_mean`], [`meter_mean`]: Monte Carlo means with their errors.
#![allow(dead_code)]

pub mod browser;
pub mod cli;
pub mod docs;
pub mod scenes;
pub mod stats;

use glam::Vec3;
use pathspace::math::{Frame, Sampler};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Pearson's chi-square statistic is only chi-square distributed when every bin expects at
/// least about five samples (Cochran's rule); smaller bins are pooled.
pub const CHI2_MIN_EXPECTED: f64 = 5.0;

/// The allowance for an estimator whose standard error is exactly zero (a deterministic
/// quantity computed in f32): a few units in the last place of an f32 result of order one.
pub const ZERO_VARIANCE_ALLOWANCE: f64 = 8.0 * f32::EPSILON as f64;

/// A deterministic stream of uniform numbers for a test: `seed` names the test, `index` the
/// sub-case.
pub fn sampler(seed: u64, index: u64) -> Sampler {
    Sampler::new(seed, index, 0)
}

/// The p-value of Pearson's chi-square test of `observed` counts against `expected` counts
/// (same length, expected summing to the number of samples).
///
/// Bins are sorted by expectation and the smallest are pooled until the pool expects at least
/// [`CHI2_MIN_EXPECTED`]; if samples fall where nothing is expected (a bin with expectation
/// zero, up to `1e-12` of the total, that holds a sample) the p-value is zero: a sampler
/// producing an impossible outcome is wrong whatever the statistic.
pub fn chi_square_p_value(observed: &[u64], expected: &[f64]) -> f64 {
    assert_eq!(observed.len(), expected.len());
    let total: f64 = expected.iter().sum();
    let impossible = total * 1e-12;
    let mut cells: Vec<(f64, f64)> = Vec::with_capacity(observed.len());
    for (&o, &e) in observed.iter().zip(expected) {
        if e <= impossible {
            if o > 0 {
                eprintln!("chi-square: {o} samples in a bin of expectation {e}");
                return 0.0;
            }
            continue;
        }
        cells.push((o as f64, e));
    }
    cells.sort_by(|a, b| a.1.partial_cmp(&b.1).unwrap());
    let mut pooled = (0.0, 0.0);
    let mut statistic = 0.0;
    let mut dof: i64 = -1;
    for (o, e) in cells {
        if pooled.1 < CHI2_MIN_EXPECTED {
            pooled.0 += o;
            pooled.1 += e;
            if pooled.1 < CHI2_MIN_EXPECTED {
                continue;
            }
            statistic += (pooled.0 - pooled.1) * (pooled.0 - pooled.1) / pooled.1;
            dof += 1;
            continue;
        }
        statistic += (o - e) * (o - e) / e;
        dof += 1;
    }
    if pooled.1 > 0.0 && pooled.1 < CHI2_MIN_EXPECTED {
        // a small remainder: counted as its own cell (rare: only when all bins are tiny)
        statistic += (pooled.0 - pooled.1) * (pooled.0 - pooled.1) / pooled.1;
        dof += 1;
    }
    if dof < 1 {
        return 1.0;
    }
    ChiSquared::new(dof as f64).unwrap().sf(statistic)
}

/// Composite Simpson rule of `f` on [a, b] with `n` (even) sub-intervals, in f64.
pub fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    assert!(
        n >= 2 && n.is_multiple_of(2),
        "Simpson's rule needs an even count"
    );
    let h = (b - a) / n as f64;
    let mut sum = f(a) + f(b);
    for i in 1..n {
        let w = if i % 2 == 1 { 4.0 } else { 2.0 };
        sum += w * f(a + h * i as f64);
    }
    sum * h / 3.0
}

/// The unit direction with cosine `cos_theta` to `frame.n` and azimuth `phi` in the frame.
pub fn direction(frame: &Frame, cos_theta: f64, phi: f64) -> Vec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    frame.to_world(Vec3::new(
        (sin_theta * phi.cos()) as f32,
        (sin_theta * phi.sin()) as f32,
        cos_theta as f32,
    ))
}

/// (cos theta, phi in [0, 2 pi)) of a world direction in `frame`.
pub fn spherical(frame: &Frame, w: Vec3) -> (f64, f64) {
    let l = frame.to_local(w);
    let phi = (l.y as f64).atan2(l.x as f64);
    let phi = if phi < 0.0 {
        phi + std::f64::consts::TAU
    } else {
        phi
    };
    ((l.z as f64).clamp(-1.0, 1.0), phi)
}

/// A grid over the sphere in (cos theta, phi) of a frame, for chi-square tests of directions.
/// Solid angle is d(cos theta) d(phi), so a solid-angle density integrates directly.
pub struct SphereGrid {
    pub frame: Frame,
    pub n_cos: usize,
    pub n_phi: usize,
    /// Simpson sub-intervals per bin in cos theta (pdfs may be peaked in cos theta).
    pub quad_cos: usize,
    /// Simpson sub-intervals per bin in phi.
    pub quad_phi: usize,
}

impl SphereGrid {
    pub fn new(frame: Frame, n_cos: usize, n_phi: usize) -> Self {
        SphereGrid {
            frame,
            n_cos,
            n_phi,
            quad_cos: 256,
            quad_phi: 8,
        }
    }

    fn bin(&self, w: Vec3) -> usize {
        let (c, phi) = self.spherical(w);
        let i = (((c + 1.0) * 0.5 * self.n_cos as f64) as usize).min(self.n_cos - 1);
        let j = ((phi / std::f64::consts::TAU * self.n_phi as f64) as usize).min(self.n_phi - 1);
        i * self.n_phi + j
    }

    fn spherical(&self, w: Vec3) -> (f64, f64) {
        spherical(&self.frame, w)
    }

    /// Expected counts of `n_samples` directions drawn from the solid-angle density `pdf`
    /// (a world-direction function), by Simpson quadrature in each bin.
    pub fn expected(&self, pdf: impl Fn(Vec3) -> f64, n_samples: u64) -> Vec<f64> {
        let dc = 2.0 / self.n_cos as f64;
        let dphi = std::f64::consts::TAU / self.n_phi as f64;
        let mut out = Vec::with_capacity(self.n_cos * self.n_phi);
        for i in 0..self.n_cos {
            let c0 = -1.0 + dc * i as f64;
            for j in 0..self.n_phi {
                let p0 = dphi * j as f64;
                let mass = simpson(
                    |c| {
                        simpson(
                            |phi| pdf(direction(&self.frame, c, phi)),
                            p0,
                            p0 + dphi,
                            self.quad_phi,
                        )
                    },
                    c0,
                    c0 + dc,
                    self.quad_cos,
                );
                out.push(mass * n_samples as f64);
            }
        }
        out
    }

    /// Observed counts of `n_samples` directions from `sample` (`None` = no sample, counted
    /// nowhere, so it shows as missing mass).
    pub fn observe(&self, mut sample: impl FnMut() -> Option<Vec3>, n_samples: u64) -> Vec<u64> {
        let mut counts = vec![0u64; self.n_cos * self.n_phi];
        for _ in 0..n_samples {
            if let Some(w) = sample() {
                counts[self.bin(w)] += 1;
            }
        }
        counts
    }
}

/// The Kolmogorov distribution's survival function Q(lambda) = 2 sum_{j>=1} (-1)^(j-1)
/// exp(-2 j^2 lambda^2), the asymptotic law of sqrt(n) D_n.
pub fn kolmogorov_q(lambda: f64) -> f64 {
    /// Below this the series converges slowly and Q is 1 to double precision anyway.
    const SMALL_LAMBDA: f64 = 0.2;
    /// Terms of the series; exp(-2 j^2 lambda^2) at j = 100, lambda = 0.2 is below 1e-34.
    const TERMS: usize = 100;
    if lambda < SMALL_LAMBDA {
        return 1.0;
    }
    let mut sum = 0.0;
    let mut sign = 1.0;
    for j in 1..=TERMS {
        let jf = j as f64;
        sum += sign * (-2.0 * jf * jf * lambda * lambda).exp();
        sign = -sign;
    }
    (2.0 * sum).clamp(0.0, 1.0)
}

/// The p-value of the one-sample Kolmogorov-Smirnov test of `samples` against the continuous
/// CDF `cdf`, with Stephens' small-sample correction of the asymptotic law
/// (lambda = (sqrt n + 0.12 + 0.11 / sqrt n) D; Stephens 1970, as in Numerical Recipes 14.3).
pub fn ks_p_value(samples: &mut [f64], cdf: impl Fn(f64) -> f64) -> f64 {
    const STEPHENS_A: f64 = 0.12;
    const STEPHENS_B: f64 = 0.11;
    samples.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = samples.len() as f64;
    let mut d: f64 = 0.0;
    for (i, &x) in samples.iter().enumerate() {
        let f = cdf(x);
        d = d.max((i as f64 + 1.0) / n - f).max(f - i as f64 / n);
    }
    let sqrt_n = n.sqrt();
    kolmogorov_q((sqrt_n + STEPHENS_A + STEPHENS_B / sqrt_n) * d)
}

/// Sample mean and its standard error sqrt(s^2 / n), s^2 the unbiased sample variance.
pub fn mean_and_stderr(samples: &[f64]) -> (f64, f64) {
    let n = samples.len() as f64;
    assert!(n >= 2.0, "a standard error needs two samples");
    let mean = samples.iter().sum::<f64>() / n;
    let var = samples.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Asserts |a - b| <= tol * max(1, |b|): comparison of deterministic f32 quantities.
pub fn assert_close(what: &str, a: f64, b: f64, tol: f64) {
    assert!(
        (a - b).abs() <= tol * b.abs().max(1.0),
        "{what}: got {a}, expected {b} (tolerance {tol:e})"
    );
}

/// Unit directions for contract tests: axes, both poles (the frame construction branches on the
/// sign of z) and a fixed pseudo-random set.
pub fn test_directions(seed: u64, n_random: usize) -> Vec<Vec3> {
    let mut dirs = vec![
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        -Vec3::Y,
        Vec3::new(1.0, 2.0, -3.0).normalize(),
    ];
    let mut s = sampler(seed, u64::MAX);
    for _ in 0..n_random {
        dirs.push(pathspace::math::warp::uniform_sphere(s.next_2d()));
    }
    dirs
}

/// A slab z in [-1, 0] extending to +-`half_width` in x and y, under a unit directional light
/// along -z, with meters `T` (just below, facing up) and `R` (just above, facing down);
/// `medium` is the body of its `[media.slab]` table. The scene of the slab oracles.
#[allow(dead_code)]
pub fn slab_scene(medium: &str, half_width: f32) -> String {
    format!(
        r#"
[render]
meter_samples = 4096

[media.slab]
{medium}

[[shapes]]
type = "box"
min = [-{half_width:.1}, -{half_width:.1}, -1.0]
max = [{half_width:.1}, {half_width:.1}, 0.0]
material = "null"
interior = "slab"

[[lights]]
type = "directional"
direction = [0.0, 0.0, -1.0]
irradiance = 1.0

[[sensors]]
type = "irradiance_meter"
name = "T"
origin = [-0.5, -0.5, -1.001]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]

[[sensors]]
type = "irradiance_meter"
name = "R"
origin = [-0.5, -0.5, 0.001]
u = [0.0, 1.0, 0.0]
v = [1.0, 0.0, 0.0]
"#
    )
}

/// Every pixel sum and splat of one 4-spp pass of `kind` on `scene` with `seed`, as bits: what
/// two renders must share to be the same image.
pub fn film_bits(
    scene: &pathspace::scene::Scene,
    kind: pathspace::integrator::IntegratorKind,
    seed: u64,
) -> Vec<u64> {
    let mut r = pathspace::integrator::Renderer::new(scene, kind, seed, None);
    r.pass(4, &|| {});
    let film = r.film.unwrap();
    film.sum
        .iter()
        .chain(film.splat.iter())
        .flatten()
        .map(|x| x.to_bits())
        .collect()
}

/// Mean RGB of the four image quadrants (12 numbers): a coarse picture of an image that
/// independent runs of two integrators must agree on.
pub fn quadrant_means(img: &pathspace::image_io::Image) -> Vec<f64> {
    let (w, h) = (img.width, img.height);
    let mut out = vec![0.0; 12];
    for y in 0..h {
        for x in 0..w {
            let q = (usize::from(y >= h / 2)) * 2 + usize::from(x >= w / 2);
            let p = img.get(x, y);
            for c in 0..3 {
                out[q * 3 + c] += p[c] as f64 / (w * h / 4) as f64;
            }
        }
    }
    out
}

/// Per-component mean and standard error of the mean over independent runs.
pub fn mean_and_se(runs: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    let n = runs.len() as f64;
    let k = runs[0].len();
    let mean: Vec<f64> = (0..k)
        .map(|i| runs.iter().map(|r| r[i]).sum::<f64>() / n)
        .collect();
    let se = (0..k)
        .map(|i| {
            let v = runs.iter().map(|r| (r[i] - mean[i]).powi(2)).sum::<f64>() / (n - 1.0);
            (v / n).sqrt()
        })
        .collect();
    (mean, se)
}

/// Quadrant means of `runs` BDPT renders of `spp` samples per pixel, depth limit `depth`,
/// seeds `seed + r`, sampling with technique `tech`.
pub fn bdpt_quadrant_runs(
    (scene, tech): (
        &pathspace::scene::Scene,
        &dyn pathspace::path::LocalSampling,
    ),
    runs: u64,
    seed: u64,
    depth: u32,
    spp: u32,
) -> Vec<Vec<f64>> {
    use pathspace::integrator::{IntegratorKind, Renderer};
    (0..runs)
        .map(|r| {
            let mut rd =
                Renderer::try_with(scene, tech, IntegratorKind::Bdpt, seed + r, Some(depth))
                    .unwrap();
            rd.pass(spp, &|| {});
            quadrant_means(&rd.film.as_ref().unwrap().image())
        })
        .collect()
}

/// Quadrant means of `runs` small MLT renders of the scene's camera image (2000 bootstrap
/// samples, 4 chains, 128 mutations per pixel), depth limit `depth`, seeds `seed + r`.
pub fn mlt_quadrant_runs(
    scene: &pathspace::scene::Scene,
    runs: u64,
    seed: u64,
    depth: u32,
) -> Vec<Vec<f64>> {
    use pathspace::integrator::mlt::{Mlt, MltSettings};
    let cam = scene.camera.as_ref().expect("a camera");
    (0..runs)
        .map(|r| {
            let settings = MltSettings {
                bootstrap: 2000,
                chains: 4,
                ..MltSettings::default()
            };
            let mut m = Mlt::new(
                scene,
                &pathspace::path::PLAIN,
                settings,
                seed + r,
                Some(depth),
            )
            .unwrap();
            let mut film = pathspace::film::Film::new(cam.width, cam.height);
            m.run(scene, &mut film, (cam.width * cam.height * 128) as u64);
            quadrant_means(&film.image())
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Calibrated forms of the helpers above: each adds its comparisons to the test's `Family`.

/// Chi-square test of a direction sampler against the solid-angle density it claims, added to
/// `fam`.
pub fn chi_square_sphere(
    fam: &mut stats::Family,
    what: &str,
    grid: &SphereGrid,
    sample: impl FnMut() -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
    n_samples: u64,
) {
    let observed = grid.observe(sample, n_samples);
    let expected = grid.expected(pdf, n_samples);
    fam.chi_square(what, &observed, &expected);
}

/// The quadrant means of two sets of independent runs agree, component by component (Welch's
/// test with the runs' own spread: Student-t, not normal, for few runs).
pub fn quadrants_agree(fam: &mut stats::Family, name: &str, a: &[Vec<f64>], b: &[Vec<f64>]) {
    let column = |runs: &[Vec<f64>], i: usize| runs.iter().map(|r| r[i]).collect::<Vec<f64>>();
    for i in 0..a[0].len() {
        fam.runs_agree(
            &format!("{name}: quadrant {} channel {}", i / 3, i % 3),
            &column(a, i),
            &column(b, i),
        );
    }
}

/// Quadrant means of `runs` small MLT renders of the scene's camera image (2000 bootstrap
/// samples, 4 chains, `mutations_per_pixel` mutations per pixel), depth limit `depth`, seeds
/// `seed + r`, technique `tech`: [`mlt_quadrant_runs`] with the run length as a parameter, so that a test can
/// buy more, shorter runs (a standard error from more runs has more degrees of freedom).
pub fn mlt_quadrant_runs_with(
    (scene, tech): (
        &pathspace::scene::Scene,
        &dyn pathspace::path::LocalSampling,
    ),
    runs: u64,
    seed: u64,
    depth: u32,
    mutations_per_pixel: u64,
) -> Vec<Vec<f64>> {
    use pathspace::integrator::mlt::{Mlt, MltSettings};
    let cam = scene.camera.as_ref().expect("a camera");
    (0..runs)
        .map(|r| {
            let settings = MltSettings {
                bootstrap: 2000,
                chains: 4,
                ..MltSettings::default()
            };
            let mut m = Mlt::new(scene, tech, settings, seed + r, Some(depth)).unwrap();
            let mut film = pathspace::film::Film::new(cam.width, cam.height);
            m.run(
                scene,
                &mut film,
                (cam.width * cam.height) as u64 * mutations_per_pixel,
            );
            quadrant_means(&film.image())
        })
        .collect()
}

/// Channel `c` of a film's image mean (over pixels) with its standard error from the pixels'
/// own sample variances (pixels are independent) and the Welch-Satterthwaite degrees of freedom
/// of that variance estimate, (sum v)^2 / sum(v^2 / (spp - 1)): between spp - 1 and
/// pixels x (spp - 1). Only for films whose splat buffer is empty (the variance of splats is
/// not recorded; the path tracer splats only the direct image of delta lights).
pub fn film_mean(film: &pathspace::film::Film, c: usize) -> (f64, f64, f64) {
    assert!(
        film.splat.iter().all(|s| s[c] == 0.0),
        "a film with splats has no per-pixel variance"
    );
    let n = film.spp as f64;
    assert!(n >= 2.0, "a standard error needs two samples per pixel");
    let pixels = film.sum.len() as f64;
    let (mut mean, mut var, mut var_sq) = (0.0, 0.0, 0.0);
    for (s, q) in film.sum.iter().zip(&film.sum_sq) {
        let m = s[c] / n;
        let v = ((q[c] / n - m * m) * n / (n - 1.0)).max(0.0) / n;
        mean += m;
        var += v;
        var_sq += v * v / (n - 1.0);
    }
    let dof = if var_sq > 0.0 {
        var * var / var_sq
    } else {
        n - 1.0
    };
    (mean / pixels, var.sqrt() / pixels, dof)
}

/// Channel `c` of a meter's estimate: (value, standard error, samples - 1 degrees of freedom).
pub fn meter_mean(m: &pathspace::integrator::MeterEstimate, c: usize) -> (f64, f64, f64) {
    (
        m.value[c] as f64,
        m.stderr[c] as f64,
        (m.samples as f64 - 1.0).max(1.0),
    )
}
