//! Calibrated statistics: every Monte Carlo assertion of the suite goes through a [`Family`].
//!
//! The false-alarm budget. With a correct renderer and a random seed, one CI run of the whole
//! suite fails by chance with probability below [`SUITE_FALSE_ALARM`]: the suite holds at most
//! [`STATISTICAL_TESTS`] statistical test functions (`tests/invariants/statistics.rs` counts them), each
//! gets [`TEST_ALPHA`] = budget / count (Bonferroni over tests), and within one test the
//! comparisons share that level by Holm's step-down procedure (sorted p-values p_(1) <= ... <=
//! p_(m); the test fails when p_(1) <= alpha / m, or p_(2) <= alpha / (m - 1) after it, ...),
//! which controls the family-wise error rate for any dependence between the comparisons.
//!
//! The p-values. A mean over k independent runs with its standard error estimated from the same
//! k runs is Student-t distributed with k - 1 degrees of freedom, not normal: with 8 runs the
//! 1e-6 two-sided quantile is 15.8 standard errors, not 4.9. Two independent sets of runs are
//! compared by Welch's t with the Welch-Satterthwaite degrees of freedom. A mean of n
//! independent samples inside one render uses n - 1 (normal in effect). Goodness of fit uses
//! Pearson's chi-square, Kolmogorov-Smirnov or the exact binomial tail.
//!
//! Fixed seeds make every test reproducible; the budget is the probability over seeds.
#![allow(dead_code)]

use statrs::distribution::{Binomial, ContinuousCDF, DiscreteCDF, StudentsT};

/// The probability that one CI run of the whole suite fails by chance on a correct renderer.
pub const SUITE_FALSE_ALARM: f64 = 1e-3;
/// The most statistical test functions the suite may hold (each with one [`Family`]); checked
/// by `tests/invariants/statistics.rs`, so adding tests beyond it means lowering every test's level.
pub const STATISTICAL_TESTS: usize = 250;
/// The significance level of one statistical test function.
pub const TEST_ALPHA: f64 = SUITE_FALSE_ALARM / STATISTICAL_TESTS as f64;

/// The allowance for an estimator whose standard error is exactly zero (a deterministic
/// quantity computed in f32): a few units in the last place of an f32 result of order one.
pub const ZERO_VARIANCE_ALLOWANCE: f64 = 8.0 * f32::EPSILON as f64;

/// One comparison of a family: its p-value and what to print if it is rejected.
#[derive(Clone, Debug)]
pub struct Comparison {
    pub what: String,
    pub p: f64,
    pub detail: String,
}

/// The comparisons of one test function, judged together at [`TEST_ALPHA`] by Holm's method.
/// Call [`Family::finish`] at the end; dropping an unfinished family panics (a test that forgot
/// to judge its comparisons would otherwise pass).
#[derive(Debug)]
pub struct Family {
    name: String,
    alpha: f64,
    comparisons: Vec<Comparison>,
    finished: bool,
}

/// Student-t survival function, two-sided: P(|T_dof| >= |t|). `dof` may be fractional (Welch).
pub fn student_two_sided(t: f64, dof: f64) -> f64 {
    if !t.is_finite() {
        return 0.0;
    }
    if dof > 1e7 {
        // the normal limit (statrs' t is unstable for astronomically many degrees of freedom)
        return 2.0 * statrs::distribution::Normal::standard().sf(t.abs());
    }
    let d = StudentsT::new(0.0, 1.0, dof.max(1.0)).expect("positive degrees of freedom");
    (2.0 * d.sf(t.abs())).min(1.0)
}

/// The two-sided Student-t quantile: |t| beyond it has probability `alpha`.
pub fn student_quantile(alpha: f64, dof: f64) -> f64 {
    let d = StudentsT::new(0.0, 1.0, dof.max(1.0)).expect("positive degrees of freedom");
    d.inverse_cdf(1.0 - alpha / 2.0)
}

/// Mean, standard error of the mean and degrees of freedom (k - 1) of k independent values.
pub fn runs_mean(values: &[f64]) -> (f64, f64, f64) {
    let k = values.len() as f64;
    assert!(k >= 2.0, "a standard error needs at least two runs");
    let mean = values.iter().sum::<f64>() / k;
    let var = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0);
    (mean, (var / k).sqrt(), k - 1.0)
}

/// The p-value of |mean - truth| for a mean with standard error `se` and `dof` degrees of
/// freedom; a zero standard error accepts exact agreement up to [`ZERO_VARIANCE_ALLOWANCE`].
pub fn p_mean(mean: f64, se: f64, dof: f64, truth: f64) -> f64 {
    let diff = (mean - truth).abs();
    if !(mean.is_finite() && se.is_finite()) {
        return 0.0;
    }
    if se == 0.0 {
        let allowance = ZERO_VARIANCE_ALLOWANCE * truth.abs().max(1.0);
        return if diff <= allowance { 1.0 } else { 0.0 };
    }
    student_two_sided(diff / se, dof)
}

