//! Checkpoints: what a render needs to continue where it stopped. A checkpoint is written between
//! passes (every `--checkpoint SECONDS`, and when a signal stops the render), so it holds whole
//! passes only: the film's sums (f64, as accumulated), the meters' sums, the counters, the pass
//! index the next pass draws its streams from, and the integrator's own state where it has one
//! (SMC's octree of radiance caches). Every random stream is `Sampler::new(seed, pixel, pass)`,
//! so a render resumed from a checkpoint draws exactly the samples the uninterrupted one would
//! have drawn next, and its image is the same bit for bit.
//!
//! MLT is the exception: its chains (the current path of each, its b estimate, the mutation
//! statistics) are not saved. A resumed MLT render is an independent run with its own seed
//! ([`Checkpoint::resume_seed`]), merged with the saved image by sample count, as `merge` does
//! for independent runs (Pauly et al. 2000 sec. 7: independent chains average).
//! Book: "Measuring a renderer" (interrupted renders, checkpoints).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::provenance::{changed_input, Streams};
// FNV-1a over the payload: a damaged file is refused before its contents are trusted.
use crate::conventions::fnv1a as checksum;
use crate::film::Film;
pub use crate::integrator::IntegratorState;
use crate::integrator::MeterAccum;

/// The first bytes of every checkpoint file, before its format version.
const MAGIC_PREFIX: &[u8] = b"pathspace checkpoint v";
/// The first bytes of a checkpoint file of this format (v4: the integrator's state is bytes
/// the integrator writes and reads).
const MAGIC: &[u8; 24] = b"pathspace checkpoint v4\n";

/// Why a checkpoint cannot be read, written or resumed from.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CheckpointError {
    #[error("cannot read the checkpoint {0}: {1}")]
    Read(String, String),
    /// The checkpoint or the partial image beside it could not be written.
    #[error("cannot write {0}")]
    Write(String),
    #[error("{0} is not a pathspace checkpoint (or was written by another version)")]
    NotACheckpoint(String),
    #[error("the checkpoint {0} is damaged (its checksum does not match): it cannot be resumed")]
    Damaged(String),
    #[error("the checkpoint {file} was written for another render: {what} differs (checkpoint: {saved}, now: {now})")]
    Mismatch {
        file: String,
        what: &'static str,
        saved: String,
        now: String,
    },
    #[error(
        "the checkpoint holds {0} spp, more than the {1} asked for now (give --spp {0} or more)"
    )]
    TooFar(u64, u32),
    /// A checkpoint of another format version (the file, its version).
    #[error("the checkpoint {0} was written by another version of pathspace (checkpoint format {1}, this one reads {2}): render again without --resume")]
    OtherVersion(String, String, String),
    #[error("the checkpoint {0} holds a state the integrator cannot take back: {1}")]
    BadState(String, &'static str),
}

/// What a checkpoint must match to be resumed: the same scene text, camera, integrator,
/// settings (every option but the sample count) and seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Identity {
    /// The FNV-1a hash of the scene file's text, as in the EXR attribute `scene_hash`.
    pub scene_hash: u64,
    /// The files the scene read (meshes, grids, maps), each with the hash of its bytes, as in
    /// the EXR attribute `scene_inputs` ([`crate::scene::SceneSource::inputs`]).
    pub inputs: Vec<(String, u64)>,
    pub integrator: String,
    /// The render's options as JSON without `spp` (a resume may ask for more samples).
    pub options: String,
    pub seed: u64,
    /// The film's size (`--resolution` changes it without changing the scene file).
    pub film: Option<(u32, u32)>,
    pub meters: usize,
}

/// How far the render got: whole passes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Passes done; the next pass draws its streams from this index.
    pub passes: u64,
    /// Samples per pixel (mutations per pixel for MLT) done, counting earlier runs.
    pub spp: u64,
    pub nan_count: u64,
    pub paths: u64,
    /// Seconds spent rendering (passes), counting earlier runs.
    pub seconds: f64,
    /// How many times the render was resumed before this checkpoint.
    pub resumes: u32,
}

/// The image of MLT's earlier runs: the sum over runs of spp_i * I_i, the sum of spp_i, and
/// each run's sample streams (its seed and passes: the render's provenance).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Earlier {
    pub weighted: Vec<[f64; 3]>,
    pub spp: u64,
    pub runs: Vec<Streams>,
}

