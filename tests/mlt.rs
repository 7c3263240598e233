//! Metropolis light transport (Pauly, Kollig, Keller 2000 sec. 5; Veach 1997 ch. 11): detailed
//! balance and reversibility of every mutation, each transition density T against the
//! empirical proposal distribution (T integrates to one over the vertex it moves, and the
//! histogram of a 1-D projection matches T integrated by quadrature, chi-square), the chain's
//! distribution over a partition of a small path space against f/b, and the MLT image against
//! BDPT over independent runs, initialization included, for all mutations and for each
//! perturbation paired with the bidirectional mutation.

mod common;

use glam::{Vec2, Vec3};
use pathspace::film::Film;
use pathspace::integrator::mlt::acceptance::acceptance;
use pathspace::integrator::mlt::contribution::{image_contribution, scalar_contribution};
use pathspace::integrator::mlt::init::Bootstrap;
use pathspace::integrator::mlt::mutation::{
    InverseDistance, Mutation, MutationKind, PropagationPerturbation,
};
use pathspace::integrator::mlt::{Chain, Mlt, MltSettings};
use pathspace::math::{Frame, Sampler};
use pathspace::path::{Vertex, VertexKind};
use pathspace::scene::{Scene, SceneSource};

use common::{chi_square_p_value, SIGNIFICANCE};

/// The fog box with a glass ball and a mirror ball in the fog, at 16 x 16 pixels: every
/// mutation type applies to some of its paths.
fn mixed_scene() -> Scene {
    let text = pathspace::scene::FOG_BOX
        .replace("resolution = [256, 256]", "resolution = [16, 16]")
        .replace("[materials.white]", "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n\n[materials.chrome]\ntype = \"mirror\"\n\n[materials.white]")
        + "\n[[shapes]]\ntype = \"sphere\"\ncenter = [-0.45, -0.6, -0.2]\nradius = 0.35\nmaterial = \"glass\"\n\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.5, -0.65, 0.2]\nradius = 0.3\nmaterial = \"chrome\"\n";
    Scene::load(&SceneSource::embedded("mixed", &text)).expect("valid test scene")
}

/// The fog box at `w` x `w` pixels.
fn fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

fn engine(scene: &Scene, weights: [f64; 5], max_depth: Option<u32>, seed: u64) -> Mlt {
    let settings = MltSettings {
        weights,
        bootstrap: 2000,
        chains: 4,
        ..MltSettings::default()
    };
    Mlt::new(scene, settings, seed, max_depth).expect("mlt applies to the scene")
}

/// Test paths x with f(x) > 0: pre-pass paths drawn proportionally to their contribution.
fn test_paths(scene: &Scene, mlt: &Mlt, count: usize, seed: u64) -> Vec<Vec<Vertex>> {
    let boot = Bootstrap::run(scene, &mlt.bdpt, 20_000, seed);
    let mut s = Sampler::new(seed, 99, 0);
    let mut out = Vec::new();
    for _ in 0..count * 4 {
        let Some(c) = boot.select(s.next_f64()) else {
            break;
        };
        if let Some(x) = Bootstrap::path_of(scene, &mlt.bdpt, seed, c) {
            if image_contribution(scene, &x).is_some() {
                out.push(x);
            }
        }
        if out.len() == count {
            break;
        }
    }
    out
}

/// Relative tolerance of the detailed-balance identity (both sides are one min() in f64 of
/// f32-derived factors).
const BALANCE_TOLERANCE: f64 = 1e-9;