/// Welch's test of two means with standard errors and degrees of freedom: the p-value.
pub fn p_welch(a: (f64, f64, f64), b: (f64, f64, f64)) -> f64 {
    let (ma, sa, da) = a;
    let (mb, sb, db) = b;
    let va = sa * sa;
    let vb = sb * sb;
    let v = va + vb;
    if !(ma.is_finite() && mb.is_finite() && v.is_finite()) {
        return 0.0;
    }
    if v == 0.0 {
        return p_mean(ma, 0.0, 1.0, mb);
    }
    // Welch-Satterthwaite
    let dof = v * v / (va * va / da.max(1.0) + vb * vb / db.max(1.0));
    student_two_sided((ma - mb) / v.sqrt(), dof)
}

impl Family {
    /// A family at the level of one statistical test function.
    pub fn new(name: &str) -> Self {
        Family {
            name: name.to_string(),
            alpha: TEST_ALPHA,
            comparisons: Vec::new(),
            finished: false,
        }
    }

    /// A family at another level `alpha`: only for testing the procedure itself
    /// (`tests/invariants/statistics.rs` simulates its false-alarm rate at a level where a rate can be
    /// measured in a few thousand repetitions). Renderer tests use [`Family::new`].
    pub fn with_alpha(name: &str, alpha: f64) -> Self {
        Family {
            name: name.to_string(),
            alpha,
            comparisons: Vec::new(),
            finished: false,
        }
    }

    /// Adds a comparison by its p-value.
    pub fn p_value(&mut self, what: &str, p: f64, detail: String) {
        let p = if p.is_nan() { 0.0 } else { p };
        self.comparisons.push(Comparison {
            what: what.to_string(),
            p,
            detail,
        });
    }

    /// A mean with standard error `se` (`dof` degrees of freedom) equals `truth`.
    pub fn mean_is(&mut self, what: &str, mean: f64, se: f64, dof: f64, truth: f64) {
        let p = p_mean(mean, se, dof, truth);
        let z = (mean - truth) / se;
        self.p_value(
            what,
            p,
            format!("got {mean:.6e} +- {se:.2e} ({dof:.0} dof), expected {truth:.6e}: {z:+.2} se"),
        );
    }

    /// The mean of independent runs equals `truth` (Student-t with k - 1 degrees of freedom).
    pub fn runs_are(&mut self, what: &str, runs: &[f64], truth: f64) {
        let (m, se, dof) = runs_mean(runs);
        self.mean_is(what, m, se, dof, truth);
    }

    /// A mean of `n` independent samples (sample variance `var`) equals `truth`.
    pub fn samples_are(&mut self, what: &str, mean: f64, var: f64, n: u64, truth: f64) {
        let se = (var.max(0.0) / n as f64).sqrt();
        self.mean_is(what, mean, se, (n as f64 - 1.0).max(1.0), truth);
    }

    /// Two (mean, standard error, degrees of freedom) agree (Welch).
    pub fn means_agree(&mut self, what: &str, a: (f64, f64, f64), b: (f64, f64, f64)) {
        let p = p_welch(a, b);
        let se = (a.1 * a.1 + b.1 * b.1).sqrt();
        let z = (a.0 - b.0) / se;
        self.p_value(
            what,
            p,
            format!(
                "{:.6e} +- {:.2e} vs {:.6e} +- {:.2e}: {z:+.2} se",
                a.0, a.1, b.0, b.1
            ),
        );
    }

    /// Two sets of independent runs have the same mean (Welch).
    pub fn runs_agree(&mut self, what: &str, a: &[f64], b: &[f64]) {
        self.means_agree(what, runs_mean(a), runs_mean(b));
    }

    /// Pearson's chi-square of binned counts against expected counts.
    pub fn chi_square(&mut self, what: &str, observed: &[u64], expected: &[f64]) {
        let p = super::chi_square_p_value(observed, expected);
        let n: u64 = observed.iter().sum();
        // the bin that departs most, in standard deviations of its count
        let worst = observed
            .iter()
            .zip(expected)
            .enumerate()
            .map(|(k, (&o, &e))| (k, o, e, (o as f64 - e) / e.max(1e-300).sqrt()))
            .max_by(|a, b| a.3.abs().total_cmp(&b.3.abs()));
        let detail = match worst {
            Some((k, o, e, z)) => format!(
                "chi-square over {n} samples; bin {k}: got {o}, expected {e:.1} ({z:+.1} sd)"
            ),
            None => format!("chi-square over {n} samples"),
        };
        self.p_value(what, p, detail);
    }

    /// The Kolmogorov-Smirnov test of samples against a continuous CDF.
    pub fn ks(&mut self, what: &str, samples: &mut [f64], cdf: impl Fn(f64) -> f64) {
        let p = super::ks_p_value(samples, &cdf);
        // the sample where the empirical CDF departs most from the expected one (sorted now)
        let n = samples.len() as f64;
        let worst = samples
            .iter()
            .enumerate()
            .map(|(i, &x)| (x, (i as f64 + 0.5) / n, cdf(x)))
            .max_by(|a, b| (a.1 - a.2).abs().total_cmp(&(b.1 - b.2).abs()));
        let detail = match worst {
            Some((x, got, expected)) => format!(
                "KS over {} samples; at {x:.4e}: got empirical CDF {got:.4}, expected {expected:.4}",
                samples.len()
            ),
            None => format!("KS over {} samples", samples.len()),
        };
        self.p_value(what, p, detail);
    }

