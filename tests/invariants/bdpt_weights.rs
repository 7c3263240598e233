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

// ---- a volume vertex x0: light subpaths that start in a glowing medium ----

/// A closed room of Lambertian walls filled with glowing fog (L_e,V0 = 0.3), a ceiling light,
/// a meter on the floor and a camera inside: light subpaths start at a volume vertex x0 (by
/// power, about five in six) or on the ceiling light.
const GLOWING_ROOM: &str = r#"
[camera]
type = "pinhole"
eye = [0.0, 0.0, 0.9]
look_at = [0.0, 0.0, 0.0]
fov_deg = 60.0
resolution = [8, 8]
[materials.white]
type = "lambert"
albedo = 0.6
[media.fog]
type = "homogeneous"
sigma_a = 0.3
sigma_s = 0.7
emission = 0.3
phase = { type = "hg", g = 0.4 }
[[shapes]]
type = "box"
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
material = "white"
interior = "fog"
[[shapes]]
type = "quad"
origin = [-0.3, 0.99, -0.3]
u = [0.6, 0.0, 0.0]
v = [0.0, 0.0, 0.6]
emission = 5.0
[[sensors]]
type = "irradiance_meter"
name = "floor"
origin = [-0.2, -0.9, -0.2]
u = [0.0, 0.0, 0.4]
v = [0.4, 0.0, 0.0]
"#;

fn glowing_room() -> Scene {
    Scene::load(&SceneSource::embedded("glowing-room.toml", GLOWING_ROOM)).unwrap()
}

/// The connections' weights with volume starts x0 (s = 0 at an eye collision that collects
/// L_e,V0, light subpaths from x0) are the direct ones, bit for bit.
#[test]
fn connection_weights_with_a_volume_x0_are_the_direct_ones() {
    let checked = weights_match(&glowing_room(), 1500, 8);
    assert!(checked > 5000, "{checked}");
}

/// Random paths whose x0 is a volume vertex (a light subpath's first vertices joined to an eye
/// subpath from the meter): the weights of all strategies (the default balance heuristic) sum
/// to one and each is p_s / sum p_i of the densities recomputed from the geometry (x0 per unit volume
/// from the light side: the media's share of the selection times the point's density; from
/// the eye side: the collision density sigma_t tau over r^2 times the direction's), and the
/// walks' own densities of x0 and its neighbours are those recomputed ones.
#[test]
fn weights_of_paths_from_a_volume_x0_sum_to_one() {
    use pathspace::bidir::{mis_weight_of_path, WalkLimits};
    use pathspace::path::pdf::{densities, strategy_pdf};
    use pathspace::path::{measurement_contribution, Path, VertexKind};
    let scene = glowing_room();
    let b = Bdpt::new(&PLAIN, Some(5), Strategies::All);
    let mut sampler = Sampler::new(3, 1, 0);
    let mut scratch = Scratch::default();
    // surface vertices lift their rays off the surface: distances differ in the last digits
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-2 * a.abs().max(b.abs());
    let (mut checked, mut volume) = (0, 0);
    for i in 0..6000 {
        b.meter_subpath(&scene, 0, WalkLimits::BDPT, &mut sampler, &mut scratch.eye);
        b.light_subpath(&scene, WalkLimits::BDPT, &mut sampler, &mut scratch.light);
        let k = 1 + i % 3;
        if scratch.light.len() < k || scratch.eye.len() < 2 {
            continue;
        }
        let from_volume = matches!(scratch.light[0].kind, VertexKind::Medium { .. });
        let mut verts: Vec<Vertex> = scratch.light[..k].to_vec();
        verts.extend(scratch.eye.iter().rev().copied());
        let path = Path { vertices: verts };
        if measurement_contribution(&scene, &path, &mut sampler) == Rgb::ZERO {
            continue;
        }
        let d = densities(&scene, &PLAIN, &path, &mut sampler);
        // the light walk's cached densities of x0 and x1 are the path's (further vertices may
        // sit next to a surface whose lifted ray origin moves their densities' last digits)
        for (j, lv) in scratch.light[..k.min(2)].iter().enumerate() {
            assert!(
                close(lv.pdf_fwd, d.light[j]),
                "light vertex {j}: {} vs {}",
                lv.pdf_fwd,
                d.light[j]
            );
            if j + 2 < k {
                assert!(
                    close(lv.pdf_rev, d.eye[j]),
                    "light vertex {j} reverse: {} vs {}",
                    lv.pdf_rev,
                    d.eye[j]
                );
            }
        }
        let n = path.vertices.len();
        let p: Vec<f64> = (0..n).map(|s| strategy_pdf(&d, s)).collect();
        let total: f64 = p.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            continue;
        }
        let mut sum = 0.0f64;
        for (s, ps) in p.iter().enumerate() {
            let w = mis_weight_of_path(&b, &scene, &path, s, &d) as f64;
            let direct = ps / total;
            assert!(
                (w - direct).abs() < 1e-3,
                "s = {s}: weight {w}, balance heuristic {direct}"
            );
            sum += w;
        }
        assert!((sum - 1.0).abs() < 1e-3, "weights sum to {sum}");
        checked += 1;
        volume += from_volume as u32;
    }
    assert!(
        checked > 1500 && volume > 1000,
        "{checked} paths, {volume} from a volume x0"
    );
}