#[test]
fn detailed_balance_and_reversibility_of_every_mutation() {
    let scene = mixed_scene();
    let mlt = engine(&scene, [1.0; 5], Some(6), 11);
    let paths = test_paths(&scene, &mlt, 600, 11);
    assert!(paths.len() >= 500, "only {} test paths", paths.len());
    // proposals with f(y) > 0 each type must have produced for the test to mean something
    let minimum = |k: MutationKind| match k {
        MutationKind::MultiChain => 3,
        _ => 50,
    };
    for kind in MutationKind::ALL {
        let m = mlt.mutations.get(kind);
        let mut sampler = Sampler::new(12, kind.index() as u64, 0);
        let (mut checked, mut irreversible) = (0, 0);
        for x in &paths {
            let (fx, _) = image_contribution(&scene, x).unwrap();
            let fx = scalar_contribution(fx) as f64;
            for _ in 0..4 {
                let Some(y) = m.sample(&scene, x, &mut sampler) else {
                    continue;
                };
                let Some((fy, _)) = image_contribution(&scene, &y) else {
                    continue;
                };
                if y.len() == x.len() && y.iter().zip(x).all(|(a, b)| a.p == b.p) {
                    // k_d = k_a = 1 reconnecting the same two vertices: a move to x itself,
                    // which changes nothing whatever alpha is
                    continue;
                }
                let fy = scalar_contribution(fy) as f64;
                let t_xy = m.transition_density(&scene, x, &y);
                let t_yx = m.transition_density(&scene, &y, x);
                assert!(
                    t_xy > 0.0 && t_xy.is_finite(),
                    "{}: T(x -> y) = {t_xy} for a y it proposed",
                    kind.name()
                );
                if t_yx <= 0.0 {
                    // y cannot give x back (only the bidirectional mutation: x's section next
                    // to a specular vertex has no joining edge with two non-specular ends
                    // when seen from y); then alpha must be zero and balance holds as 0 = 0
                    assert_eq!(acceptance(fx, fy, t_xy, t_yx), 0.0);
                    irreversible += 1;
                    continue;
                }
                let lhs = fx * t_xy * acceptance(fx, fy, t_xy, t_yx);
                let rhs = fy * t_yx * acceptance(fy, fx, t_yx, t_xy);
                assert!(
                    (lhs - rhs).abs() <= BALANCE_TOLERANCE * lhs.abs().max(rhs.abs()),
                    "{}: f T alpha {lhs} vs {rhs}",
                    kind.name()
                );
                checked += 1;
            }
        }
        eprintln!(
            "{}: {checked} proposals checked, {irreversible} irreversible",
            kind.name()
        );
        if kind == MutationKind::Bidirectional {
            assert!(
                irreversible * 20 < checked,
                "bidirectional: {irreversible} irreversible"
            );
        } else {
            assert_eq!(
                irreversible,
                0,
                "{}: T(y -> x) = 0 for a y with f(y) > 0",
                kind.name()
            );
        }
        assert!(
            checked >= minimum(kind),
            "{}: only {checked} proposals",
            kind.name()
        );
    }
}

/// Points of the plane through `c` with normal `n` in polar coordinates about `c`: radius
/// bins with log-spaced edges, quadrature in log(rho) and angle.
struct PolarQuadrature {
    edges: Vec<f64>,
    sub: usize,
    angles: usize,
}

impl PolarQuadrature {
    /// Probability per bin of landing at the plane point given by `t(point)` (a density per
    /// area), and the total.
    fn integrate(&self, c: Vec3, n: Vec3, t: &dyn Fn(Vec3) -> f64) -> (Vec<f64>, f64) {
        let f = Frame::from_normal(n);
        let mut bins = vec![0.0; self.edges.len() - 1];
        for (b, w) in bins.iter_mut().enumerate() {
            let (l0, l1) = (self.edges[b].ln(), self.edges[b + 1].ln());
            let dl = (l1 - l0) / self.sub as f64;
            for i in 0..self.sub {
                let rho = (l0 + (i as f64 + 0.5) * dl).exp();
                for a in 0..self.angles {
                    let phi = std::f64::consts::TAU * (a as f64 + 0.5) / self.angles as f64;
                    let p = c + (f.s * phi.cos() as f32 + f.t * phi.sin() as f32) * rho as f32;
                    // dA = rho drho dphi = rho^2 dlog(rho) dphi
                    *w += t(p) * rho * rho * dl * std::f64::consts::TAU / self.angles as f64;
                }
            }
        }
        let total = bins.iter().sum();
        (bins, total)
    }

