//! Which light paths each integrator's strategies reach, and what each says about the rest
//! (book: "The agreement matrix", "The Neumann series and the path tracer", "Metropolis light
//! transport"):
//!
//! - BDPT's next-event estimation (s = 1) samples its own light vertex, so it is taken however
//!   the light subpath ended;
//! - the path tracer renders the direct image of a point light in view (a Dirac on the film),
//!   exactly the flux BDPT's (1, 1) strategy splats;
//! - MLT's path length law has an unbounded geometric tail without a depth limit;
//! - `integrator::reach` warns where a method cannot sample some paths, and only there.

use crate::common;

use common::stats::Family;
use glam::Vec2;
use pathspace::bidir::WalkLimits;
use pathspace::integrator::bdpt::{Bdpt, Scratch, Strategies};
use pathspace::integrator::mlt::mutation::Bidirectional;
use pathspace::integrator::reach::unreachable_paths;
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::math::Sampler;
use pathspace::scene::{Scene, SceneSource, FOG_BOX};

fn fog_box(w: u32) -> Scene {
    let text = FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap()
}

/// With an empty light subpath (a walk that ended before its first vertex), `combine` still
/// takes s = 1: its estimate equals the one with a full light subpath restricted to the
/// strategies that do not use the light subpath (s = 0 and s = 1), sample by sample.
#[test]
fn next_event_estimation_does_not_need_the_light_subpath() {
    let scene = fog_box(8);
    let all = Bdpt::new(&pathspace::path::PLAIN, Some(3), Strategies::All);
    let mut scratch = Scratch::default();
    let mut nonzero = 0;
    for i in 0..2000u64 {
        let raster = Vec2::new((i % 8) as f32 + 0.5, ((i / 8) % 8) as f32 + 0.5);
        let mut s = Sampler::new(17, i, 0);
        all.camera_subpath(&scene, raster, WalkLimits::BDPT, &mut s, &mut scratch.eye);
        scratch.light.clear();
        let mut splats = Vec::new();
        let empty = all.combine(
            &scene,
            &mut scratch,
            &mut Sampler::new(18, i, 0),
            &mut splats,
        );
        // the same strategies one by one with the same random numbers
        let mut s2 = Sampler::new(18, i, 0);
        let mut expected = pathspace::spectrum::Rgb::ZERO;
        for t in 1..=scratch.eye.len() {
            for s_light in 0..=1usize {
                let depth = s_light as i64 + t as i64 - 2;
                if !(0..=3).contains(&depth) {
                    continue;
                }
                if let Some((l, raster)) =
                    all.connect(&scene, &scratch.light, &scratch.eye, s_light, t, &mut s2)
                {
                    if raster.is_none() {
                        expected += l;
                    }
                }
            }
        }
        assert!(
            (empty - expected).abs().max_element() <= 1e-5 * expected.max_element().max(1.0),
            "sample {i}: {empty} vs {expected}"
        );
        if empty.max_element() > 0.0 {
            nonzero += 1;
        }
    }
    // next-event estimation lights most camera vertices of the fog box
    assert!(nonzero > 1000, "only {nonzero} samples carried light");
}

/// A point light of intensity I in vacuum, in view of a w x w pinhole camera at distance d along
/// the optical axis: its direct image is one pixel of value I npix / (d^2 A_film cos^3) (W_e of
/// the pinhole, `Camera::importance`), which the path tracer adds as BDPT's (1, 1) strategy
/// does. Both must give it, and the pixels around it must stay black.
#[test]
fn the_path_tracer_renders_a_point_light_in_view() {
    let text = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [9, 9]

[[lights]]
type = "point"
position = [0.0, 0.0, 0.0]
intensity = 2.0
"#;
    let scene = Scene::load(&SceneSource::embedded("point-in-view", text)).unwrap();
    let cam = scene.camera.as_ref().unwrap();
    let (d, cos) = (3.0f64, 1.0f64);
    let truth = 2.0 * 81.0 / (d * d * cam.film_area() as f64 * cos.powi(3));
    for kind in [
        IntegratorKind::Path,
        IntegratorKind::Smc,
        IntegratorKind::Bdpt,
    ] {
        let mut r = Renderer::new(&scene, kind, 1, None);
        r.pass(4, &|| {});
        let img = r.film.as_ref().unwrap().image();
        let centre = img.get(4, 4).x as f64;
        assert!(
            (centre - truth).abs() <= 1e-4 * truth,
            "{}: the light's pixel is {centre}, expected {truth}",
            kind.name()
        );
        let others: f64 = img.pixels.iter().map(|p| p.x as f64).sum::<f64>() - centre;
        assert_eq!(
            others,
            0.0,
            "{}: light outside the light's pixel",
            kind.name()
        );
    }
}

