//! The memory a render needs, estimated before it starts, so that a resolution or a setting
//! the machine cannot hold is refused with the figure instead of failing (or swapping) hours
//! into the render.
//!
//! The film's part is exact (three `[f64; 3]` buffers per pixel, `Film::new`); the others are
//! per-pixel, per-sample or per-particle sizes of the structures a render holds at its peak:
//! a pass's tile results and splats (kept until the pass is merged, in tile order, for
//! determinism), the output image and its variance with their encoders, the integrator's
//! own structures (declared by its module: SMC's octree, MLT's chains), the guide's particles
//! and maps, the adjoint image's cells. `tests/inputs/bounds.rs` checks the estimate of a moderate render against the peak
//! resident memory the render reports (`--json`'s `memory`).
//! Book: "Measuring a renderer", section "Memory".

use std::mem::size_of;

use super::plan::PASS_SPP;
use crate::enlightened::GuideKind;
use crate::film::FilteredPixel;
use crate::geometry::Primitive;
use crate::integrator::settings::RenderSettings;
use crate::integrator::{Case, IntegratorKind};
use crate::medium::Medium;
use crate::scene::{Environment, Light, Scene};

/// The film: sum, sum of squares and splats per pixel (exactly `Film::new`'s buffers).
pub const FILM_BYTES_PER_PIXEL: u64 = 3 * size_of::<[f64; 3]>() as u64;
/// A pass's tile results: (pixel index, sum, sum of squares) per pixel, held until merged.
const PASS_BYTES_PER_PIXEL: u64 = size_of::<(usize, [f64; 3], [f64; 3])>() as u64;
/// The output: the image and its variance (f32 RGB each) and the EXR and PNG encoders' copies.
const OUTPUT_BYTES_PER_PIXEL: u64 = 48;
/// A guide's particle with its path, region assignment and kd-tree entry (about 750 bytes
/// measured on the fog box with 200,000 particles).
const GUIDE_BYTES_PER_PARTICLE: u64 = 1024;
/// The process itself: code, the scene's parser, the allocator's slack.
const PROCESS_BYTES: u64 = 16 << 20;
/// A worker thread's stack and scratch.
const THREAD_BYTES: u64 = 2 << 20;

/// The estimate, by part (name, bytes), in the order a reader meets them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MemoryEstimate {
    pub parts: Vec<(&'static str, u64)>,
}

impl MemoryEstimate {
    /// The whole estimate in bytes.
    pub fn total(&self) -> u64 {
        self.parts.iter().map(|p| p.1).sum()
    }

    /// `about 1.2 GiB (film 0.5 GiB, pass 0.4 GiB, ...)`, the parts above 1% of the total.
    pub fn describe(&self) -> String {
        let total = self.total();
        let parts: Vec<String> = self
            .parts
            .iter()
            .filter(|p| p.1 * 100 >= total)
            .map(|(name, b)| format!("{name} {}", gib(*b)))
            .collect();
        format!("about {} ({})", gib(total), parts.join(", "))
    }
}

/// Bytes as GiB with a precision that shows small renders too.
pub fn gib(bytes: u64) -> String {
    let g = bytes as f64 / (1u64 << 30) as f64;
    if g >= 10.0 {
        format!("{g:.0} GiB")
    } else if g >= 0.1 {
        format!("{g:.1} GiB")
    } else {
        format!("{:.1} MiB", bytes as f64 / (1u64 << 20) as f64)
    }
}

/// The memory a render of `scene` by `kind` with `settings` on `threads` workers needs.
pub fn estimate(
    scene: &Scene,
    kind: IntegratorKind,
    settings: &RenderSettings,
    threads: usize,
) -> MemoryEstimate {
    let pixels = scene
        .camera
        .as_ref()
        .map_or(0, |c| c.width as u64 * c.height as u64);
    let mut parts = vec![
        ("process", PROCESS_BYTES + threads as u64 * THREAD_BYTES),
        ("scene", scene_bytes(scene)),
        ("film", pixels * film_bytes_per_pixel(scene)),
        ("pass", pixels * pass_bytes_per_pixel(scene, kind, settings)),
        ("image", pixels * OUTPUT_BYTES_PER_PIXEL),
    ];
    parts.extend(integrator_parts(scene, kind, settings));
    MemoryEstimate { parts }
}

/// The film's bytes per pixel: [`FILM_BYTES_PER_PIXEL`], and a filtered pixel's sums with a
/// filter other than the box (`Film::with_filter`).
fn film_bytes_per_pixel(scene: &Scene) -> u64 {
    let filtered = scene.camera.as_ref().is_some_and(|c| !c.filter.is_box());
    FILM_BYTES_PER_PIXEL
        + if filtered {
            size_of::<FilteredPixel>() as u64
        } else {
            0
        }
}