    fn bin_of(&self, rho: f64) -> Option<usize> {
        (0..self.edges.len() - 1).find(|&b| rho >= self.edges[b] && rho < self.edges[b + 1])
    }
}

fn log_edges(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..=n)
        .map(|i| lo * (hi / lo).powf(i as f64 / n as f64))
        .collect()
}

/// A fog-box path light -> x_1 -> x_2 -> pinhole with x_2 near the middle of the back wall and
/// x_1 on the floor, built by hand, and checked to carry light.
fn back_wall_path(scene: &Scene) -> Vec<Vertex> {
    let x = back_wall_path_unchecked(scene);
    assert!(
        image_contribution(scene, &x).is_some(),
        "the hand-built path carries light"
    );
    x
}

/// [`back_wall_path`] without evaluating its contribution (a test of one mutation then
/// depends on nothing else of MLT).
fn back_wall_path_unchecked(scene: &Scene) -> Vec<Vertex> {
    let light_prim = (0..scene.prims.len())
        .find(|&p| scene.shapes[scene.prim_shape[p] as usize].light.is_some())
        .unwrap() as u32;
    let prim_at = |p: Vec3, n: Vec3| -> u32 {
        (0..scene.prims.len())
            .find(|&i| {
                let shape = &scene.shapes[scene.prim_shape[i] as usize];
                !shape.is_null()
                    && shape.light.is_none()
                    && scene.prims[i]
                        .intersect(&pathspace::geometry::Ray::new(p + n * 0.01, -n), 1.0)
                        .is_some()
            })
            .unwrap() as u32
    };
    let fog = Some(0);
    let l = Vertex::new(
        VertexKind::Light {
            light: 0,
            prim: Some(light_prim),
        },
        Vec3::new(0.05, 0.999, -0.1),
        Vec3::new(0.0, -1.0, 0.0),
        fog,
        fog,
    );
    let floor_p = Vec3::new(0.1, -1.0, 0.0);
    let floor = Vertex::new(
        VertexKind::Surface {
            prim: prim_at(floor_p, Vec3::Y),
        },
        floor_p,
        Vec3::Y,
        fog,
        fog,
    );
    let wall_p = Vec3::new(-0.05, 0.1, -1.0);
    let wall = Vertex::new(
        VertexKind::Surface {
            prim: prim_at(wall_p, Vec3::Z),
        },
        wall_p,
        Vec3::Z,
        fog,
        fog,
    );
    let cam = scene.camera.as_ref().unwrap();
    let eye = Vertex::new(VertexKind::Camera, cam.eye, cam.forward, None, None);
    vec![l, floor, wall, eye]
}

/// Samples of the mutation's moved end vertex (index `i`) binned by distance from the old one,
/// against T integrated over the plane it lies in.
fn check_plane_density(
    scene: &Scene,
    m: &dyn Mutation,
    x: &[Vertex],
    i: usize,
    quad: &PolarQuadrature,
    samples: usize,
    seed: u64,
) {
    let c = x[i].p;
    let n = x[i].n;
    let t = |p: Vec3| {
        let mut y = x.to_vec();
        y[i].p = p;
        m.transition_density(scene, x, &y)
    };
    let (expected_p, total) = quad.integrate(c, n, &t);
    // T is a density over the moved vertex: it integrates to one over where it can land
    assert!(
        (total - 1.0).abs() < 0.01,
        "T integrates to {total} over the plane, not 1"
    );
    let mut counts = vec![0u64; expected_p.len()];
    let mut sampler = Sampler::new(seed, 0, 0);
    // a sample whose angle or offset, measured back from the vertices, rounds out of the
    // range is no proposal (T = 0 there): it may happen, but only at the range's edges
    let mut none = 0;
    for _ in 0..samples {
        let Some(y) = m.sample(scene, x, &mut sampler) else {
            none += 1;
            continue;
        };
        assert!((y[i].p - c).dot(n).abs() < 1e-4, "left the plane");
        if let Some(b) = quad.bin_of((y[i].p - c).length() as f64) {
            counts[b] += 1;
        }
    }
    assert!(
        none * 1000 <= samples,
        "{none} of {samples} moves left the wall"
    );
    let kept = (samples - none) as f64;
    let expected: Vec<f64> = expected_p.iter().map(|p| p * kept).collect();
    let p = chi_square_p_value(&counts, &expected);
    assert!(
        p > SIGNIFICANCE,
        "chi-square p = {p}: {counts:?} vs {expected:?}"
    );
}