    /// `hits` successes in `n` Bernoulli(p) trials: the exact two-sided binomial tail.
    pub fn binomial(&mut self, what: &str, hits: u64, n: u64, p: f64) {
        let pv = if p <= 0.0 || p >= 1.0 {
            let expected = if p <= 0.0 { 0 } else { n };
            if hits == expected {
                1.0
            } else {
                0.0
            }
        } else {
            let b = Binomial::new(p, n).expect("a probability in (0, 1)");
            let lower = b.cdf(hits);
            let upper = if hits == 0 { 1.0 } else { b.sf(hits - 1) };
            (2.0 * lower.min(upper)).min(1.0)
        };
        self.p_value(
            what,
            pv,
            format!(
                "{hits}/{n} = {:.5} vs p = {p:.5}",
                hits as f64 / n.max(1) as f64
            ),
        );
    }

    /// The number of comparisons so far.
    pub fn len(&self) -> usize {
        self.comparisons.len()
    }

    /// The smallest p-value so far (1 without comparisons).
    pub fn min_p(&self) -> f64 {
        self.comparisons.iter().map(|c| c.p).fold(1.0, f64::min)
    }

    // ANCHOR: holm
    /// Holm's step-down verdict: the comparisons rejected at the family's level.
    pub fn rejected(&self) -> Vec<Comparison> {
        let mut sorted = self.comparisons.clone();
        sorted.sort_by(|a, b| a.p.total_cmp(&b.p));
        let m = sorted.len();
        let mut out = Vec::new();
        for (i, c) in sorted.into_iter().enumerate() {
            if c.p > self.alpha / (m - i) as f64 {
                break;
            }
            out.push(c);
        }
        out
    }
    // ANCHOR_END: holm

    /// Holm's verdict without panicking: the rejected comparisons (the family is finished).
    /// For simulations of the procedure; renderer tests call [`Family::finish`].
    pub fn into_rejected(mut self) -> Vec<Comparison> {
        self.finished = true;
        self.rejected()
    }

    /// Judges the family: panics listing every rejected comparison.
    pub fn finish(mut self) {
        self.finished = true;
        assert!(
            !self.comparisons.is_empty(),
            "{}: a statistical test without comparisons",
            self.name
        );
        if std::env::var_os("PATHSPACE_STATS").is_some() {
            // PATHSPACE_STATS=1 lists every comparison, smallest p first (power and calibration
            // of a test at a glance; run with --nocapture)
            let mut sorted = self.comparisons.clone();
            sorted.sort_by(|a, b| a.p.total_cmp(&b.p));
            eprintln!("{}: {} comparisons", self.name, sorted.len());
            for c in &sorted {
                eprintln!("  {}: p = {:.2e}: {}", c.what, c.p, c.detail);
            }
        }
        if let Some(path) = std::env::var_os("PATHSPACE_STATS_DUMP") {
            // scripts/bit-identity.sh: the exact p of every comparison, one line each
            self.dump(std::path::Path::new(&path));
        }
        let rejected = self.rejected();
        if !rejected.is_empty() {
            let lines: Vec<String> = rejected
                .iter()
                .map(|c| format!("  {}: p = {:.2e}: {}", c.what, c.p, c.detail))
                .collect();
            panic!(
                "{}: {} of {} comparisons rejected at family level {:.1e} (Holm):\n{}",
                self.name,
                rejected.len(),
                self.comparisons.len(),
                self.alpha,
                lines.join("\n")
            );
        }
    }
}

impl Family {
    /// Appends `family<TAB>comparison<TAB>p` (p exactly, as `{:?}` prints it) to `path`.
    fn dump(&self, path: &std::path::Path) {
        use std::io::Write;
        let lines: String = self
            .comparisons
            .iter()
            .map(|c| format!("{}\t{}\t{:?}\n", self.name, c.what, c.p))
            .collect();
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .expect("PATHSPACE_STATS_DUMP: cannot open the file");
        f.write_all(lines.as_bytes())
            .expect("PATHSPACE_STATS_DUMP: cannot write");
    }
}

impl Drop for Family {
    fn drop(&mut self) {
        if !self.finished && !std::thread::panicking() {
            panic!("{}: Family dropped without finish()", self.name);
        }
    }
}

/// A power check: a difference the suite claims to see (a deliberately wrong reference, a
/// known defect of a variant) must be significant at [`TEST_ALPHA`], so that the test that
/// guards against it could fail. `p` is the p-value of "no difference".
pub fn assert_significant(what: &str, p: f64) {
    assert!(
        p <= TEST_ALPHA,
        "{what}: p = {p:.2e} > {TEST_ALPHA:.1e}: the difference is not significant, so the \
         test that should see it has no power"
    );
}
