//! A render's provenance: what its image estimates (the scene file's hash, the integrator and its
//! settings) and which samples it holds (its sample streams and sample count), recorded in the
//! EXR header, so that `merge` can refuse inputs that are not independent estimates of one
//! image, and a merged file records its sources.
//!
//! Every random stream of a render is `Sampler::new(seed, pixel, pass)`, so a render's samples
//! are named by its seed and the range of pass indices it drew: `streams = "7:0..16"` (seed 7,
//! passes 0 to 15). Two renders share samples exactly when they share a seed and their pass
//! ranges intersect; disjoint ranges of one seed (parts of one run, e.g. shards) are
//! independent, and a render resumed from a checkpoint continues its range (checkpoints fall
//! between passes). MLT's chains start at pass 0 of their seed whatever the range, so two MLT
//! runs of one seed always overlap; a resumed MLT run is an independent run with a seed of its
//! own ([`super::checkpoint::Checkpoint::resume_seed`]) and adds a range: `7:0..2,SEED2:0..2`.
//! Book: "Measuring a renderer" (provenance, merging, determinism).

use std::fmt;

use serde::{Deserialize, Serialize};

use super::shard::Shard;
use crate::image_io::ImageMeta;

/// The EXR attributes that hold timings: left out by `render --reproducible`, so that the same
/// scene, seed and settings give the same bytes.
pub const TIMING_KEYS: [&str; 2] = ["seconds", "guide_seconds"];

/// One run's sample streams: seed `seed`, passes `first..end`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Streams {
    pub seed: u64,
    pub first: u64,
    pub end: u64,
}

impl Streams {
    /// Whether the two draw a common stream (the same seed and intersecting pass ranges).
    pub fn overlaps(&self, o: &Streams) -> bool {
        self.seed == o.seed && self.first < o.end && o.first < self.end
    }
}

impl fmt::Display for Streams {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}..{}", self.seed, self.first, self.end)
    }
}

/// The `streams` attribute: runs joined by commas.
pub fn format_streams(runs: &[Streams]) -> String {
    let all: Vec<String> = runs.iter().map(Streams::to_string).collect();
    all.join(",")
}

/// Reads [`format_streams`] back; `None` when the text is no such record.
pub fn parse_streams(text: &str) -> Option<Vec<Streams>> {
    let one = |run: &str| {
        let (seed, range) = run.trim().split_once(':')?;
        let (first, end) = range.split_once("..")?;
        let s = Streams {
            seed: seed.parse().ok()?,
            first: first.parse().ok()?,
            end: end.parse().ok()?,
        };
        (s.first <= s.end).then_some(s)
    };
    if text.trim().is_empty() {
        return Some(Vec::new());
    }
    text.split(',').map(one).collect()
}

/// Whether `spp` samples per pixel can come from the passes `runs` drew: every pass adds
/// between 1 (a pass of a timed render, or the last of a target) and
/// [`super::plan::PASS_SPP`] samples, so a damaged or forged count outside that range
/// would weight an image wrongly in a merge.
pub fn spp_fits_streams(spp: u64, runs: &[Streams]) -> bool {
    let passes = pass_count(runs);
    let most = passes.saturating_mul(super::plan::PASS_SPP as u64);
    (passes..=most).contains(&spp)
}

/// The number of passes `runs` drew (saturating: the ranges of a forged record may add up
/// beyond `u64`).
pub fn pass_count(runs: &[Streams]) -> u64 {
    runs.iter()
        .fold(0u64, |n, r| n.saturating_add(r.end - r.first))
}

/// Sorted runs, the adjacent ranges of one seed joined (the parts of a run make the run).
pub fn joined(mut runs: Vec<Streams>) -> Vec<Streams> {
    runs.sort();
    let mut out: Vec<Streams> = Vec::with_capacity(runs.len());
    for r in runs {
        match out.last_mut() {
            Some(last) if last.seed == r.seed && last.end == r.first => last.end = r.end,
            _ => out.push(r),
        }
    }
    out
}

/// One render a merged file was made of.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Source {
    /// The file as `merge` was given it (`m.exr > a.exr` for a source of a merged input).
    pub file: String,
    pub spp: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    pub streams: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub complete: Option<bool>,
}

/// The `sources` attribute: a TOML array of tables, one `[[source]]` per render.
#[derive(Serialize, Deserialize, Default)]
struct Sources {
    #[serde(default)]
    source: Vec<Source>,
}