#[test]
fn sensor_perturbation_density_matches_its_samples() {
    let scene = fog_box(64);
    let mut mlt = engine(&scene, [1.0; 5], None, 3);
    mlt.mutations.sensor.offset = InverseDistance::new(0.1, 4.0).unwrap();
    let x = back_wall_path(&scene);
    // one pixel is ~0.056 at the back wall: 0.1 .. 4 pixels lie well inside these edges
    let quad = PolarQuadrature {
        edges: log_edges(2e-3, 0.4, 10),
        sub: 60,
        angles: 96,
    };
    check_plane_density(&scene, &mlt.mutations.sensor, &x, 2, &quad, 20_000, 4);
}

#[test]
fn light_perturbation_density_matches_its_samples() {
    let scene = fog_box(64);
    let mlt = engine(&scene, [1.0; 5], None, 5);
    let x = back_wall_path(&scene);
    // theta in [1e-4, 0.1] rad from the floor point ~1.1 away
    let quad = PolarQuadrature {
        edges: log_edges(5e-5, 0.4, 12),
        sub: 60,
        angles: 96,
    };
    check_plane_density(&scene, &mlt.mutations.light, &x, 2, &quad, 20_000, 6);
}

#[test]
fn propagation_perturbation_density_matches_its_samples() {
    let scene = fog_box(64);
    // the mutation as `Mlt::new` configures it, built alone
    let (d0, d1) = MltSettings::default().propagation_distance;
    let r = scene.radius.max(f32::MIN_POSITIVE);
    let m = &PropagationPerturbation {
        distance: InverseDistance::new(d0 * r, d1 * r).unwrap(),
    };
    let mut x = back_wall_path_unchecked(&scene);
    // x_2 in the fog, 1.0 from the floor point towards the back wall's old point
    let w = (x[2].p - x[1].p).normalize();
    let p = x[1].p + w * 1.0;
    x[2] = Vertex::new(
        VertexKind::Medium { medium: 0 },
        p,
        Vec3::ZERO,
        Some(0),
        Some(0),
    );
    // T over the line in the measure t^2 dt (dV = t^2 dw dt): signed displacement bins
    let d = m.distance;
    let edges = log_edges(d.min as f64 * 0.5, d.max as f64 * 1.5, 8);
    let steps = 4000;
    let mut expected = vec![0.0; 2 * (edges.len() - 1)];
    let mut total = 0.0;
    for sign in [1.0f64, -1.0] {
        for b in 0..edges.len() - 1 {
            let (l0, l1) = (edges[b].ln(), edges[b + 1].ln());
            let dl = (l1 - l0) / steps as f64;
            for i in 0..steps {
                let s = (l0 + (i as f64 + 0.5) * dl).exp();
                let t = 1.0 + sign * s;
                let mut y = x.clone();
                y[2].p = x[1].p + w * t as f32;
                let v = m.transition_density(&scene, &x, &y) * t * t * s * dl;
                expected[b + if sign > 0.0 { 0 } else { edges.len() - 1 }] += v;
                total += v;
            }
        }
    }
    assert!((total - 1.0).abs() < 0.01, "T integrates to {total}");
    let samples = 20_000;
    let mut counts = vec![0u64; expected.len()];
    let mut sampler = Sampler::new(8, 0, 0);
    for _ in 0..samples {
        let y = m
            .sample(&scene, &x, &mut sampler)
            .expect("stays in the fog");
        let t = (y[2].p - x[1].p).length() as f64;
        let s = t - 1.0;
        let b = (0..edges.len() - 1)
            .find(|&b| s.abs() >= edges[b] && s.abs() < edges[b + 1])
            .expect("displacement in range");
        counts[b + if s > 0.0 { 0 } else { edges.len() - 1 }] += 1;
    }
    let expected: Vec<f64> = expected.iter().map(|p| p * samples as f64).collect();
    let p = chi_square_p_value(&counts, &expected);
    assert!(
        p > SIGNIFICANCE,
        "chi-square p = {p}: {counts:?} vs {expected:?}"
    );
}

