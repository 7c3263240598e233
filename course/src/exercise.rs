//! Open-ended measurement exercises (book: "Course use: assignments", measurement exercises):
//! the student runs `pathspace converge` studies of their own design (scene, budget, runs) and
//! the exercise's claims are judged from the studies' `convergence.csv`, each with Student's t
//! over the independent runs, at a family-wise level of 5 % (Bonferroni over the claims).
//!
//! Two claims are known: `efficiency_ratio` (one line's final efficiency over another's is at
//! least a threshold: Welch's one-sided test on the runs' log efficiencies) and `slope` (the
//! fitted slope of log relMSE against log time, one fit per run, lies in an interval: the
//! two-sided confidence interval of its mean must lie inside it).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use statrs::distribution::{ContinuousCDF, StudentsT};

/// The family-wise error rate of an exercise's claims.
pub const ALPHA: f64 = 0.05;

/// Fewer runs than this make a t interval too wide to judge anything, and one run none at all.
pub const MIN_RUNS: usize = 3;

/// A measurement exercise of the registry.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Exercise {
    pub name: String,
    /// The chapter that asks it, under `book/src/`.
    pub chapter_file: String,
    /// The question, in one line.
    pub question: String,
    /// The studies to run (each a `pathspace converge ... -o DIR` command; the student may
    /// change budgets, runs and resolution).
    pub studies: Vec<String>,
    /// A student's time for it, in hours.
    pub hours: u32,
    /// What the studies must show.
    pub claims: Vec<Claim>,
}

/// One claim about the studies' lines. A line is named by its label in `convergence.csv`
/// (`path`, `path/delta-tracking`), or `STUDY:LABEL` where STUDY is the name of the study's
/// directory, when several studies are compared.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Claim {
    /// efficiency(line) / efficiency(over) >= at_least at the last checkpoint.
    EfficiencyRatio {
        line: String,
        over: String,
        at_least: f64,
    },
    /// The slope of log relMSE against log seconds of `line` lies within [lo, hi].
    Slope { line: String, within: [f64; 2] },
}

/// Why an exercise cannot be graded.
#[derive(Debug, thiserror::Error)]
pub enum ExerciseError {
    #[error("no exercise `{0}`; `pathspace assignment list` shows them")]
    Unknown(String),
    #[error("cannot read {0}: {1}")]
    Read(String, #[source] std::io::Error),
    #[error("{0}: {1}")]
    Csv(String, String),
    #[error("no line `{0}` in the studies given (lines: {1})")]
    NoLine(String, String),
    #[error("line `{0}` has {1} runs; the claims need at least {MIN_RUNS} (converge --runs)")]
    TooFewRuns(String, usize),
}

/// One run of one line: its checkpoints as (seconds, relMSE, efficiency).
type Run = Vec<(f64, f64, f64)>;

/// The lines of the studies in `dirs`: label (and `STUDY:LABEL`) -> its runs.
pub fn read_studies(dirs: &[PathBuf]) -> Result<BTreeMap<String, Vec<Run>>, ExerciseError> {
    let mut lines: BTreeMap<String, Vec<Run>> = BTreeMap::new();
    for d in dirs {
        let csv = d.join("convergence.csv");
        let text = std::fs::read_to_string(&csv)
            .map_err(|e| ExerciseError::Read(csv.display().to_string(), e))?;
        let study = d
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let mut runs: BTreeMap<(String, usize), Run> = BTreeMap::new();
        let mut rows = text.lines();
        let header: Vec<&str> = rows.next().unwrap_or("").split(',').collect();
        let col = |name: &str| {
            header.iter().position(|h| *h == name).ok_or_else(|| {
                ExerciseError::Csv(csv.display().to_string(), format!("no column `{name}`"))
            })
        };
        let (ci, cr, cs, cm, ce) = (
            col("integrator")?,
            col("run")?,
            col("seconds")?,
            col("relmse")?,
            col("efficiency")?,
        );
        for (i, row) in rows.enumerate() {
            let f: Vec<&str> = row.split(',').collect();
            let bad = || ExerciseError::Csv(csv.display().to_string(), format!("row {}", i + 2));
            let num = |c: usize| f.get(c).and_then(|v| v.parse::<f64>().ok()).ok_or_else(bad);
            let run: usize = f.get(cr).and_then(|v| v.parse().ok()).ok_or_else(bad)?;
            let label = f.get(ci).ok_or_else(bad)?.to_string();
            runs.entry((label, run))
                .or_default()
                .push((num(cs)?, num(cm)?, num(ce)?));
        }
        for ((label, _), run) in runs {
            lines
                .entry(format!("{study}:{label}"))
                .or_default()
                .push(run.clone());
            lines.entry(label).or_default().push(run);
        }
    }
    Ok(lines)
}

/// Mean and standard error of the mean.
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Least-squares slope of y against x.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

fn t_quantile(p: f64, df: f64) -> f64 {
    StudentsT::new(0.0, 1.0, df.max(1.0))
        .map(|t| t.inverse_cdf(p))
        .unwrap_or(f64::INFINITY)
}

/// The verdict on one claim: passed, and the sentence that says what was measured.
pub struct Verdict {
    pub passed: bool,
    pub report: String,
}

fn runs_of<'a>(
    lines: &'a BTreeMap<String, Vec<Run>>,
    name: &str,
) -> Result<&'a Vec<Run>, ExerciseError> {
    let runs = lines.get(name).ok_or_else(|| {
        let known: Vec<&str> = lines.keys().map(String::as_str).collect();
        ExerciseError::NoLine(name.to_string(), known.join(", "))
    })?;
    if runs.len() < MIN_RUNS {
        return Err(ExerciseError::TooFewRuns(name.to_string(), runs.len()));
    }
    Ok(runs)
}

