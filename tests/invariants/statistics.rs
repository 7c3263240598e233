//! The suite's statistics are calibrated, and the calibration is true.
//!
//! - The false-alarm budget (`tests/common/stats.rs`): a correct renderer fails one CI run of
//!   the whole suite by chance with probability below `SUITE_FALSE_ALARM`, because no more
//!   than `STATISTICAL_TESTS` test functions judge Monte Carlo quantities, each through one
//!   `Family` at `TEST_ALPHA = SUITE_FALSE_ALARM / STATISTICAL_TESTS` (Bonferroni over
//!   functions, Holm within one). This file counts the families in the sources of
//!   the test crates, so the budget cannot silently grow past its statement.
//! - No migrated test file uses the uncalibrated helpers (a fixed number of standard errors
//!   whatever the number of comparisons and the degrees of freedom, a fixed significance per
//!   comparison).
//! - The helper itself: Holm's procedure on hand-made p-values, the Student-t quantiles
//!   against printed tables, the exact binomial tail and Welch's degrees of freedom by hand,
//!   and a simulation in which correct estimators are rejected at the rate the procedure
//!   states (so a normal quantile used for a mean of 8 runs, which rejects twice as often,
//!   shows).

use crate::common;

use common::stats::{
    p_welch, runs_mean, student_quantile, student_two_sided, Family, STATISTICAL_TESTS,
    SUITE_FALSE_ALARM, TEST_ALPHA,
};
use pathspace::math::Sampler;
use std::path::{Path, PathBuf};

/// The constructor of a family as it appears in a test (spelled in two parts so that this
/// file's own source does not count it).
const FAMILY_NEW: &str = concat!("Family", "::new(");

/// The uncalibrated helpers and tolerances of the suite before `Family`: a fixed k-sigma bound,
/// a fixed per-comparison significance, and the hand-set slack on fitted orders.
const UNCALIBRATED: [&str; 10] = [
    "assert_within_sigma",
    "SIGMA_BOUND",
    "assert_chi_square(",
    "assert_chi_square_sphere(",
    "assert_ks(",
    "assert_binomial(",
    "assert_quadrants_agree(",
    "SIGNIFICANCE",
    "K_SIGMA",
    "ORDER_SLACK",
];

/// The sources of the test crates under `tests/` (not `tests/common`), by path under `tests/`.
fn test_sources() -> Vec<(String, String)> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                if !path.ends_with("common") {
                    walk(&path, out);
                }
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut files = Vec::new();
    walk(&dir, &mut files);
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let name = p.strip_prefix(&dir).unwrap().to_string_lossy().into_owned();
            (name, std::fs::read_to_string(&p).unwrap())
        })
        .collect()
}

#[test]
fn the_false_alarm_budget_covers_every_family() {
    assert_eq!(TEST_ALPHA, SUITE_FALSE_ALARM / STATISTICAL_TESTS as f64);
    // the stated budget: below 1e-3 per CI run (a const assertion: checked at compile time)
    const _: () = assert!(SUITE_FALSE_ALARM <= 1e-3);
    let sources = test_sources();
    assert!(sources.len() > 20, "tests/ was not found");
    let mut total = 0;
    for (name, text) in &sources {
        let families = text.matches(FAMILY_NEW).count();
        let tests = text.matches("#[test]").count();
        // one family per test function at most (a family built in a helper or a loop would
        // judge many functions' worth of comparisons at one function's level)
        assert!(
            families <= tests,
            "{name}: {families} families in {tests} test functions"
        );
        total += families;
    }
    eprintln!("{total} families of at most {STATISTICAL_TESTS} in tests/");
    assert!(
        total <= STATISTICAL_TESTS,
        "{total} families exceed the budget of {STATISTICAL_TESTS}: raise STATISTICAL_TESTS \
         (which lowers every test's level) or merge tests"
    );
    // the shared helpers never create a family of their own
    let common = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/common");
    for entry in std::fs::read_dir(common).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            !text.contains(FAMILY_NEW),
            "{}: a helper creates a Family",
            path.display()
        );
    }
}

#[test]
fn no_file_uses_an_uncalibrated_helper() {
    // every Monte Carlo assertion of the suite goes through a `Family`: the old helpers and
    // tolerances are gone from tests/common, and none may come back in a test or a helper
    let common = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/common");
    let mut sources = test_sources();
    for entry in std::fs::read_dir(common).unwrap() {
        let path = entry.unwrap().path();
        let name = format!("common/{}", path.file_name().unwrap().to_string_lossy());
        sources.push((name, std::fs::read_to_string(&path).unwrap()));
    }
    let offenders: Vec<String> = sources
        .iter()
        .filter(|(name, _)| !name.ends_with("statistics.rs")) // it names them
        .filter_map(|(name, text)| {
            let used: Vec<&str> = UNCALIBRATED
                .iter()
                .copied()
                .filter(|h| text.contains(h))
                .collect();
            (!used.is_empty()).then(|| format!("{name}: {}", used.join(", ")))
        })
        .collect();
    assert!(
        offenders.is_empty(),
        "uncalibrated helpers in use:\n  {}",
        offenders.join("\n  ")
    );
}