/// The cell of a path of the 4 x 4, one-bounce fog box: pixel, and the light seen directly
/// (k = 1), x_1 on a surface, or x_1 in the fog.
fn cell(x: &[Vertex], raster: Vec2) -> usize {
    let pixel = (raster.y.min(3.999) as usize) * 4 + raster.x.min(3.999) as usize;
    let kind = if x.len() == 2 {
        0
    } else if x[1].is_medium() {
        2
    } else {
        1
    };
    pixel * 3 + kind
}
const CELLS: usize = 48;

#[test]
fn chain_distribution_matches_f_over_b_on_a_small_path_space() {
    // paths light -> (x_1 ->) pinhole only (max_depth 1): 16 pixels x {direct, surface, medium}
    let scene = fog_box(4);
    let mlt = engine(&scene, [1.0, 0.0, 0.0, 0.0, 0.0], Some(1), 21);
    // f/b per cell by an independent estimator: BDPT's strategy (1, 2) alone, f/p
    let mut truth = vec![0.0f64; CELLS];
    let mut s = Sampler::new(22, 0, 0);
    let n_truth = 400_000;
    let cam = scene.camera.as_ref().unwrap();
    let eye = Vertex::new(VertexKind::Camera, cam.eye, cam.forward, None, None);
    let media: Vec<Option<u32>> = mlt.mutations.bidirectional.light_media.clone();
    use pathspace::bsdf::TransportMode;
    use pathspace::integrator::mlt::contribution::singular_densities;
    use pathspace::integrator::mlt::trace::{extend, sample_direction, sample_light_vertex};
    for _ in 0..n_truth {
        let Some(d) = sample_direction(&scene, None, &eye, TransportMode::Radiance, &mut s) else {
            continue;
        };
        let Some(x1) = extend(&scene, &eye, d, &mut s) else {
            continue;
        };
        if let VertexKind::Surface { prim } = x1.kind {
            if let Some(light) = scene.shapes[scene.prim_shape[prim as usize] as usize].light {
                // the light seen directly (k = 1): f / p_E(x_0)
                let mut l = x1;
                l.kind = VertexKind::Light {
                    light,
                    prim: Some(prim),
                };
                let x = vec![l, eye];
                if let Some((f, r)) = image_contribution(&scene, &x) {
                    let p = singular_densities(&scene, &x).eye[0] as f64;
                    truth[cell(&x, r)] += scalar_contribution(f) as f64 / p;
                }
            }
        }
        let Some(l) = sample_light_vertex(&scene, &media, &mut s) else {
            continue;
        };
        let x = vec![l, x1, eye];
        let Some((f, r)) = image_contribution(&scene, &x) else {
            continue;
        };
        let dens = singular_densities(&scene, &x);
        let p = dens.light[0] as f64 * dens.eye[1] as f64;
        truth[cell(&x, r)] += scalar_contribution(f) as f64 / p;
    }
    let b: f64 = truth.iter().sum::<f64>() / n_truth as f64;
    let truth: Vec<f64> = truth.iter().map(|t| t / n_truth as f64).collect();
    // the estimators agree on b itself (the pre-pass is BDPT with all strategies)
    let boot = Bootstrap::run(&scene, &mlt.bdpt, 100_000, 25);
    assert!(
        (boot.b - b).abs() < 0.03 * b,
        "b: pre-pass {} vs {b}",
        boot.b
    );
    // chains started all at one path (a wrong start) must forget it
    let start = test_paths(&scene, &mlt, 1, 23).pop().unwrap();
    let chains = 3000;
    let steps = 60;
    let mut counts = vec![0u64; CELLS];
    let mut splats = Vec::new();
    let mut stats = Default::default();
    for c in 0..chains {
        let mut chain = Chain::new(&scene, Sampler::new(24, c, 0), start.clone()).unwrap();
        for _ in 0..steps {
            splats.clear();
            mlt.step(&scene, &mut chain, &mut splats, &mut stats);
        }
        counts[cell(&chain.x, chain.raster)] += 1;
    }
    let expected: Vec<f64> = truth.iter().map(|t| t / b * chains as f64).collect();
    let p = chi_square_p_value(&counts, &expected);
    assert!(
        p > SIGNIFICANCE,
        "chi-square p = {p}: {counts:?} vs {expected:?}"
    );
}