/// Judges `claim` at level `alpha`.
pub fn judge(
    claim: &Claim,
    lines: &BTreeMap<String, Vec<Run>>,
    alpha: f64,
) -> Result<Verdict, ExerciseError> {
    let last_log_eff = |runs: &Vec<Run>| -> Vec<f64> {
        runs.iter()
            .map(|r| r.last().map_or(f64::NAN, |c| c.2.ln()))
            .collect()
    };
    Ok(match claim {
        Claim::EfficiencyRatio {
            line,
            over,
            at_least,
        } => {
            let (a, b) = (
                last_log_eff(runs_of(lines, line)?),
                last_log_eff(runs_of(lines, over)?),
            );
            let ((ma, sa), (mb, sb)) = (mean_se(&a), mean_se(&b));
            let se = (sa * sa + sb * sb).sqrt();
            // Welch-Satterthwaite degrees of freedom
            let df = se.powi(4)
                / (sa.powi(4) / (a.len() as f64 - 1.0) + sb.powi(4) / (b.len() as f64 - 1.0));
            let lower = (ma - mb) - t_quantile(1.0 - alpha, df) * se;
            Verdict {
                passed: lower > at_least.ln(),
                report: format!(
                    "efficiency of {line} over {over}: got {:.3} (one-sided {:.1}% lower bound \
                     {:.3}, {} and {} runs), expected at least {at_least}",
                    (ma - mb).exp(),
                    100.0 * (1.0 - alpha),
                    lower.exp(),
                    a.len(),
                    b.len()
                ),
            }
        }
        Claim::Slope { line, within } => {
            let runs = runs_of(lines, line)?;
            let s: Vec<f64> = runs
                .iter()
                .map(|r| {
                    let pts: Vec<(f64, f64)> = r.iter().map(|c| (c.0.ln(), c.1.ln())).collect();
                    slope(&pts)
                })
                .collect();
            let (m, se) = mean_se(&s);
            let h = t_quantile(1.0 - alpha / 2.0, s.len() as f64 - 1.0) * se;
            Verdict {
                passed: m - h >= within[0] && m + h <= within[1],
                report: format!(
                    "slope of relMSE against time of {line}: got {m:.3} ± {h:.3} ({:.1}% \
                     interval, {} runs), expected within [{}, {}]",
                    100.0 * (1.0 - alpha),
                    s.len(),
                    within[0],
                    within[1]
                ),
            }
        }
    })
}

/// Judges every claim of `e` from the studies in `dirs`, at a family-wise level [`ALPHA`].
pub fn grade(e: &Exercise, dirs: &[PathBuf]) -> Result<Vec<Verdict>, ExerciseError> {
    let lines = read_studies(dirs)?;
    let alpha = ALPHA / e.claims.len().max(1) as f64;
    e.claims.iter().map(|c| judge(c, &lines, alpha)).collect()
}

