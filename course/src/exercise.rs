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