const RUNS: u64 = 16;
const RES: u32 = 8;
const DEPTH: u32 = 3;

fn bdpt_runs(scene: &Scene) -> Vec<Vec<f64>> {
    (0..RUNS)
        .map(|r| {
            let mut rd = pathspace::integrator::Renderer::new(
                scene,
                pathspace::integrator::IntegratorKind::Bdpt,
                1000 + r,
                Some(DEPTH),
            );
            rd.pass(32, &|| {});
            common::quadrant_means(&rd.film.as_ref().unwrap().image())
        })
        .collect()
}

fn mlt_runs(scene: &Scene, weights: [f64; 5]) -> Vec<Vec<f64>> {
    (0..RUNS)
        .map(|r| {
            let mut m = engine(scene, weights, Some(DEPTH), 2000 + r);
            let mut film = Film::new(RES, RES);
            m.run(scene, &mut film, (RES * RES * 128) as u64);
            common::quadrant_means(&film.image())
        })
        .collect()
}

#[test]
fn mlt_image_is_unbiased_against_bdpt_with_every_mutation_set() {
    let scene = fog_box(RES);
    let bdpt = bdpt_runs(&scene);
    common::assert_quadrants_agree("all mutations", &mlt_runs(&scene, [1.0; 5]), &bdpt);
    for kind in [
        MutationKind::Sensor,
        MutationKind::Light,
        MutationKind::Propagation,
    ] {
        let mut w = [0.0; 5];
        w[0] = 1.0;
        w[kind.index()] = 1.0;
        common::assert_quadrants_agree(kind.name(), &mlt_runs(&scene, w), &bdpt);
    }
}

#[test]
fn merge_weights_renders_by_their_sample_counts() {
    use pathspace::cli::merge::merge;
    use pathspace::image_io::{Image, ImageMeta};
    let img = |v: f32| Image {
        width: 2,
        height: 1,
        pixels: vec![Vec3::splat(v); 2],
    };
    let meta = |spp: u64| {
        let mut m = ImageMeta::default();
        m.set("spp", spp);
        m
    };
    let (out, total) = merge(&[
        ("a".into(), img(1.0), meta(1)),
        ("b".into(), img(5.0), meta(3)),
    ])
    .unwrap();
    assert_eq!(total, 4);
    assert_eq!(out.pixels[0], Vec3::splat(4.0)); // (1 * 1 + 3 * 5) / 4
    let err = merge(&[("c".into(), img(1.0), ImageMeta::default())]).unwrap_err();
    assert!(err.contains("spp"), "{err}");
}