/// An attribute that is present but is not the record it names.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: the attribute `{key}` is not a valid record ({value:?})")]
pub struct BadRecord {
    pub file: String,
    pub key: &'static str,
    pub value: String,
}

/// What an image file says about itself.
#[derive(Clone, Debug, PartialEq)]
pub struct Provenance {
    pub file: String,
    pub scene_hash: Option<String>,
    /// `scene_inputs`: the files the scene read, each with the hash of its bytes.
    pub inputs: Option<Vec<(String, u64)>>,
    pub integrator: Option<String>,
    /// `render_options` without the sample count and the seed, flattened to `key = value`.
    pub settings: Option<Vec<(String, String)>>,
    pub streams: Option<Vec<Streams>>,
    pub spp: Option<u64>,
    pub seconds: Option<f64>,
    pub complete: Option<bool>,
    /// The renders it is made of: its own `sources`, or itself.
    pub sources: Vec<Source>,
    /// What `merge --force` let through into it (`merge_forced`, one line each).
    pub forced: Vec<String>,
    /// The shard of a render it is (`render --shard`), when it is one.
    pub shard: Option<ShardRecord>,
}

/// A shard's record: which shard, and the whole render's spp and seed (`shard`, `shard_spp`,
/// `shard_seed`), which the shards of one render share.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShardRecord {
    pub shard: Shard,
    pub spp: u32,
    pub seed: u64,
}

/// Why `merge` refuses a set of inputs (each one, unless `--force`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Conflict {
    #[error("{0} is given twice")]
    SameFile(String),
    #[error("{file} records no `{key}`, so where its samples come from cannot be checked")]
    Unrecorded { file: String, key: &'static str },
    #[error("{a} and {b} are renders of different scene files (scene_hash {ha} and {hb})")]
    Scene {
        a: String,
        b: String,
        ha: String,
        hb: String,
    },
    #[error(
        "{a} and {b} are renders of a scene whose file {file} differs (its hash {ha} and {hb})"
    )]
    Input {
        a: String,
        b: String,
        file: String,
        ha: String,
        hb: String,
    },
    #[error("{a} and {b} were rendered by different integrators ({ia} and {ib})")]
    Integrator {
        a: String,
        b: String,
        ia: String,
        ib: String,
    },
    #[error("{a} and {b} were rendered with different settings: {what}")]
    Settings { a: String, b: String, what: String },
    #[error(
        "the shards of the {integrator} render of {spp} spp with seed {seed} are incomplete, \
         missing: {}; render each with --shard I/N",
        .missing.join(", ")
    )]
    MissingShards {
        integrator: String,
        spp: u32,
        seed: u64,
        missing: Vec<String>,
    },
    #[error(
        "{a} and {b} hold the same samples (seed {seed}, passes {ra} and {rb}): they are not \
         independent renders (render one again with another --seed)"
    )]
    Overlap {
        a: String,
        b: String,
        seed: u64,
        ra: String,
        rb: String,
    },
}

/// Why `merge` stops.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProvenanceError {
    #[error(transparent)]
    BadRecord(#[from] BadRecord),
    #[error(
        "merge refuses these inputs (--force merges them anyway):\n  {}",
        lines(.0, "\n  ")
    )]
    Refused(Vec<Conflict>),
}

fn lines(conflicts: &[Conflict], sep: &str) -> String {
    let all: Vec<String> = conflicts.iter().map(Conflict::to_string).collect();
    all.join(sep)
}

/// An attribute parsed as `T`: `None` when absent, an error when present and not a `T`.
fn field<T: std::str::FromStr>(
    file: &str,
    meta: &ImageMeta,
    key: &'static str,
) -> Result<Option<T>, BadRecord> {
    let Some(text) = meta.get(key) else {
        return Ok(None);
    };
    text.trim().parse().map(Some).map_err(|_| BadRecord {
        file: file.to_string(),
        key,
        value: text.to_string(),
    })
}

/// The shard record of an image (`None` when it is no shard); an error when `shard` is present
/// and it or its companions are not a record.
fn shard_record(file: &str, meta: &ImageMeta) -> Result<Option<ShardRecord>, BadRecord> {
    let Some(text) = meta.get("shard") else {
        return Ok(None);
    };
    let bad = |key, value: &str| BadRecord {
        file: file.to_string(),
        key,
        value: value.to_string(),
    };
    let shard = Shard::parse(text).map_err(|_| bad("shard", text))?;
    let spp = field(file, meta, "shard_spp")?.ok_or_else(|| bad("shard_spp", ""))?;
    let seed = field(file, meta, "shard_seed")?.ok_or_else(|| bad("shard_seed", ""))?;
    Ok(Some(ShardRecord { shard, spp, seed }))
}