// ---------------------------------------------------------------------------------------------
// The helper

/// Holm's step-down on hand-made p-values at level 0.05: sorted p_(1) <= ... <= p_(m) are
/// rejected while p_(i) <= alpha / (m - i + 1), and nothing after the first acceptance.
#[test]
fn holm_rejects_exactly_what_it_should() {
    let rejected = |ps: &[f64]| -> Vec<f64> {
        let mut fam = Family::with_alpha("hand-made", 0.05);
        for (i, &p) in ps.iter().enumerate() {
            fam.p_value(&format!("c{i}"), p, String::new());
        }
        let mut r: Vec<f64> = fam.into_rejected().iter().map(|c| c.p).collect();
        r.sort_by(f64::total_cmp);
        r
    };
    // 0.004 <= 0.05/4, 0.012 <= 0.05/3, 0.02 <= 0.05/2, 0.2 > 0.05: three rejections where
    // Bonferroni (all against 0.05/4) makes two
    assert_eq!(
        rejected(&[0.2, 0.012, 0.004, 0.02]),
        vec![0.004, 0.012, 0.02]
    );
    // 0.03 > 0.05/2 stops the procedure: 0.04 <= 0.05 is not rejected after it
    assert_eq!(rejected(&[0.04, 0.001, 0.03]), vec![0.001]);
    // the boundary is inclusive, and nothing is rejected when the smallest p passes
    assert_eq!(rejected(&[0.025, 0.025]), vec![0.025, 0.025]);
    assert_eq!(rejected(&[0.0126, 0.5, 0.9, 0.99]), Vec::<f64>::new());
    // a NaN p-value (an estimate that is not a number) is a rejection
    assert_eq!(rejected(&[f64::NAN, 0.9]), vec![0.0]);

    // Family::new judges at TEST_ALPHA, and finish() panics exactly when Holm rejects
    let finish = |ps: Vec<f64>| {
        std::panic::catch_unwind(move || {
            let mut fam = Family::new("statistics: the level of Family::new");
            for (i, p) in ps.into_iter().enumerate() {
                fam.p_value(&format!("c{i}"), p, String::new());
            }
            fam.finish();
        })
        .is_ok()
    };
    assert!(finish(vec![TEST_ALPHA / 2.0 * 1.01, 1.0]));
    assert!(!finish(vec![TEST_ALPHA / 2.0, 1.0]));
    assert!(finish(vec![TEST_ALPHA * 1.01]));
    assert!(!finish(vec![TEST_ALPHA]));
    // a family without comparisons, and one dropped unjudged, are failures too
    assert!(!finish(vec![]));
    assert!(std::panic::catch_unwind(|| {
        let mut fam = Family::with_alpha("unfinished", 0.05);
        fam.p_value("c", 0.5, String::new());
    })
    .is_err());
}

/// Student-t quantiles against printed tables (e.g. Abramowitz and Stegun, table 26.10):
/// t_{0.975, 7} = 2.3646, t_{0.995, 15} = 2.9467, t_{0.975, 1} = 12.7062, and the normal limit
/// 1.95996; the survival function inverts them.
#[test]
fn student_t_matches_the_tables() {
    const TABLE: f64 = 1e-4; // the tables' four decimals
    let cases = [
        (0.05, 7.0, 2.3646),
        (0.01, 15.0, 2.9467),
        (0.05, 1.0, 12.7062),
        (0.10, 30.0, 1.6973),
    ];
    for (alpha, dof, t) in cases {
        let q = student_quantile(alpha, dof);
        assert!(
            (q - t).abs() <= TABLE,
            "t quantile {alpha}, {dof} dof: {q} vs {t}"
        );
        // the tabulated t is rounded to 5e-5, which moves p by less than 1e-4 relative here
        let p = student_two_sided(t, dof);
        assert!(
            (p - alpha).abs() <= 1e-4 * alpha,
            "P(|T_{dof}| > {t}) = {p}, table {alpha}"
        );
    }
    assert!((student_two_sided(1.959_964, 1e9) - 0.05).abs() < 1e-6);
    // what the calibration changes: the 1e-6 two-sided quantile of a mean of 8 runs is 15.77
    // standard errors, not the normal 4.89
    assert!((student_quantile(1e-6, 7.0) - 15.767).abs() < 1e-3);
}