#[test]
fn bad_mlt_settings_are_clear_errors() {
    let err = MltSettings::parse_weights("bidirectional=1,lens=3").unwrap_err();
    assert!(err.contains("unknown mutation `lens`"), "{err}");
    let text =
        pathspace::scene::FOG_BOX.replace("seed = 1", "seed = 1\n\n[render.mlt]\nchains = 0");
    let err = Scene::load(&SceneSource::embedded("bad", &text))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("chains"), "{err}");
    let text =
        pathspace::scene::FOG_BOX.replace("seed = 1", "seed = 1\n\n[render.mlt]\nsensor = -1.0");
    assert!(Scene::load(&SceneSource::embedded("bad", &text)).is_err());
}

/// The chain re-evaluates f(y) reusing the edge factors of x for the edges y shares with it
/// (aligned from either end). That must change nothing: for proposals of every mutation type
/// the reused evaluation equals the evaluation from scratch to the bit, and the edges it
/// reports are the path's own.
#[test]
fn reused_edge_factors_give_the_same_contribution_to_the_bit() {
    use pathspace::integrator::mlt::contribution::image_contribution_reusing;
    let scene = mixed_scene();
    let mlt = engine(&scene, [1.0; 5], Some(6), 31);
    let paths = test_paths(&scene, &mlt, 200, 31);
    let mut reused_any = [0usize; 5];
    for kind in MutationKind::ALL {
        let m = mlt.mutations.get(kind);
        let mut sampler = Sampler::new(32, kind.index() as u64, 0);
        for x in &paths {
            let mut ex = Vec::new();
            image_contribution_reusing(&scene, x, None, &mut ex).unwrap();
            let Some(y) = m.sample(&scene, x, &mut sampler) else {
                continue;
            };
            let (mut fresh, mut reused) = (Vec::new(), Vec::new());
            let a = image_contribution_reusing(&scene, &y, None, &mut fresh);
            let b = image_contribution_reusing(&scene, &y, Some((x, &ex)), &mut reused);
            assert_eq!(a, b, "{}: f(y) differs with reuse", kind.name());
            if a.is_some() {
                assert_eq!(fresh, reused, "{}: edge factors differ", kind.name());
                let shared = y
                    .windows(2)
                    .zip(x.windows(2))
                    .any(|(p, q)| p[0].p == q[0].p && p[1].p == q[1].p && p[0].kind == q[0].kind);
                reused_any[kind.index()] += usize::from(shared);
            }
        }
    }
    // perturbations keep the light end: reuse must actually happen for them
    for k in [MutationKind::Sensor, MutationKind::Propagation] {
        assert!(reused_any[k.index()] > 10, "{}: {reused_any:?}", k.name());
    }
}

/// With `b_refine` the estimate of b keeps growing its sample: after N mutations it is exactly
/// the pre-pass estimate over n + round(b_refine N) samples (the same sample indices), and the
/// image's luminance sum is that b (every deposit is b / N).
#[test]
fn refined_b_is_the_prepass_estimate_over_more_samples_and_the_image_sum() {
    let scene = fog_box(8);
    let settings = MltSettings {
        bootstrap: 1000,
        chains: 4,
        b_refine: 0.5,
        ..MltSettings::default()
    };
    let mut mlt = Mlt::new(&scene, settings, 41, None).unwrap();
    let mut film = Film::new(8, 8);
    mlt.run(&scene, &mut film, 64 * 40);
    let more = Bootstrap::run(&scene, &mlt.bdpt, 1000 + 64 * 20, 41).b;
    assert!(
        (mlt.b - more).abs() <= 1e-9 * more,
        "refined b {} vs pre-pass over n + m samples {more}",
        mlt.b
    );
    let prepass = Bootstrap::run(&scene, &mlt.bdpt, 1000, 41).b;
    assert_ne!(mlt.b, prepass, "b was not refined");
    let sum: f64 = film
        .image()
        .pixels
        .iter()
        .map(|p| pathspace::spectrum::luminance(*p) as f64)
        .sum();
    assert!(
        (sum - mlt.b).abs() <= 1e-4 * mlt.b,
        "image sum {sum} vs b {}",
        mlt.b
    );
}