/// The `[render]` table of `render_options` without what differs between independent parts
/// of one render (`spp`, `seed`) and what is compared apart (`integrator`), flattened.
fn settings_of(render_options: &str) -> Option<Vec<(String, String)>> {
    fn flatten(prefix: &str, t: &toml::Table, out: &mut Vec<(String, String)>) {
        for (k, v) in t {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                toml::Value::Table(inner) => flatten(&key, inner, out),
                v => out.push((key, v.to_string())),
            }
        }
    }
    let table: toml::Table = render_options.parse().ok()?;
    let mut out = Vec::new();
    if let Some(toml::Value::Table(render)) = table.get("render") {
        flatten("", render, &mut out);
    }
    out.retain(|(k, _)| !matches!(k.as_str(), "spp" | "seed" | "integrator"));
    out.sort();
    Some(out)
}

impl Provenance {
    /// The record of the image `file` with attributes `meta`.
    pub fn read(file: &str, meta: &ImageMeta) -> Result<Self, BadRecord> {
        let bad = |key, value: &str| BadRecord {
            file: file.to_string(),
            key,
            value: value.to_string(),
        };
        let streams = match meta.get("streams") {
            Some(t) => Some(parse_streams(t).ok_or_else(|| bad("streams", t))?),
            None => None,
        };
        let settings = match meta.get("render_options") {
            Some(t) => Some(settings_of(t).ok_or_else(|| bad("render_options", t))?),
            None => None,
        };
        let mut p = Provenance {
            file: file.to_string(),
            scene_hash: meta.get("scene_hash").map(str::to_string),
            inputs: match meta.get("scene_inputs") {
                Some(t) => Some(parse_inputs(t).ok_or_else(|| bad("scene_inputs", t))?),
                None => None,
            },
            integrator: meta.get("integrator").map(str::to_string),
            settings,
            streams,
            spp: field(file, meta, "spp")?,
            seconds: field(file, meta, "seconds")?,
            complete: field(file, meta, "complete")?,
            sources: Vec::new(),
            forced: meta
                .get("merge_forced")
                .map_or(Vec::new(), |t| t.lines().map(str::to_string).collect()),
            shard: shard_record(file, meta)?,
        };
        p.sources = match meta.get("sources") {
            Some(t) => {
                let s: Sources = toml::from_str(t).map_err(|_| bad("sources", t))?;
                let via = |s: Source| Source {
                    file: format!("{file} > {}", s.file),
                    ..s
                };
                s.source.into_iter().map(via).collect()
            }
            None => vec![p.as_source()],
        };
        Ok(p)
    }

    fn as_source(&self) -> Source {
        Source {
            file: self.file.clone(),
            spp: self.spp.unwrap_or(0),
            seconds: self.seconds,
            streams: self
                .streams
                .as_deref()
                .map_or("unrecorded".into(), format_streams),
            complete: self.complete,
        }
    }
}

/// What `merge` must refuse in `inputs` (empty: they are independent estimates of one image):
/// a missing record, another scene, integrator or settings than the first input's, and any two
/// inputs that hold the same samples.
// ANCHOR: conflicts
pub fn conflicts(inputs: &[Provenance]) -> Vec<Conflict> {
    let mut out = Vec::new();
    for p in inputs {
        let missing = [
            ("scene_hash", p.scene_hash.is_none()),
            ("integrator", p.integrator.is_none()),
            ("render_options", p.settings.is_none()),
            ("streams", p.streams.is_none()),
        ];
        for (key, _) in missing.into_iter().filter(|m| m.1) {
            let file = p.file.clone();
            out.push(Conflict::Unrecorded { file, key });
        }
    }
    if let Some((first, rest)) = inputs.split_first() {
        for p in rest {
            out.extend(differences(first, p));
        }
    }
    for (i, a) in inputs.iter().enumerate() {
        for b in &inputs[i + 1..] {
            out.extend(overlap(a, b));
        }
    }
    out.extend(missing_shards(inputs));
    out
}
// ANCHOR_END: conflicts