/// How the command that wrote a checkpoint was called: what `--resume FILE` alone needs to
/// repeat it (the scene file, the flags, the sample target). Not part of the [`Identity`]:
/// the identity says which render the state belongs to, the recipe how to continue it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Recipe {
    /// The scene file as it was given (None: the embedded fog box).
    pub scene: Option<String>,
    /// The same file as an absolute path, for a resume started from another directory.
    pub scene_absolute: Option<String>,
    /// The render options given as flags (the scene's `[render]` keys are in the scene
    /// file), as JSON; `spp` is the target of the whole render.
    pub flags: String,
    /// `--resolution`, `--time`, `--shard I/N` and `--png` as given.
    pub resolution: Option<(u32, u32)>,
    pub time: Option<f64>,
    pub shard: Option<String>,
    pub png: Option<String>,
    /// `--reproducible`: no timings in the EXR header.
    pub reproducible: bool,
    /// `--checkpoint SECONDS`: the resumed render keeps checkpointing at the same interval.
    pub checkpoint: Option<f64>,
    /// `--aovs`: the layers the finished render writes beside its image.
    pub aovs: Option<String>,
}

/// A render's state between two passes.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint {
    pub identity: Identity,
    /// How to continue the render without repeating its command line (None: written by a
    /// caller of the library that gave none).
    pub recipe: Option<Recipe>,
    pub progress: Progress,
    /// The film of the run in progress (for MLT, the runs merged so far are in `earlier`).
    pub film: Option<Film>,
    pub meters: Vec<MeterAccum>,
    pub state: IntegratorState,
    /// MLT: the runs before the one in progress, merged by sample count.
    pub earlier: Option<Earlier>,
}