/// Bytes per pixel of one pass's results (tile results and what the integrator's samples
/// deposit: splats, SMC's records).
fn pass_bytes_per_pixel(scene: &Scene, kind: IntegratorKind, settings: &RenderSettings) -> u64 {
    let footprint = kind.facts().pass_footprint(&Case { scene, settings });
    let tiles = if footprint.tiles {
        PASS_BYTES_PER_PIXEL
    } else {
        0
    };
    tiles + PASS_SPP as u64 * footprint.bytes_per_sample
}

/// The preprocessing structures and integrator state of `kind` with `settings`.
fn integrator_parts(
    scene: &Scene,
    kind: IntegratorKind,
    settings: &RenderSettings,
) -> Vec<(&'static str, u64)> {
    let mut parts = kind.facts().memory_parts(&Case { scene, settings });
    let g = &settings.guide;
    if g.kind != GuideKind::Off && kind.takes_guide() {
        let maps = g.regions.regions as u64 * g.cols as u64 * g.rows as u64 * 2 * 4;
        parts.push((
            "guide",
            g.particles as u64 * GUIDE_BYTES_PER_PARTICLE + maps,
        ));
    }
    if settings.adjoint_image && kind.samples_light_starts() {
        let (c, r) = settings.adjoint.resolution;
        // the estimate, the distribution and its per-pass sums (f64 each)
        parts.push(("adjoint", c as u64 * r as u64 * 4 * 8));
    }
    parts
}

/// The scene's grids (their values and majorant blocks), environment map and primitives with
/// their BVHs (`Scene::bvh`, `Scene::boundary_bvh`, `Scene::camera_bvh`), whose bytes are counted as built
/// ([`Bvh::memory_bytes`](crate::geometry::Bvh::memory_bytes)).
fn scene_bytes(scene: &Scene) -> u64 {
    /// A primitive with its shape index and opacity flag.
    const PRIMITIVE_BYTES: u64 = (size_of::<Primitive>() + size_of::<u32>() + 1) as u64;
    let grids: u64 = scene.media.iter().map(Medium::memory_bytes).sum();
    let maps: u64 = scene
        .lights
        .iter()
        .map(|l| match l {
            Light::Environment(Environment::Map(m)) => m.memory_bytes(),
            _ => 0,
        })
        .sum();
    let camera = scene.camera_bvh.as_ref().map_or(0, |b| b.memory_bytes());
    let trees = scene.bvh.memory_bytes() + scene.boundary_bvh.memory_bytes() + camera;
    grids + maps + scene.prims.len() as u64 * PRIMITIVE_BYTES + trees as u64
}

/// The default `--max-memory`: [`MACHINE_SHARE`] of the machine's memory (MemTotal of
/// `/proc/meminfo`), or [`FALLBACK_MAX_MEMORY`] where that file does not exist.
pub fn default_max_memory() -> u64 {
    match machine_memory() {
        Some(total) => (total as f64 * MACHINE_SHARE) as u64,
        None => FALLBACK_MAX_MEMORY,
    }
}

/// The share of the machine's memory a render may use by default (the rest is the system's
/// and other programs').
pub const MACHINE_SHARE: f64 = 0.75;
/// The limit where the machine's memory is unknown (no `/proc/meminfo`).
pub const FALLBACK_MAX_MEMORY: u64 = 8 << 30;

/// MemTotal of `/proc/meminfo` in bytes.
pub fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The process's peak resident memory so far in bytes (getrusage's ru_maxrss, KiB on Linux).
pub fn peak_resident() -> Option<u64> {
    // SAFETY: getrusage writes into the zeroed struct it is given and reads nothing else.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let ok = unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0;
    (ok && usage.ru_maxrss > 0).then(|| usage.ru_maxrss as u64 * 1024)
}

/// A render's memory limit: `max_gib` GiB as given, or by default a share of the machine's
/// memory ([`default_max_memory`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Limit {
    pub max_gib: Option<f64>,
}

/// A render that needs more memory than its limit allows (the estimate described, the limit,
/// where the limit comes from).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("the render needs {needs}, more than --max-memory {limit} ({origin}): lower the resolution or the settings named, or raise --max-memory")]
pub struct MemoryError {
    pub needs: String,
    pub limit: String,
    pub origin: String,
}

impl Limit {
    /// Refuses an `estimate` above the limit, naming both.
    pub fn refuse(&self, estimate: &MemoryEstimate) -> Result<(), MemoryError> {
        let (limit, origin) = match self.max_gib {
            Some(g) => ((g * (1u64 << 30) as f64) as u64, "as given".to_string()),
            None => (
                default_max_memory(),
                match machine_memory() {
                    Some(m) => format!(
                        "the default, {:.0}% of this machine's {}",
                        MACHINE_SHARE * 100.0,
                        gib(m)
                    ),
                    None => "the default where /proc/meminfo is missing".to_string(),
                },
            ),
        };
        if estimate.total() > limit {
            return Err(MemoryError {
                needs: estimate.describe(),
                limit: gib(limit),
                origin,
            });
        }
        Ok(())
    }
}