/// The remaining formulas of the helper by hand.
#[test]
fn means_welch_and_binomial_by_hand() {
    // runs: mean 2.5, sample variance 5/3, standard error sqrt(5/12), 3 dof
    let (m, se, dof) = runs_mean(&[1.0, 2.0, 3.0, 4.0]);
    assert_eq!((m, dof), (2.5, 3.0));
    assert!((se - (5.0f64 / 12.0).sqrt()).abs() < 1e-15);
    // Welch: equal standard errors 1 and 10 dof each: t = 1 / sqrt 2 with
    // (1 + 1)^2 / (1/10 + 1/10) = 20 degrees of freedom
    let p = p_welch((1.0, 1.0, 10.0), (0.0, 1.0, 10.0));
    assert!((p - student_two_sided(std::f64::consts::FRAC_1_SQRT_2, 20.0)).abs() < 1e-15);
    // Welch with one exact side is the one-sample t test
    let p = p_welch((1.0, 0.5, 7.0), (0.0, 0.0, 1.0));
    assert!((p - student_two_sided(2.0, 7.0)).abs() < 1e-15);
    // the exact binomial tail: 0 of 10 fair coins is 2 / 1024 two-sided; 5 of 10 is 1
    let p_of = |hits: u64, n: u64, q: f64| {
        let mut fam = Family::with_alpha("binomial", 0.05);
        fam.binomial("b", hits, n, q);
        let p = fam.min_p();
        fam.into_rejected();
        p
    };
    assert!((p_of(0, 10, 0.5) - 2.0 / 1024.0).abs() < 1e-12);
    assert!((p_of(10, 10, 0.5) - 2.0 / 1024.0).abs() < 1e-12);
    assert_eq!(p_of(5, 10, 0.5), 1.0);
    // 2 of 10 at p = 0.5: P(X <= 2) = 56 / 1024, doubled
    assert!((p_of(2, 10, 0.5) - 112.0 / 1024.0).abs() < 1e-12);
    // impossible outcomes
    assert_eq!(p_of(1, 10, 0.0), 0.0);
    assert_eq!(p_of(0, 10, 0.0), 1.0);
    // Pearson: (10, 20) against (15, 15) is 25/15 + 25/15 = 10/3 on one dof, p = 0.0679
    let p = common::chi_square_p_value(&[10, 20], &[15.0, 15.0]);
    assert!((p - 0.067_889).abs() < 1e-5, "chi-square p = {p}");
}

/// A standard normal number from two uniforms (Box-Muller), in f64.
fn normal(s: &mut Sampler) -> f64 {
    let (u1, u2) = (s.next_f64(), s.next_f64());
    (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Over many repetitions with correct estimators, a family at level 0.05 rejects at the rate
/// its procedure states: a mean of 8 normal runs against its truth (Student-t is exact:
/// rate 0.05), four such means at once (Holm rejects when min p <= alpha / 4, for independent
/// comparisons with probability 1 - (1 - alpha / 4)^4 = 0.0491), Welch's test of 6 against
/// 10 runs of unequal variances (approximate: nominal 0.05) and Pearson's chi-square of 10
/// cells of 50 expected counts (nominal 0.05). Each rejection count is judged by the exact
/// binomial test in this test's own family. With a normal quantile for the mean of 8 runs the
/// first rate would be 0.09.
#[test]
fn correct_estimators_are_rejected_at_the_stated_rate() {
    const REPETITIONS: u64 = 4000;
    const ALPHA: f64 = 0.05;
    let mut fam = Family::new("statistics: rejection rates of correct estimators");
    let mut s = common::sampler(0x57a7, 0);
    let runs = |k: usize, sigma: f64, s: &mut Sampler| -> Vec<f64> {
        (0..k).map(|_| 1.0 + sigma * normal(s)).collect()
    };
    let (mut one, mut four, mut welch, mut chi) = (0u64, 0u64, 0u64, 0u64);
    for r in 0..REPETITIONS {
        let mut f = Family::with_alpha("one mean", ALPHA);
        f.runs_are("mean of 8", &runs(8, 1.0, &mut s), 1.0);
        one += (!f.into_rejected().is_empty()) as u64;

        let mut f = Family::with_alpha("four means", ALPHA);
        for i in 0..4 {
            f.runs_are(&format!("mean {i}"), &runs(8, 2.0, &mut s), 1.0);
        }
        four += (!f.into_rejected().is_empty()) as u64;

        let mut f = Family::with_alpha("welch", ALPHA);
        let (a, b) = (runs(6, 1.0, &mut s), runs(10, 3.0, &mut s));
        f.runs_agree("6 vs 10 runs", &a, &b);
        welch += (!f.into_rejected().is_empty()) as u64;

        let mut f = Family::with_alpha("chi-square", ALPHA);
        let mut counts = [0u64; 10];
        let mut c = common::sampler(0x57a8, r);
        for _ in 0..500 {
            counts[c.next_index(10)] += 1;
        }
        f.chi_square("uniform cells", &counts, &[50.0; 10]);
        chi += (!f.into_rejected().is_empty()) as u64;
    }
    eprintln!(
        "rejections of {REPETITIONS}: one mean {one}, four means {four}, Welch {welch}, \
         chi-square {chi}"
    );
    fam.binomial("one mean of 8 runs", one, REPETITIONS, ALPHA);
    let holm = 1.0 - (1.0 - ALPHA / 4.0f64).powi(4);
    fam.binomial("Holm over four means", four, REPETITIONS, holm);
    fam.binomial("Welch", welch, REPETITIONS, ALPHA);
    fam.binomial("chi-square", chi, REPETITIONS, ALPHA);
    fam.finish();
}