/// The shards missing from the renders the inputs hold shards of: per render (integrator,
/// shard count, spp, seed), the shard numbers not given, as ranges between the given ones (a
/// render of a billion shards costs what its inputs cost, not a billion entries), each single
/// missing shard with what it holds, at most [`MAX_LISTED_GAPS`] ranges named.
// ANCHOR: missing_shards
fn missing_shards(inputs: &[Provenance]) -> Vec<Conflict> {
    let mut renders: Vec<(String, u32, u32, u64)> = inputs
        .iter()
        .filter_map(|p| {
            let s = p.shard?;
            let integrator = p.integrator.clone().unwrap_or_default();
            Some((integrator, s.shard.count, s.spp, s.seed))
        })
        .collect();
    renders.sort();
    renders.dedup();
    let mut out = Vec::new();
    for (integrator, count, spp, seed) in renders {
        let mut given: Vec<u32> = inputs
            .iter()
            .filter(|p| p.integrator.as_deref() == Some(integrator.as_str()))
            .filter_map(|p| p.shard)
            .filter(|s| (s.shard.count, s.spp, s.seed) == (count, spp, seed))
            .map(|s| s.shard.index)
            .collect();
        given.sort_unstable();
        given.dedup();
        let gaps = gaps(&given, count);
        if gaps.is_empty() {
            continue;
        }
        let mut missing: Vec<String> = gaps
            .iter()
            .take(MAX_LISTED_GAPS)
            .map(|&(a, b)| match a == b {
                true => Shard { index: a, count }.describe(spp, seed, integrator == "mlt"),
                false => format!("{a}/{count} to {b}/{count} ({} shards)", b - a + 1),
            })
            .collect();
        if gaps.len() > MAX_LISTED_GAPS {
            missing.push(format!("and {} more ranges", gaps.len() - MAX_LISTED_GAPS));
        }
        out.push(Conflict::MissingShards {
            integrator,
            spp,
            seed,
            missing,
        });
    }
    out
}

/// The most ranges of missing shards a refusal names.
pub const MAX_LISTED_GAPS: usize = 8;

/// The ranges of 1..=count that the sorted, distinct indices `given` leave out.
fn gaps(given: &[u32], count: u32) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    let mut next = 1u64;
    let end = count as u64 + 1;
    for i in given.iter().map(|&i| (i as u64).min(end)).chain([end]) {
        if i > next {
            out.push((next as u32, (i - 1) as u32));
        }
        next = next.max(i + 1);
    }
    out
}
// ANCHOR_END: missing_shards

/// The EXR attribute `scene_inputs`: `name=hash` per file the scene read, one per line (no
/// line when it read none).
pub fn format_inputs(inputs: &[(String, u64)]) -> String {
    let lines: Vec<String> = inputs
        .iter()
        .map(|(n, h)| format!("{n}={h:016x}"))
        .collect();
    lines.join("\n")
}

/// Reads [`format_inputs`] back; None where a line is not `name=hash`.
fn parse_inputs(text: &str) -> Option<Vec<(String, u64)>> {
    text.lines()
        .filter(|l| !l.is_empty())
        .map(|l| {
            let (name, hash) = l.rsplit_once('=')?;
            Some((name.to_string(), u64::from_str_radix(hash, 16).ok()?))
        })
        .collect()
}

/// The first file whose content differs between two lists of a scene's inputs (sorted by
/// name), with its hash in each (`absent` where a list lacks it).
pub fn changed_input(a: &[(String, u64)], b: &[(String, u64)]) -> Option<(String, String, String)> {
    let hash = |l: &[(String, u64)], f: &str| {
        l.iter()
            .find(|(n, _)| n == f)
            .map_or("absent".to_string(), |(_, h)| format!("{h:016x}"))
    };
    a.iter()
        .chain(b)
        .map(|(f, _)| f)
        .find(|f| hash(a, f) != hash(b, f))
        .map(|f| (f.clone(), hash(a, f), hash(b, f)))
}

/// What makes `b` an estimate of another image than `a`.
fn differences(a: &Provenance, b: &Provenance) -> Vec<Conflict> {
    let (fa, fb) = (a.file.clone(), b.file.clone());
    let mut out = Vec::new();
    if let (Some(ha), Some(hb)) = (&a.scene_hash, &b.scene_hash) {
        if ha != hb {
            let (ha, hb) = (ha.clone(), hb.clone());
            out.push(Conflict::Scene {
                a: fa.clone(),
                b: fb.clone(),
                ha,
                hb,
            });
        }
    }
    let inputs = (a.inputs.as_deref(), b.inputs.as_deref());
    if let (Some(ia), Some(ib)) = inputs {
        if let Some((file, ha, hb)) = changed_input(ia, ib) {
            out.push(Conflict::Input {
                a: fa.clone(),
                b: fb.clone(),
                file,
                ha,
                hb,
            });
        }
    }
    if let (Some(ia), Some(ib)) = (&a.integrator, &b.integrator) {
        if ia != ib {
            let (ia, ib) = (ia.clone(), ib.clone());
            out.push(Conflict::Integrator {
                a: fa.clone(),
                b: fb.clone(),
                ia,
                ib,
            });
        }
    }
    if let (Some(sa), Some(sb)) = (&a.settings, &b.settings) {
        if sa != sb {
            let what = settings_difference(sa, sb);
            out.push(Conflict::Settings { a: fa, b: fb, what });
        }
    }
    out
}