/// Without a depth limit the bidirectional mutation adds k_a edges with weight 2^-|k_a - k_d| on
/// [lo, infinity): the law sums to one (to rounding), keeps the cap's law when a cap exists, and
/// the sampler follows it (chi-square over k_a).
#[test]
fn the_unbounded_path_length_law_sums_to_one_and_is_sampled() {
    let unbounded = Bidirectional {
        max_vertices: usize::MAX,
    };
    let capped = Bidirectional { max_vertices: 12 };
    for (kd, l, n) in [(1usize, 0i64, 5usize), (3, -1, 6), (6, 2, 9)] {
        let total: f64 = (1..400)
            .map(|ka| unbounded.addition_pmf(ka, kd, l, n))
            .sum();
        assert!(
            (total - 1.0).abs() < 1e-12,
            "k_d = {kd}: the law sums to {total}"
        );
        let capped_total: f64 = (1..400).map(|ka| capped.addition_pmf(ka, kd, l, n)).sum();
        assert!(
            (capped_total - 1.0).abs() < 1e-12,
            "capped law sums to {capped_total}"
        );
        assert_eq!(
            capped.addition_pmf(12 + kd - n + 1, kd, l, n),
            0.0,
            "beyond the cap"
        );
    }
    let mut fam = Family::new("strategies: the unbounded length law is sampled");
    // the mutation draws k_a itself; bin it over many proposals from the fog box
    let scene = fog_box(4);
    let mlt = pathspace::integrator::mlt::Mlt::new(
        &scene,
        &pathspace::path::PLAIN,
        pathspace::integrator::mlt::MltSettings {
            bootstrap: 2000,
            chains: 1,
            ..Default::default()
        },
        1,
        None,
    )
    .unwrap();
    assert_eq!(mlt.mutations.bidirectional.max_vertices, usize::MAX);
    let (kd, l, n) = (2usize, 0i64, 4usize);
    let draws = 200_000u64;
    let mut counts = vec![0u64; 40];
    let mut s = Sampler::new(5, 0, 0);
    for _ in 0..draws {
        let (lo, hi) = unbounded.addition_range(l, kd, n);
        let ka = Bidirectional::sample_addition(s.next_f64(), lo, hi, kd);
        counts[ka.min(39)] += 1;
    }
    let expected: Vec<f64> = (0..40)
        .map(|ka| draws as f64 * unbounded.addition_pmf(ka, kd, l, n))
        .collect();
    fam.chi_square("k_a", &counts, &expected);
    fam.finish();
}

/// The warnings of `integrator::reach` on the scenes that need them, and silence elsewhere.
#[test]
fn reach_warns_exactly_where_paths_are_lost() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/agreement/");
    let load = |f: &str| {
        let text = std::fs::read_to_string(format!("{dir}{f}")).unwrap();
        Scene::load(&SceneSource {
            name: f.into(),
            text,
            base_dir: dir.into(),
            origin: None,
            inputs: Default::default(),
        })
        .unwrap()
    };
    use IntegratorKind::*;
    let cases: [(&str, &[IntegratorKind]); 4] = [
        // a spot light behind glass: the path tracer and SMC; the camera does not see the glass
        ("caustic.toml", &[Path, Smc]),
        // glass and a mirror in view under an area light: light tracing only
        ("specular.toml", &[Light]),
        ("chromatic.toml", &[]),
        ("grid.toml", &[]),
    ];
    for (file, warned) in cases {
        let scene = load(file);
        for kind in IntegratorKind::ALL {
            let w = unreachable_paths(&scene, *kind);
            assert_eq!(
                w.is_some(),
                warned.contains(kind),
                "{file}, {}: {w:?}",
                kind.name()
            );
        }
    }
    // the shipped volume caustic: a spot light focused by glass, glass in view
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/volume-caustic.toml"
    ))
    .unwrap();
    let scene = Scene::load(&SceneSource::embedded("volume-caustic.toml", &text)).unwrap();
    for kind in [Path, Smc, Light] {
        assert!(unreachable_paths(&scene, kind).is_some(), "{}", kind.name());
    }
    for kind in [Bdpt, Mlt] {
        assert!(unreachable_paths(&scene, kind).is_none(), "{}", kind.name());
    }
}
