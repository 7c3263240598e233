//! A convergence study's record (`study.toml` beside `convergence.csv`) and the merge of the
//! shards of one study (`converge --shard I/N`, then `merge DIR... -o DIR`).
//!
//! A study of R runs split into N shards renders runs `(I-1)R/N .. IR/N` in shard I, each with
//! the seed it has in the whole study (`convergence::run_seed(seed, run)`), so the merged rows
//! are the rows one process would have written, up to the timings (each run is timed where it
//! ran). The merge checks that the shards describe one study (scene, budget, checkpoints, runs,
//! seed, lines) and that every shard is there once.
//! Book: "Measuring a renderer" (shards).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::convergence::{CheckpointRow, CSV_HEADER};
use crate::render::shard::Shard;

/// The file beside `convergence.csv` that describes the study.
pub const STUDY_FILE: &str = "study.toml";

/// What a study (or one shard of it) was.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Study {
    /// The scene file's name and the hash of its text (FNV-1a, as in the EXR provenance).
    pub scene: String,
    pub scene_hash: String,
    pub budget: f64,
    pub checkpoints: usize,
    /// Runs of the whole study (all shards).
    pub runs: usize,
    pub seed: u64,
    /// The lines as asked for (`--integrators`, `--propagation`, `--external`).
    pub lines: Vec<String>,
    /// `I/N` for a shard; absent for a whole study.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<String>,
    /// The reference's estimated relMSE (its noise floor in the charts), when it records one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_relmse: Option<f64>,
}

/// Why shards cannot be merged into one study; the messages are what `merge` prints.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error("{0}: {1}")]
    Io(String, #[source] std::io::Error),
    #[error("{0}: {1}")]
    Parse(String, String),
    #[error("{0} is no shard of a study (`converge --shard I/N` writes one)")]
    NotAShard(String),
    #[error("{0} and {1} are shards of different studies ({2} differs)")]
    Different(String, String, &'static str),
    #[error("{0} and {1} are both shard {2}")]
    Twice(String, String, String),
    #[error("the study has {0} shards, but shard {1} is missing")]
    Missing(u32, String),
    /// The record cannot be written (its path, the cause).
    #[error(transparent)]
    Write(#[from] crate::image_io::ImageError),
}

impl Study {
    /// Writes the record into `dir`.
    pub fn write(&self, dir: &Path) -> Result<(), StudyError> {
        let path = dir.join(STUDY_FILE);
        let text = toml::to_string(self).map_err(|e| parse_err(&path, e))?;
        // through a temporary file: a full disk leaves an earlier record whole
        Ok(crate::image_io::write_file_replacing(
            &path,
            text.as_bytes(),
        )?)
    }

    /// Reads the record of the study in `dir`.
    pub fn read(dir: &Path) -> Result<Study, StudyError> {
        let path = dir.join(STUDY_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| io_err(&path, e))?;
        toml::from_str(&text).map_err(|e| parse_err(&path, e))
    }

    /// The first field in which `other` describes another study than `self`.
    fn differs(&self, other: &Study) -> Option<&'static str> {
        let checks: [(&'static str, bool); 7] = [
            ("the scene", self.scene_hash == other.scene_hash),
            ("the budget", self.budget == other.budget),
            ("the checkpoints", self.checkpoints == other.checkpoints),
            ("the runs", self.runs == other.runs),
            ("the seed", self.seed == other.seed),
            ("the lines", self.lines == other.lines),
            (
                "the reference",
                self.reference_relmse == other.reference_relmse,
            ),
        ];
        checks.iter().find(|(_, same)| !same).map(|(what, _)| *what)
    }
}

fn io_err(path: &Path, e: std::io::Error) -> StudyError {
    StudyError::Io(path.display().to_string(), e)
}

fn parse_err(path: &Path, e: impl std::fmt::Display) -> StudyError {
    StudyError::Parse(path.display().to_string(), e.to_string())
}

/// Reads a `convergence.csv` written by `convergence::write_csv`.
pub fn read_csv(path: &Path) -> Result<Vec<CheckpointRow>, StudyError> {
    let text = std::fs::read_to_string(path).map_err(|e| io_err(path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(CSV_HEADER) {
        return Err(parse_err(path, format!("the header is not `{CSV_HEADER}`")));
    }
    lines
        .enumerate()
        .map(|(i, l)| row(l).ok_or_else(|| parse_err(path, format!("line {}: `{l}`", i + 2))))
        .collect()
}

fn row(line: &str) -> Option<CheckpointRow> {
    let f: Vec<&str> = line.split(',').collect();
    let [integrator, run, checkpoint, seconds, samples, rmse, relmse, efficiency] = f[..] else {
        return None;
    };
    Some(CheckpointRow {
        integrator: integrator.to_string(),
        run: run.parse().ok()?,
        checkpoint: checkpoint.parse().ok()?,
        seconds: seconds.parse().ok()?,
        samples: samples.parse().ok()?,
        rmse: rmse.parse().ok()?,
        relmse: relmse.parse().ok()?,
        efficiency: efficiency.parse().ok()?,
    })
}

/// The shards in `dirs` as one study: its record (without a shard) and every row, line by line
/// in the study's order, run by run; refused unless they are the N shards of one study, each
/// once.
pub fn merge_shards(dirs: &[&Path]) -> Result<(Study, Vec<CheckpointRow>), StudyError> {
    let mut parts: Vec<(Shard, &Path, Study)> = Vec::new();
    for &d in dirs {
        let study = Study::read(d)?;
        let name = || d.display().to_string();
        let shard = study
            .shard
            .as_deref()
            .ok_or_else(|| StudyError::NotAShard(name()))?;
        let shard = Shard::parse(shard).map_err(|e| StudyError::Parse(name(), e.to_string()))?;
        if let Some((s, other, first)) = parts.first() {
            let what = first
                .differs(&study)
                .or((s.count != shard.count).then_some("the number of shards"));
            if let Some(what) = what {
                return Err(StudyError::Different(
                    other.display().to_string(),
                    name(),
                    what,
                ));
            }
        }
        if let Some((_, other, _)) = parts.iter().find(|(s, _, _)| *s == shard) {
            let i = format!("{}/{}", shard.index, shard.count);
            return Err(StudyError::Twice(other.display().to_string(), name(), i));
        }
        parts.push((shard, d, study));
    }
    let Some((first, _, study)) = parts.first().cloned() else {
        return Err(StudyError::Missing(0, "1".into()));
    };
    for i in 1..=first.count {
        if !parts.iter().any(|(s, _, _)| s.index == i) {
            return Err(StudyError::Missing(
                first.count,
                format!("{i}/{}", first.count),
            ));
        }
    }
    parts.sort_by_key(|(s, _, _)| s.index);
    let mut rows = Vec::new();
    for (_, d, _) in &parts {
        rows.extend(read_csv(&d.join("convergence.csv"))?);
    }
    // line by line in the order they first appear, then run by run: one process's order
    let mut order: Vec<String> = Vec::new();
    for r in &rows {
        if !order.contains(&r.integrator) {
            order.push(r.integrator.clone());
        }
    }
    let line = |r: &CheckpointRow| order.iter().position(|l| *l == r.integrator);
    rows.sort_by_key(|r| (line(r), r.run, r.checkpoint));
    Ok((
        Study {
            shard: None,
            ..study
        },
        rows,
    ))
}