/// The study directories a command line names (`-o DIR` or `--output DIR`).
pub fn output_of(command: &str) -> Option<&Path> {
    let words: Vec<&str> = command.split_whitespace().collect();
    words
        .windows(2)
        .find(|w| w[0] == "-o" || w[0] == "--output")
        .map(|w| Path::new(w[1]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A study of `runs` runs of two lines: `a` with relMSE 1/(t e_a), `b` with 1/(t e_b), each
    /// run's efficiency scaled by a fixed spread factor, and relMSE falling as t^slope.
    fn study(dir: &Path, runs: usize, e_a: f64, e_b: f64, slope: f64) {
        noisy_study(dir, runs, e_a, e_b, slope, 0.0);
    }

    /// [`study`] with the runs' slopes alternating by +-`slope_spread` around `slope`.
    fn noisy_study(dir: &Path, runs: usize, e_a: f64, e_b: f64, slope: f64, slope_spread: f64) {
        std::fs::create_dir_all(dir).unwrap();
        let mut csv =
            String::from("integrator,run,checkpoint,seconds,samples,rmse,relmse,efficiency\n");
        for (label, e) in [("a", e_a), ("b/x", e_b)] {
            for r in 0..runs {
                let spread = 1.0 + 0.05 * (r as f64 - (runs as f64 - 1.0) / 2.0);
                let slope = slope
                    + if r % 2 == 0 {
                        slope_spread
                    } else {
                        -slope_spread
                    };
                for k in 0..5 {
                    let t = 0.5 * 2f64.powi(k);
                    let relmse =
                        t.powf(slope) / (e * spread) * (1.0 + 0.01 * ((r + k as usize) % 3) as f64);
                    let eff = 1.0 / (relmse * t);
                    csv.push_str(&format!(
                        "{label},{r},{k},{t},{},0.1,{relmse},{eff}\n",
                        10 * k
                    ));
                }
            }
        }
        std::fs::write(dir.join("convergence.csv"), csv).unwrap();
    }

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("pathspace-course-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn efficiency_ratios_are_judged_one_sided_from_the_runs() {
        let d = scratch("ratio");
        study(&d, 4, 2.0, 1.0, -1.0);
        let lines = read_studies(std::slice::from_ref(&d)).unwrap();
        let claim = |at_least: f64| Claim::EfficiencyRatio {
            line: "a".into(),
            over: "b/x".into(),
            at_least,
        };
        let v = judge(&claim(1.0), &lines, ALPHA).unwrap();
        assert!(v.passed, "{}", v.report);
        assert!(v.report.contains("got 2.0"), "{}", v.report);
        // a ratio of 2 with a 5 % spread does not show a ratio of 2.5, nor of 2 itself
        assert!(!judge(&claim(2.5), &lines, ALPHA).unwrap().passed);
        assert!(!judge(&claim(2.0), &lines, ALPHA).unwrap().passed);
        // the study's directory name qualifies a line
        assert!(judge(
            &Claim::EfficiencyRatio {
                line: format!("{}:a", d.file_name().unwrap().to_string_lossy()),
                over: "b/x".into(),
                at_least: 1.0,
            },
            &lines,
            ALPHA
        )
        .is_ok());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn slopes_are_judged_by_their_confidence_interval() {
        let d = scratch("slope");
        study(&d, 4, 1.0, 1.0, -1.0);
        let lines = read_studies(std::slice::from_ref(&d)).unwrap();
        let claim = |lo: f64, hi: f64| Claim::Slope {
            line: "a".into(),
            within: [lo, hi],
        };
        let v = judge(&claim(-1.2, -0.8), &lines, ALPHA).unwrap();
        assert!(v.passed, "{}", v.report);
        assert!(!judge(&claim(-0.9, -0.5), &lines, ALPHA).unwrap().passed);
        let _ = std::fs::remove_dir_all(&d);
        // runs whose slopes scatter widely around -1: the mean is inside the band, the
        // interval is not, and the claim is not shown
        let d = scratch("noisy");
        noisy_study(&d, 4, 1.0, 1.0, -1.0, 0.4);
        let lines = read_studies(std::slice::from_ref(&d)).unwrap();
        let v = judge(&claim(-1.2, -0.8), &lines, ALPHA).unwrap();
        assert!(!v.passed, "{}", v.report);
        let _ = std::fs::remove_dir_all(&d);
        // a flattened curve (a biased estimator's floor) is refused
        let d = scratch("flat");
        study(&d, 4, 1.0, 1.0, -0.4);
        let lines = read_studies(std::slice::from_ref(&d)).unwrap();
        assert!(!judge(&claim(-1.2, -0.8), &lines, ALPHA).unwrap().passed);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn too_few_runs_and_unknown_lines_are_errors() {
        let d = scratch("few");
        study(&d, 2, 2.0, 1.0, -1.0);
        let lines = read_studies(std::slice::from_ref(&d)).unwrap();
        let slope = |line: &str| Claim::Slope {
            line: line.into(),
            within: [-2.0, 0.0],
        };
        assert!(matches!(
            judge(&slope("a"), &lines, ALPHA),
            Err(ExerciseError::TooFewRuns(_, 2))
        ));
        assert!(matches!(
            judge(&slope("c"), &lines, ALPHA),
            Err(ExerciseError::NoLine(..))
        ));
        let _ = std::fs::remove_dir_all(&d);
    }
}
