//! `Path::verify` as an invariant: every density, propagation pdf, throughput and edge factor a
//! sampler caches on its paths equals its recomputation from the vertices (`path::verify`),
//! over many paths of BDPT's camera and light subpaths and their joined full paths, MLT's
//! current paths after mutations, and the guided walks the enlightened particle samplers'
//! guide steers, on the fog box, the cloud, nested media, the volume caustic and mlt-sds.
//! The particle samplers themselves return particles, not paths (they run BDPT's walks, checked
//! here with and without a guide).

use std::sync::Arc;

use glam::Vec2;
use pathspace::bidir::{Bdpt, Strategies, WalkLimits};
use pathspace::enlightened::guide::{build_guide, ParticleSampler};
use pathspace::enlightened::{Enlightened, GuideKind, GuideSettings};
use pathspace::integrator::mlt::contribution::image_contribution;
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::math::Sampler;
use pathspace::medium::heterogeneous::LineIntegral;
use pathspace::path::verify::{deterministic_transmittance, verify_edges};
use pathspace::path::{LocalSampling, Path, Vertex, PLAIN};
use pathspace::scene::{Scene, SceneSource};

/// A scene file at `resolution` x `resolution` pixels (the paths, not the image, matter).
fn load(file: &str, resolution: u32) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let mut source = SceneSource::read(&path).unwrap_or_else(|e| panic!("{e}"));
    source.text = regex_resolution(&source.text, resolution);
    Scene::load(&source).unwrap_or_else(|e| panic!("{e}"))
}

