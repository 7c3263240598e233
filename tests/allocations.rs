//! No allocation per sample (ARCHITECTURE.md, "Fast enough to be used"): a counting allocator
//! around the system's, and every integrator's passes on the fog box on one thread, where the
//! allocations of a pass must not grow with its samples. Per-pass, per-tile and per-chunk
//! buffers may allocate; a sample, a path or a mutation may not. The counts are exact (one
//! thread, fixed seed), so the test is deterministic.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

use pathspace::enlightened::{Enlightened, GuideKind, GuideSettings};
use pathspace::integrator::path::DistanceSampling;
use pathspace::integrator::settings::{load, RenderSettings};
use pathspace::integrator::{IntegratorKind, Renderer, Setup};
use pathspace::path::{LocalSampling, PLAIN};
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The film's side: one tile, a pass of 32 spp is 8192 samples (MLT: mutations).
const SIDE: u32 = 16;

/// The allocations of one pass of `spp` samples per pixel.
fn allocations_of(r: &mut Renderer, spp: u32) -> u64 {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    r.pass(spp, &|| {});
    ALLOCATIONS.load(Ordering::Relaxed) - before
}

/// What a pass of 32 spp may allocate beyond a pass of 1 spp: 2 log2(n) for its n samples.
///
/// Without an allocation per sample, the difference has two sources, both logarithmic:
/// - a buffer that a pass fills from empty (a tile's splats and SMC records, the subpaths of
///   a chunk of MLT's BDPT samples that refine b) doubles its capacity once per power of two
///   of its length: 32 times the items are log2(32) = 5 more doublings per buffer;
/// - a buffer kept across samples (a walk's vertices, an MLT chain's proposal, its densities
///   and edge factors) grows only when a path longer than every earlier one comes, and only at
///   a power of two: about ln n records among n draws, and fewer doublings.
///
/// An allocation per sample adds n (8192 here; one per 32 MLT mutations still adds 256), far
/// above 2 log2(n) = 26.
fn allowance(spp: u32) -> u64 {
    let n = (SIDE * SIDE * spp) as f64;
    (2.0 * n.log2()).ceil() as u64
}

/// The fog box at `SIDE` x `SIDE` with its render settings, SMC's octree held fixed (it
/// allocates when it refines: a cost of the structure, bounded by its budget, not of samples).
fn fog_box() -> (Scene, RenderSettings) {
    fog_box_from(FOG_BOX)
}

/// The fog box with its lamp's radiance a checkerboard: a texture read at every light vertex.
const TEXTURED_LAMP: &str = "textured lamp";

fn fog_box_from(text: &str) -> (Scene, RenderSettings) {
    let (mut scene, mut settings) = load(&SceneSource::embedded("fog.toml", text)).unwrap();
    settings.smc.threshold = f64::MAX;
    let cam = scene.camera.take().unwrap();
    scene.camera = cam.with_resolution(SIDE, SIDE);
    (scene, settings)
}

/// The label of the path tracer with `distance = "equiangular-mis"`.
const EQUIANGULAR: &str = "equiangular";

/// Checks one integrator with technique `tech`; `label` names the case. Integrators that refuse
/// the technique are skipped.
fn check(kind: IntegratorKind, tech: &dyn LocalSampling, label: &str) {
    let (scene, mut settings) = if label == TEXTURED_LAMP {
        let lamp = "emission = [10.0, 10.0, 10.0]";
        assert!(FOG_BOX.contains(lamp));
        let textured = r#"emission = { texture = "checkerboard", color0 = 14.0, color1 = 6.0 }"#;
        fog_box_from(&FOG_BOX.replace(lamp, textured))
    } else {
        fog_box()
    };
    if label == EQUIANGULAR {
        settings.distance = DistanceSampling::EquiangularMis;
    }
    let setup = Setup {
        scene: &scene,
        technique: tech,
        settings: &settings,
        seed: 3,
        max_depth: None,
    };
    let Ok(mut r) = Renderer::prepared(kind, &setup) else {
        return;
    };
    // warm-up: the preprocessing (MLT's bootstrap), then buffers kept across samples grow to
    // the lengths of the scene's paths
    allocations_of(&mut r, 1);
    allocations_of(&mut r, 128);
    let one = allocations_of(&mut r, 1);
    let many = allocations_of(&mut r, 32);
    let name = format!("{} {label}", kind.name());
    println!("{name:>17}: 1 spp {one:4}, 32 spp {many:4}");
    assert!(
        many <= one + allowance(32),
        "{name}: a pass of 32 spp allocates {many} times, one of 1 spp {one}: more than the \
         allowance {} of capacity doubling (an allocation per sample?)",
        allowance(32)
    );
}

/// The guide mixtures at every vertex and the adjoint image's light starts, installed as a
/// render session installs them.
fn enlightened() -> Enlightened {
    let (scene, settings) = fog_box();
    let mut tech = Enlightened::default();
    tech.install_adjoint(&scene, &settings.adjoint, 3, None)
        .unwrap();
    let guide = GuideSettings {
        kind: GuideKind::Both,
        ..settings.guide
    };
    tech.install_guide(&scene, &guide, 3).unwrap();
    tech
}

#[test]
fn a_pass_of_more_samples_allocates_no_more_than_a_logarithmic_allowance() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let guided = enlightened();
    pool.install(|| {
        for &kind in IntegratorKind::ALL {
            check(kind, &PLAIN, "plain");
            check(kind, &guided, "enlightened");
            check(kind, &PLAIN, TEXTURED_LAMP);
        }
        check(IntegratorKind::Path, &PLAIN, EQUIANGULAR);
    });
}