/// The keys whose values differ, `key: A and B` (`not given` where one has no value).
fn settings_difference(a: &[(String, String)], b: &[(String, String)]) -> String {
    let get = |s: &[(String, String)], k: &str| {
        s.iter()
            .find(|(key, _)| key == k)
            .map_or("not given".to_string(), |(_, v)| v.clone())
    };
    let mut keys: Vec<&str> = a.iter().chain(b).map(|(k, _)| k.as_str()).collect();
    keys.sort();
    keys.dedup();
    let diff: Vec<String> = keys
        .into_iter()
        .filter(|k| get(a, k) != get(b, k))
        .map(|k| format!("{k}: {} and {}", get(a, k), get(b, k)))
        .collect();
    diff.join("; ")
}

/// The first pair of runs of `a` and `b` that hold the same samples.
fn overlap(a: &Provenance, b: &Provenance) -> Option<Conflict> {
    let (ra, rb) = (a.streams.as_deref()?, b.streams.as_deref()?);
    let (x, y) = ra
        .iter()
        .flat_map(|x| rb.iter().map(move |y| (x, y)))
        .find(|(x, y)| x.overlaps(y))?;
    Some(Conflict::Overlap {
        a: a.file.clone(),
        b: b.file.clone(),
        seed: x.seed,
        ra: format!("{}..{}", x.first, x.end),
        rb: format!("{}..{}", y.first, y.end),
    })
}

/// The record of the merge of `inputs` (the first's attributes `first`): the first's scene,
/// integrator and settings; the sums of the sample counts and seconds; every input's seed and
/// streams; every source; and what `--force` let through (`forced`).
pub fn merged_record(inputs: &[Provenance], first: &ImageMeta, forced: &[Conflict]) -> ImageMeta {
    let mut meta = first.clone();
    // what describes one render only
    for key in [
        "spp_target",
        "nan_count",
        "negative_pixels",
        "merged_from",
        "guide_seconds",
        "shard",
        "shard_spp",
        "shard_seed",
    ] {
        meta.attributes.remove(key);
    }
    if let Some(t) = first.get("render_options") {
        meta.set("render_options", without_samples(t));
    }
    let spp: u64 = inputs.iter().filter_map(|p| p.spp).sum();
    let runs: Vec<Streams> = inputs
        .iter()
        .flat_map(|p| p.streams.clone().unwrap_or_default())
        .collect();
    let mut seeds: Vec<u64> = runs.iter().map(|r| r.seed).collect();
    seeds.dedup();
    let seeds: Vec<String> = seeds.iter().map(u64::to_string).collect();
    meta.set("spp", spp)
        .set("seed", seeds.join(","))
        .set("streams", format_streams(&joined(runs)))
        .set("complete", inputs.iter().all(|p| p.complete != Some(false)));
    // the sum only when every input records its time (`--reproducible` renders do not)
    meta.attributes.remove("seconds");
    if let Some(s) = inputs.iter().map(|p| p.seconds).sum::<Option<f64>>() {
        meta.set("seconds", format!("{s:.3}"));
    }
    let source = inputs.iter().flat_map(|p| p.sources.clone()).collect();
    let sources = toml::to_string(&Sources { source }).unwrap_or_else(|e| format!("# {e}"));
    meta.set("sources", sources);
    let mut forced_all: Vec<String> = inputs.iter().flat_map(|p| p.forced.clone()).collect();
    forced_all.extend(forced.iter().map(Conflict::to_string));
    if !forced_all.is_empty() {
        meta.set("merge_forced", forced_all.join("\n"));
    }
    meta
}

/// `render_options` without `spp` and `seed`: a merge is of several.
fn without_samples(render_options: &str) -> String {
    let Ok(mut table) = render_options.parse::<toml::Table>() else {
        return render_options.to_string();
    };
    if let Some(toml::Value::Table(render)) = table.get_mut("render") {
        render.remove("spp");
        render.remove("seed");
    }
    toml::to_string(&table).unwrap_or_else(|_| render_options.to_string())
}