/// `text` with its camera's resolution replaced.
fn regex_resolution(text: &str, w: u32) -> String {
    let mut section = String::new();
    text.lines()
        .map(|l| {
            let t = l.trim_start();
            if t.starts_with('[') {
                section = t.to_string();
            }
            if section == "[camera]" && t.starts_with("resolution") {
                format!("resolution = [{w}, {w}]")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The cloud with delta tracking: its file's random-offset marching samples distances whose
/// density is the marched one, which `free_flight_pdf` replaces by the exact one (a documented
/// DEVIATION of the order of the marching bias), so only tracking caches exact densities.
fn cloud() -> Scene {
    let mut scene = load("scenes/cloud.toml", 8);
    assert_eq!(scene.set_line_integral(LineIntegral::DeltaTracking), 1);
    scene
}

/// The scenes the invariant runs on: homogeneous fog, a heterogeneous cloud, nested media,
/// glass in fog (volume caustic) and specular-diffuse-specular chains.
fn scenes() -> Vec<(&'static str, Scene)> {
    vec![
        ("fog-box", load("scenes/fog-box.toml", 8)),
        ("cloud", cloud()),
        ("nested", load("tests/fixtures/agreement/nested.toml", 8)),
        ("volume-caustic", load("scenes/volume-caustic.toml", 8)),
        ("mlt-sds", load("scenes/mlt-sds.toml", 8)),
    ]
}

/// `eye` reversed and appended to `light[..s]`: the full path of strategy (s, t) before its
/// connection.
fn joined(light: &[Vertex], s: usize, eye: &[Vertex], t: usize) -> Path {
    let mut vertices = light[..s].to_vec();
    vertices.extend(eye[..t].iter().rev());
    Path { vertices }
}

/// Draws `count` light and camera subpaths with `bdpt` (roulette off, so that beta is a
/// function of the vertices) and verifies each subpath and every joined full path; returns
/// how many paths were checked.
fn verify_bdpt(
    name: &str,
    (scene, tech): (&Scene, &dyn LocalSampling),
    count: u32,
    seed: u64,
) -> usize {
    let bdpt = Bdpt::new(tech, Some(8), Strategies::All);
    let no_roulette = WalkLimits {
        roulette: false,
        ..WalkLimits::BDPT
    };
    let beta = deterministic_transmittance(scene);
    let cam = scene.camera.as_ref().expect("a camera");
    let (mut light, mut eye) = (Vec::new(), Vec::new());
    let mut unused = Sampler::new(0, 0, 0);
    let mut checked = 0;
    for i in 0..count {
        let mut sampler = Sampler::new(seed, i as u64, 0);
        bdpt.light_subpath(scene, no_roulette, &mut sampler, &mut light);
        let u = sampler.next_2d();
        let raster = Vec2::new(u.x * cam.width as f32, u.y * cam.height as f32);
        bdpt.camera_subpath(scene, raster, no_roulette, &mut sampler, &mut eye);
        let mut check = |path: Path, s: usize, what: &str| {
            if let Err(m) = path.verify(scene, tech, s, beta, &mut unused) {
                panic!(
                    "{name}, sample {i}, {what} (s = {s}): {m}\n{:#?}",
                    path.vertices
                );
            }
            checked += 1;
        };
        check(
            Path {
                vertices: light.clone(),
            },
            light.len(),
            "light subpath",
        );
        check(joined(&light, 0, &eye, eye.len()), 0, "eye subpath");
        for s in 1..=light.len() {
            for t in 1..=eye.len() {
                check(joined(&light, s, &eye, t), s, "full path");
            }
        }
    }
    checked
}

#[test]
fn bdpt_subpaths_and_full_paths_match_their_recomputation() {
    for (k, (name, scene)) in scenes().iter().enumerate() {
        let n = verify_bdpt(name, (scene, &PLAIN), 1000, 11 + k as u64);
        eprintln!("{name}: {n} paths verified");
        assert!(n > 2000, "{name}: only {n} paths checked");
    }
}

#[test]
fn guided_walks_match_their_recomputation() {
    // the guide built by the Metropolis particle sampler (Kristensen 2010 eq. 5.15), steering
    // every scattering density and sampler of the walks
    let scene = load("scenes/fog-box.toml", 8);
    let mut settings = GuideSettings::for_radius(scene.radius);
    settings.kind = GuideKind::Both;
    settings.sampler = ParticleSampler::Metropolis;
    settings.particles = 4000;
    settings.regions.regions = 16;
    settings.cols = 8;
    settings.rows = 4;
    let technique = Enlightened {
        guide: Some(Arc::new(build_guide(&scene, &PLAIN, settings))),
        adjoint: None,
    };
    let n = verify_bdpt("guided fog-box", (&scene, &technique), 1000, 5);
    eprintln!("guided fog-box: {n} paths verified");
    assert!(n > 2000, "only {n} paths checked");
}

#[test]
fn mlt_current_paths_match_their_recomputation_after_mutations() {
    for (k, (name, scene)) in scenes().iter().enumerate() {
        let settings = MltSettings {
            bootstrap: 2000,
            chains: 4,
            ..MltSettings::default()
        };
        let Ok(mut mlt) = Mlt::new(scene, &PLAIN, settings, 3 + k as u64, Some(8)) else {
            continue;
        };
        mlt.initialize(scene);
        let (mut splats, mut stats) = (Vec::new(), Default::default());
        let mut chains = std::mem::take(&mut mlt.chains);
        for step in 0..1000 {
            for (c, chain) in chains.iter_mut().enumerate() {
                mlt.step(scene, chain, &mut splats, &mut stats);
                splats.clear();
                let path = Path {
                    vertices: chain.x.clone(),
                };
                if let Err(m) = verify_edges(scene, &path, &chain.edges) {
                    panic!("{name}, chain {c}, step {step}: {m}\n{:#?}", path.vertices);
                }
                // f and the pixel, recomputed without reusing any edge (the exact tau makes f
                // a function of the path in the cloud too)
                let (f, raster) = image_contribution(scene, &chain.x).expect("f(x) > 0");
                assert_eq!((f, raster), (chain.f, chain.raster), "{name}, chain {c}");
            }
        }
        assert!(!chains.is_empty(), "{name}: no chain");
        eprintln!(
            "{name}: {} chains verified after each of 1000 steps",
            chains.len()
        );
    }
}