/// Eq. (8) by hand: alpha(x -> y) = min(1, f(y) T(y -> x) / (f(x) T(x -> y))), zero for a
/// proposal that has no contribution or cannot be taken back, and detailed balance
/// f(x) T(x -> y) alpha(x -> y) = f(y) T(y -> x) alpha(y -> x).
#[test]
fn acceptance_is_eq_8() {
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs().max(1.0);
    assert_eq!(acceptance(1.0, 2.0, 1.0, 1.0), 1.0);
    assert!(close(acceptance(2.0, 1.0, 1.0, 1.0), 0.5));
    assert!(close(acceptance(1.0, 1.0, 4.0, 1.0), 0.25));
    assert!(close(
        acceptance(3.0, 2.0, 0.5, 0.25),
        (2.0 * 0.25) / (3.0 * 0.5)
    ));
    assert_eq!(acceptance(1.0, 0.0, 1.0, 1.0), 0.0, "f(y) = 0");
    assert_eq!(acceptance(1.0, 1.0, 1.0, 0.0), 0.0, "T(y -> x) = 0");
    assert_eq!(acceptance(1.0, 1.0, 0.0, 1.0), 0.0, "T(x -> y) = 0");
    assert_eq!(acceptance(0.0, 1.0, 1.0, 1.0), 1.0, "leaving f(x) = 0");
    for (fx, fy, txy, tyx) in [
        (1.0, 2.0, 0.3, 0.7),
        (5.0, 0.1, 2.0, 0.01),
        (0.4, 0.4, 1.0, 3.0),
    ] {
        let lhs = fx * txy * acceptance(fx, fy, txy, tyx);
        let rhs = fy * tyx * acceptance(fy, fx, tyx, txy);
        assert!(close(lhs, rhs), "{lhs} != {rhs}");
    }
}

/// Perturbation sizes with p(D) ~ 1/D on [min, max] (Pauly et al. sec. 5.2.1, Veach eq.
/// 11.11): the pdf is 1 / (D ln(max/min)) inside and 0 outside, it integrates to one, and
/// stratified samples put equal shares into bins of equal width in ln D.
#[test]
fn inverse_distance_follows_one_over_d() {
    let (min, max) = (0.01f32, 1.0f32);
    let d = InverseDistance::new(min, max).unwrap();
    let ln_ratio = ((max / min) as f64).ln();
    for x in [0.02f32, 0.1, 0.5] {
        let expected = 1.0 / (x as f64 * ln_ratio);
        assert!((d.pdf(x) - expected).abs() < 1e-6 * expected, "p({x})");
    }
    assert_eq!(d.pdf(0.001), 0.0);
    assert_eq!(d.pdf(2.0), 0.0);
    // int p(D) dD over [min, max], in s = ln D where dD = D ds
    let n = 10_000;
    let h = ln_ratio / n as f64;
    let integral: f64 = (0..n)
        .map(|i| {
            let dd = ((min as f64).ln() + (i as f64 + 0.5) * h).exp();
            d.pdf(dd as f32) * dd * h
        })
        .sum();
    assert!((integral - 1.0).abs() < 1e-4, "integral {integral}");
    let bins = 10;
    let mut counts = vec![0usize; bins];
    let samples = 100_000;
    for i in 0..samples {
        let x = d.sample((i as f32 + 0.5) / samples as f32);
        assert!((min * 0.999..=max * 1.001).contains(&x), "D = {x}");
        let b = (((x / min) as f64).ln() / ln_ratio * bins as f64) as usize;
        counts[b.min(bins - 1)] += 1;
    }
    for (b, c) in counts.iter().enumerate() {
        let share = *c as f64 / samples as f64;
        assert!((share - 0.1).abs() < 1e-3, "bin {b}: {share}");
    }
}