impl Checkpoint {
    /// The seed of the independent run a resumed MLT render starts (run `resumes` after the
    /// first): the user's seed mixed with the run's number, printed when the run starts, so the
    /// run can be repeated with `--seed`.
    pub fn resume_seed(seed: u64, resumes: u32) -> u64 {
        let mut z = seed ^ (resumes as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// The seed of run `run` of a render seeded `seed`: the seed itself, then
    /// [`Checkpoint::resume_seed`] for each resumed MLT run.
    pub fn run_seed(seed: u64, run: u32) -> u64 {
        match run {
            0 => seed,
            k => Self::resume_seed(seed, k),
        }
    }

    /// The file's bytes: the magic line, the checksum of the payload, the payload (postcard).
    pub fn to_bytes(&self) -> Vec<u8> {
        let payload = postcard::to_stdvec(self).expect("a checkpoint always serializes");
        let mut out = Vec::with_capacity(MAGIC.len() + 8 + payload.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&checksum(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        out
    }

    /// Reads back [`Checkpoint::to_bytes`]; `name` is the file's name for the errors.
    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Self, CheckpointError> {
        let not_one = || CheckpointError::NotACheckpoint(name.to_string());
        if !bytes.starts_with(MAGIC) {
            if let Some(rest) = bytes.strip_prefix(MAGIC_PREFIX) {
                let version = |b: &[u8]| {
                    let line = b.split(|&c| c == b'\n').next().unwrap_or_default();
                    format!("v{}", String::from_utf8_lossy(&line[..line.len().min(16)]))
                };
                let ours = version(&MAGIC[MAGIC_PREFIX.len()..]);
                return Err(CheckpointError::OtherVersion(
                    name.to_string(),
                    version(rest),
                    ours,
                ));
            }
        }
        let rest = bytes.strip_prefix(MAGIC.as_slice()).ok_or_else(not_one)?;
        let (sum, payload) = rest.split_at_checked(8).ok_or_else(not_one)?;
        let sum = u64::from_le_bytes(sum.try_into().map_err(|_| not_one())?);
        if checksum(payload) != sum {
            return Err(CheckpointError::Damaged(name.to_string()));
        }
        let c: Checkpoint = postcard::from_bytes(payload).map_err(|_| not_one())?;
        c.check_shape(name)?;
        Ok(c)
    }

    /// Refuses a state whose arrays do not fit its own header (a lookup must not go out of
    /// bounds on a file that passed its checksum but was written by a bug).
    fn check_shape(&self, name: &str) -> Result<(), CheckpointError> {
        let bad = |why| Err(CheckpointError::BadState(name.to_string(), why));
        if let Some(f) = &self.film {
            let n = f.width as usize * f.height as usize;
            if self.identity.film != Some((f.width, f.height))
                || f.sum.len() != n
                || f.sum_sq.len() != n
                || f.splat.len() != n
                || f.filtered.len() != if f.filter.is_box() { 0 } else { n }
            {
                return bad("the film's arrays do not match its size");
            }
        }
        if self.meters.len() != self.identity.meters {
            return bad("the number of meters does not match");
        }
        if !self.sums_are_finite() {
            return bad("a sum is not finite, or its mean is beyond an image's range");
        }
        Ok(())
    }

    /// Whether every sum the resumed image is made of is finite and gives a mean an image can
    /// hold (a forged or damaged file with a recomputed checksum must not become a NaN or
    /// infinite image).
    fn sums_are_finite(&self) -> bool {
        // sums of squares need only be finite (their mean may exceed f32 where a sample is huge)
        let within = |v: &[[f64; 3]], n: f64| {
            v.iter()
                .flatten()
                .all(|x| x.is_finite() && (x / n).abs() <= f32::MAX as f64)
        };
        let film = self.film.as_ref().is_none_or(|f| {
            let spp = f.spp.max(1) as f64;
            let splats = f.splat_count.max(1) as f64 / f.splat_scale.abs().max(1.0);
            within(&f.sum, spp)
                && within(&f.sum_sq, f64::INFINITY)
                && f.splat_scale.is_finite()
                && within(&f.splat, splats)
                && f.filtered.iter().zip(&f.sum).all(|(p, s)| {
                    let w = [p.weight, p.weight_sq];
                    w.iter()
                        .chain(&p.pass)
                        .chain(&p.cross)
                        .all(|x| x.is_finite())
                        && p.weight >= 0.0
                        && s.iter()
                            .all(|a| (a / p.weight.max(1e-300)).abs() <= f32::MAX as f64)
                })
        });
        let meters = self.meters.iter().all(|m| {
            let n = m.samples.max(1) as f64;
            within(&[m.sum], n) && within(&[m.sum_sq], f64::INFINITY)
        });
        let earlier = self
            .earlier
            .as_ref()
            .is_none_or(|e| within(&e.weighted, e.spp.max(1) as f64));
        film && meters && earlier && self.progress.seconds.is_finite()
    }

    /// Writes the checkpoint through a temporary file renamed over `path`, so a crash (or a
    /// `kill -9`) during the write leaves the previous checkpoint whole.
    pub fn write(&self, path: &Path) -> Result<(), CheckpointError> {
        let bytes = self.to_bytes();
        crate::image_io::write_replacing(path, |tmp| {
            std::fs::write(tmp, &bytes).map_err(|e| crate::image_io::io_err(path, e))
        })
        .map_err(|e| CheckpointError::Write(e.to_string()))
    }

    /// Reads the checkpoint at `path`.
    /// Only a regular file is read, and no more of it than its size: `--resume /dev/zero`
    /// is refused at once instead of reading until memory runs out.
    pub fn read(path: &Path) -> Result<Self, CheckpointError> {
        use std::io::Read;
        let name = path.display().to_string();
        let fail = |e: String| CheckpointError::Read(name.clone(), e);
        let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
        let size = file.metadata().map_err(|e| fail(e.to_string()))?;
        if !size.is_file() {
            return Err(fail("it is not a regular file".into()));
        }
        let mut bytes = Vec::with_capacity(size.len().min(1 << 30) as usize);
        file.take(size.len())
            .read_to_end(&mut bytes)
            .map_err(|e| fail(e.to_string()))?;
        Self::from_bytes(&bytes, &name)
    }

    /// Refuses to resume unless `now` is the render this checkpoint was written for, naming
    /// the first thing that differs.
    pub fn check_identity(&self, now: &Identity, name: &str) -> Result<(), CheckpointError> {
        let saved = &self.identity;
        let differs = |what, a: String, b: String| {
            Err(CheckpointError::Mismatch {
                file: name.to_string(),
                what,
                saved: a,
                now: b,
            })
        };
        if saved.scene_hash != now.scene_hash {
            let hex = |h: u64| format!("{h:016x}");
            return differs("the scene file", hex(saved.scene_hash), hex(now.scene_hash));
        }
        if let Some((file, a, b)) = changed_input(&saved.inputs, &now.inputs) {
            return Err(CheckpointError::Mismatch {
                file: name.to_string(),
                what: "a file the scene reads",
                saved: format!("{file} {a}"),
                now: format!("{file} {b}"),
            });
        }
        if saved.integrator != now.integrator {
            return differs(
                "the integrator",
                saved.integrator.clone(),
                now.integrator.clone(),
            );
        }
        if saved.seed != now.seed {
            return differs("the seed", saved.seed.to_string(), now.seed.to_string());
        }
        if saved.film != now.film {
            let size = |f: Option<(u32, u32)>| f.map_or("none".into(), |(w, h)| format!("{w}x{h}"));
            return differs("the resolution", size(saved.film), size(now.film));
        }
        if saved.options != now.options || saved.meters != now.meters {
            return differs(
                "the render options",
                saved.options.clone(),
                now.options.clone(),
            );
        }
        Ok(())
    }
}
