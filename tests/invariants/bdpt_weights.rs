//! BDPT's connections compute the MIS weight's changed densities from values they share
//! (the connection's direction, each vertex's direction to its predecessor, computed once per
//! sample by `Bdpt::combine`): the weight must be the one of the direct computation from the
//! vertices (`Bdpt::mis_weight`) bit for bit, on every strategy of random paths, and `combine`
//! must give what the strategies give one by one (book: "Measuring a renderer", "Where the
//! time goes").

use glam::Vec2;
use pathspace::bidir::{Join, SensorStart};
use pathspace::integrator::bdpt::{Bdpt, Scratch, Strategies};
use pathspace::math::Sampler;
use pathspace::path::{Vertex, PLAIN};
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::Rgb;

fn scene(name: &str, resolution: Option<u32>) -> Scene {
    let path = format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut text = std::fs::read_to_string(&path).unwrap();
    if let Some(w) = resolution {
        let start = text.find("resolution = [").unwrap();
        let end = start + text[start..].find(']').unwrap() + 1;
        text.replace_range(start..end, &format!("resolution = [{w}, {w}]"));
    }
    Scene::load(&SceneSource::embedded(name, &text)).unwrap()
}

fn same_bits(a: Rgb, b: Rgb) -> bool {
    a.to_array()
        .iter()
        .zip(b.to_array())
        .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The sensor start of sample `i`: a pixel of a `w` x `w` camera, or the scene's first meter.
fn start(scene: &Scene, i: u64, w: u32) -> SensorStart {
    if scene.camera.is_some() {
        let w = w as u64;
        SensorStart::Camera(Vec2::new((i % w) as f32 + 0.5, ((i / w) % w) as f32 + 0.5))
    } else {
        SensorStart::Meter(0)
    }
}

/// The connection's two ends as the joined path has them (the sampled one replacing its
/// subpath's end), for recomputing the edge's propagation pdfs.
fn ends<'a>(
    light: &'a [Vertex],
    eye: &'a [Vertex],
    s: usize,
    t: usize,
    sampled: &'a Option<Vertex>,
) -> (&'a Vertex, &'a Vertex) {
    let q = if s == 1 {
        sampled.as_ref().unwrap()
    } else {
        &light[s - 1]
    };
    let p = if t == 1 && s != 1 {
        sampled.as_ref().unwrap()
    } else {
        &eye[t - 1]
    };
    (q, p)
}

/// Every strategy of `n` samples: the weighted contribution equals the unweighted one (the
/// same random numbers, `Strategies::Only`) times the directly computed weight, bit for bit.
/// The scenes' media are homogeneous, so an edge re-evaluated here has the same pdfs.
fn weights_match(scene: &Scene, n: u64, w: u32) -> usize {
    let all = Bdpt::new(&PLAIN, Some(6), Strategies::All);
    let mut scratch = Scratch::default();
    let mut checked = 0;
    for i in 0..n {
        all.sample(
            scene,
            start(scene, i, w),
            &mut Sampler::new(5, i, 0),
            &mut scratch,
        );
        let (light, eye) = (&scratch.light, &scratch.eye);
        for t in 1..=eye.len() {
            for s in 0..=Bdpt::max_light_vertices(scene, light) {
                // s = 1 is left out: its edge starts at the light point the connection drew,
                // which this test does not re-evaluate identically
                if s + t < 2 || s + t - 2 > 6 || s == 1 {
                    continue;
                }
                let weighted =
                    all.connect_sampled(scene, light, eye, s, t, &mut Sampler::new(6, i, 0));
                let only = Bdpt::new(&PLAIN, Some(6), Strategies::Only(s, t));
                let unweighted =
                    only.connect_sampled(scene, light, eye, s, t, &mut Sampler::new(6, i, 0));
                let (Some((lw, _, sampled)), Some((lu, _, _))) = (weighted, unweighted) else {
                    assert!(
                        weighted.is_none() && unweighted.is_none(),
                        "({s}, {t}) sample {i}"
                    );
                    continue;
                };
                let (pdf_qp, pdf_pq) = if s == 0 {
                    (1.0, 1.0)
                } else {
                    let (q, p) = ends(light, eye, s, t, &sampled);
                    let e =
                        scene.edge(q.edge_end(p.p), p.edge_end(q.p), &mut Sampler::new(0, 0, 0));
                    (e.pdf_ab, e.pdf_ba)
                };
                let join = Join {
                    s,
                    t,
                    sampled,
                    pdf_qp,
                    pdf_pq,
                };
                let weight = all.mis_weight(scene, light, eye, join);
                assert!(
                    same_bits(lw, lu * weight),
                    "({s}, {t}) sample {i}: {lw} against {lu} * {weight} = {}",
                    lu * weight
                );
                checked += 1;
            }
        }
    }
    checked
}

#[test]
fn connection_weights_are_the_direct_ones_bit_for_bit() {
    // the fog box (Lambert walls, isotropic fog), rough glass and metal in an HG haze, and a
    // meter in a slab of medium (light tracing's meter connection aside)
    let fog = weights_match(&scene("fog-box.toml", Some(8)), 1500, 8);
    let glossy = weights_match(&scene("glossy-caustic.toml", Some(8)), 1500, 8);
    let slab = weights_match(&scene("slab.toml", None), 1500, 8);
    assert!(
        fog > 5000 && glossy > 2000 && slab > 1000,
        "{fog} {glossy} {slab}"
    );
}

/// `combine`, with its per-vertex values computed once per sample, gives the sum and the
/// splats of the strategies connected one by one from the vertices, bit for bit.
#[test]
fn combine_equals_the_strategies_one_by_one() {
    for (name, res) in [("fog-box.toml", Some(8)), ("slab.toml", None)] {
        let scene = scene(name, res);
        let all = Bdpt::new(&PLAIN, Some(6), Strategies::All);
        let mut scratch = Scratch::default();
        let mut splats = Vec::new();
        for i in 0..1000u64 {
            all.sample(
                &scene,
                start(&scene, i, 8),
                &mut Sampler::new(7, i, 0),
                &mut scratch,
            );
            splats.clear();
            let own = all.combine(
                &scene,
                &mut scratch,
                &mut Sampler::new(8, i, 0),
                &mut splats,
            );
            let mut sampler = Sampler::new(8, i, 0);
            let (mut expected, mut expected_splats) = (Rgb::ZERO, Vec::new());
            let meter = scene.camera.is_none();
            all.for_each_strategy(
                &scene,
                &scratch.light,
                &scratch.eye,
                &mut sampler,
                &mut |_, _, l, r, _| {
                    match r {
                        Some(r) if !meter => expected_splats.push((r, l)),
                        _ => expected += l,
                    }
                    true
                },
            );
            assert!(
                same_bits(own, expected),
                "{name} sample {i}: {own} against {expected}"
            );
            assert_eq!(splats.len(), expected_splats.len());
            for ((ra, la), (rb, lb)) in splats.iter().zip(&expected_splats) {
                assert!(ra == rb && same_bits(*la, *lb), "{name} sample {i}");
            }
        }
    }
}
