//! Path space with media (Pauly, Kollig, Keller 2000, sec. 3-4) and BDPT's multiple importance
//! sampling: the characteristic, the generalized G term, f_j / p against the sampler's own
//! throughput, cached densities against recomputed ones, MIS weights, and every (s, t) strategy
//! alone against the path tracer.

use crate::common;

use common::stats::{assert_significant, p_welch, runs_mean, Family};
use glam::Vec3;
use pathspace::bidir::WalkLimits;
use pathspace::integrator::bdpt::{mis_weight_of_path, Bdpt, MisHeuristic, Scratch, Strategies};
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::math::Sampler;
use pathspace::path::pdf::{densities, strategy_pdf, Densities};
use pathspace::path::{
    characteristic, geometry_term, geometry_term::geometry_term_unoccluded,
    measurement_contribution, Path, Vertex, VertexKind,
};
use pathspace::scene::{Scene, SceneSource};

/// A closed room [-1,1]^3 of Lambertian walls filled with fog (its null boundary coplanar with
/// the walls), a ceiling light and a meter on the floor facing up, inside the fog.
const ROOM: &str = r#"
[render]
meter_samples = 1024
[materials.white]
type = "lambert"
albedo = 0.6
[media.fog]
type = "homogeneous"
sigma_a = 0.3
sigma_s = 0.7
phase = { type = "hg", g = 0.4 }
[[shapes]]
type = "box"
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
material = "null"
interior = "fog"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -1.0]
u = [0.0, 0.0, 2.0]
v = [2.0, 0.0, 0.0]
material = "white"
[[shapes]]
type = "quad"
origin = [-1.0, 1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 0.0, 2.0]
material = "white"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -1.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
material = "white"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, 1.0]
u = [0.0, 2.0, 0.0]
v = [2.0, 0.0, 0.0]
material = "white"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -1.0]
u = [0.0, 2.0, 0.0]
v = [0.0, 0.0, 2.0]
material = "white"
[[shapes]]
type = "quad"
origin = [1.0, -1.0, -1.0]
u = [0.0, 0.0, 2.0]
v = [0.0, 2.0, 0.0]
material = "white"
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

fn room() -> Scene {
    Scene::load(&SceneSource::embedded("room.toml", ROOM)).unwrap()
}

fn v(kind: VertexKind, p: Vec3, n: Vec3) -> Vertex {
    Vertex::new(kind, p, n, None, None)
}

/// Pauly et al. Figure 2: x_0, x_1, x_3 on surfaces and x_2 in the volume: l = 1011b = 11.
#[test]
fn characteristic_of_figure_2_is_eleven() {
    let path = Path {
        vertices: vec![
            v(
                VertexKind::Light {
                    light: 0,
                    prim: Some(0),
                },
                Vec3::ZERO,
                Vec3::Y,
            ),
            v(VertexKind::Surface { prim: 1 }, Vec3::X, Vec3::Y),
            v(
                VertexKind::Medium { medium: 0 },
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::ZERO,
            ),
            v(VertexKind::Camera, Vec3::new(0.0, 2.0, 0.0), -Vec3::Y),
        ],
    };
    let got = characteristic(&path.vertices);
    assert_eq!(
        got, 0b1011,
        "characteristic of Fig. 2 (light, surface, medium, camera): got {got:#b}, expected 0b1011 \
         (bit i for vertex x_i, 1 on surfaces and at the light and camera, 0 in the medium)"
    );
    assert_eq!(path.characteristic(), 11);
    // an all-medium interior and a longer path: the bits follow the vertex index
    let x = &path.vertices;
    let long = [x[0], x[2], x[2], x[1], x[2], x[3]];
    let got = characteristic(&long);
    assert_eq!(
        got, 0b101001,
        "light, medium, medium, surface, medium, camera: got {got:#b}, expected 0b101001"
    );
    assert_eq!(pathspace::path::characteristic::measure_of(11, 2), "dV");
    assert_eq!(pathspace::path::characteristic::measure_of(11, 1), "dA");
}

/// G of two medium vertices is 1/d^2; a surface and a medium vertex, cos/d^2; two surfaces,
/// cos cos / d^2 (sec. 3.2: a medium vertex's "normal" is the edge direction itself). The
/// cosines are absolute values (a surface seen from behind converts densities as one seen from
/// the front: which side scatters is the BSDF's business, not G's); an infinite light's end
/// has no distance factor and no cosine of its own; two coincident points have G = 0 (no
/// direction joins them), never a NaN or an infinity.
#[test]
fn geometry_term_closed_forms() {
    let m = |p: Vec3| v(VertexKind::Medium { medium: 0 }, p, Vec3::ZERO);
    let s = |p: Vec3, n: Vec3| v(VertexKind::Surface { prim: 0 }, p, n);
    let g = |what: &str, x: &Vertex, y: &Vertex, expected: f32| {
        let got = geometry_term_unoccluded(x, y);
        assert!(
            (got - expected).abs() <= 1e-7 * expected.abs().max(1.0),
            "G({what}): got {got}, expected {expected}"
        );
    };
    let a = m(Vec3::ZERO);
    let b = m(Vec3::new(0.0, 0.0, 2.0));
    g("two medium vertices 2 apart", &a, &b, 0.25);
    let c = s(
        Vec3::new(3.0, 0.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0).normalize(),
    );
    // from a at the origin to c at distance 3: the cosine at c is cos 45 degrees
    let expect = std::f32::consts::FRAC_1_SQRT_2 / 9.0;
    g("medium to surface at 45 degrees", &a, &c, expect);
    g("surface to medium (symmetry)", &c, &a, expect);
    let d = s(Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, -1.0, 0.0));
    let e = s(Vec3::ZERO, Vec3::new(0.0, 0.6, 0.8));
    g("two surfaces facing each other", &d, &e, 0.6 / 4.0);
    g("two surfaces, reversed", &e, &d, 0.6 / 4.0);
    // back-facing: the same points with either normal, or both, flipped
    let d_back = s(d.p, -d.n);
    let e_back = s(e.p, -e.n);
    g("back-facing at x", &d_back, &e, 0.6 / 4.0);
    g("back-facing at y", &d, &e_back, 0.6 / 4.0);
    g("back-facing at both ends", &d_back, &e_back, 0.6 / 4.0);
    g("back-facing surface to medium", &s(c.p, -c.n), &a, expect);
    // coincident points: no direction, G = 0
    g("coincident medium vertices", &a, &a, 0.0);
    g("coincident surface vertices", &d, &d, 0.0);
    // an infinite light 2R away in direction w: only the other end's cosine, no 1/d^2
    let light_w = Vec3::new(0.0, 0.6, 0.8);
    let inf = v(
        VertexKind::InfiniteLight {
            light: 0,
            w: light_w,
        },
        light_w * 40.0,
        Vec3::ZERO,
    );
    let floor = s(Vec3::ZERO, Vec3::Z);
    g("infinite light to a floor point", &inf, &floor, 0.8);
    g("floor point to an infinite light", &floor, &inf, 0.8);
    g("infinite light to a medium vertex", &inf, &a, 1.0);
    g("medium vertex to an infinite light", &a, &inf, 1.0);
}

/// Paths sampled by the eye random walk (BSDF / phase sampling and Table 1, the path tracer's
/// walk without light sampling) that end on the light: f_j(x) / p(x) from the path module equals
/// the walk's own throughput times L_e, and the walk's cached densities equal the densities
/// recomputed from the geometry (`Path::verify` in spirit).
#[test]
fn contribution_over_density_equals_walk_throughput() {
    let scene = room();
    // max_depth 2 keeps Russian roulette out (it starts after 3 vertices)
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(2), Strategies::All);
    let mut sampler = Sampler::new(7, 0, 0);
    let mut eye = Vec::new();
    let mut checked = 0;
    for _ in 0..20000 {
        b.meter_subpath(&scene, 0, WalkLimits::BDPT, &mut sampler, &mut eye);
        let last = *eye.last().unwrap();
        let VertexKind::Surface { prim } = last.kind else {
            continue;
        };
        let Some(light) = scene.shapes[scene.prim_shape[prim as usize] as usize].light else {
            continue;
        };
        let le = last.surface_emission(&scene, eye[eye.len() - 2].p);
        if le == Vec3::ZERO {
            continue;
        }
        // the full path x_0 (light) ... x_k (meter)
        let mut verts: Vec<Vertex> = eye.iter().rev().copied().collect();
        verts[0].kind = VertexKind::Light {
            light,
            prim: Some(prim),
        };
        let path = Path { vertices: verts };
        let f = measurement_contribution(&scene, &path, &mut sampler);
        let p: f64 = eye.iter().map(|v| v.pdf_fwd as f64).product();
        let expect = last.beta * le;
        for c in 0..3 {
            let got = f[c] as f64 / p;
            let rel = (got - expect[c] as f64).abs() / (expect[c] as f64).max(1e-12);
            assert!(
                rel < 1e-3,
                "f/p = {got}, walk throughput * Le = {}, path {:?}",
                expect[c],
                path.characteristic()
            );
        }
        // cached densities against recomputed ones
        let d = densities(&scene, &pathspace::path::PLAIN, &path, &mut sampler);
        let n = path.vertices.len();
        for (k, ev) in eye.iter().enumerate() {
            let i = n - 1 - k;
            let rel = (d.eye[i] - ev.pdf_fwd).abs() / ev.pdf_fwd.max(1e-12);
            assert!(
                rel < 1e-3,
                "p_E(x_{i}) = {} but the walk cached {}",
                d.eye[i],
                ev.pdf_fwd
            );
            // the walk set pdf_rev of every vertex that has a scattering successor
            if k + 2 < eye.len() && k > 0 {
                let rel = (d.light[i] - ev.pdf_rev).abs() / ev.pdf_rev.max(1e-12);
                assert!(
                    rel < 1e-3,
                    "p_L(x_{i}) = {} but the walk cached {}",
                    d.light[i],
                    ev.pdf_rev
                );
            }
        }
        checked += 1;
    }
    assert!(checked > 100, "only {checked} walks reached the light");
}

/// The medium around an area light is the one it emits into: two lights on the fog box's open
/// face (z = +1, coplanar with the fog's null boundary), one facing into the box and one facing
/// out, start their subpaths in the fog and in vacuum; the ceiling light hangs in the fog.
#[test]
fn an_area_light_on_a_medium_boundary_starts_in_the_medium_it_faces() {
    let face = |u: [f32; 3], v: [f32; 3]| {
        format!(
            "\n[[shapes]]\ntype = \"quad\"\norigin = [-0.5, -0.5, 1.0]\nu = {u:?}\nv = {v:?}\nemission = [1.0, 1.0, 1.0]\n"
        )
    };
    let inward = face([0.0, 0.5, 0.0], [0.5, 0.0, 0.0]); // u x v = -z
    let outward = face([0.5, 0.0, 0.0], [0.0, 0.5, 0.0]); // u x v = +z
    let text = format!("{}{inward}{outward}", pathspace::scene::FOG_BOX);
    let scene = Scene::load(&SceneSource::embedded("faces.toml", &text)).unwrap();
    assert_eq!(scene.light_media, [Some(0), Some(0), None]);
}

/// The light side of the same identity. x_0 is uniform on the room's only light (a 0.6 x 0.6
/// quad): p_L(x_0) = 1 / 0.36 exactly. For a surface vertex x_1, the throughput the light walk
/// carries there equals L_e(x_0 -> x_1) G tau / (p_L(x_0) p_L(x_1)) with the densities recomputed
/// by `densities`, and the walk's cached p_L(x_1) is the recomputed one. MIS weights are a
/// partition of unity for any consistent densities, so only this pins their values.
#[test]
fn light_subpath_densities_reproduce_its_throughput() {
    let scene = room();
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(2), Strategies::All);
    // the ceiling light hangs inside the fog (medium 0): its subpaths start there
    assert_eq!(scene.light_media, [Some(0)]);
    let mut sampler = Sampler::new(11, 0, 0);
    let mut light = Vec::new();
    let mut checked = 0;
    for _ in 0..4000 {
        b.light_subpath(&scene, WalkLimits::BDPT, &mut sampler, &mut light);
        if light.len() < 2 {
            continue;
        }
        let (x0, x1) = (light[0], light[1]);
        let path = Path {
            vertices: vec![x0, x1],
        };
        let d = densities(&scene, &pathspace::path::PLAIN, &path, &mut sampler);
        let area = 0.6f32 * 0.6;
        assert!(
            (d.light[0] * area - 1.0).abs() < 1e-5 && (x0.pdf_fwd * area - 1.0).abs() < 1e-5,
            "p_L(x_0) = {} (cached {}), 1 / A = {}",
            d.light[0],
            x0.pdf_fwd,
            1.0 / area
        );
        if !matches!(x1.kind, VertexKind::Surface { .. }) {
            continue;
        }
        let rel = (d.light[1] - x1.pdf_fwd).abs() / x1.pdf_fwd.max(1e-12);
        assert!(
            rel < 1e-3,
            "p_L(x_1) = {} but the walk cached {}",
            d.light[1],
            x1.pdf_fwd
        );
        let (g, tau) = geometry_term(&scene, &x0, &x1, &mut sampler);
        let f = x0.emitted(&scene, x1.p) * tau * g;
        let p = d.light[0] as f64 * d.light[1] as f64;
        for c in 0..3 {
            let got = f[c] as f64 / p;
            let rel = (got - x1.beta[c] as f64).abs() / (x1.beta[c] as f64).max(1e-12);
            assert!(
                rel < 1e-3,
                "f / p = {got}, the walk's throughput {}",
                x1.beta[c]
            );
        }
        checked += 1;
    }
    assert!(
        checked > 500,
        "only {checked} light walks reached a surface"
    );
}

/// A spot light's intensity I(c) in a direction of cosine c to its axis: 0 outside the cone
/// (c < cos_total), I inside the falloff (c >= cos_falloff), and I s(x) between, with the
/// smoothstep s(x) = x^2 (3 - 2x) of x = (c - cos_total) / (cos_falloff - cos_total). Its
/// integral 2 pi int_{-1}^{1} I(c) dc is the power `Light::power` states, 2 pi I (1 - (cos_total +
/// cos_falloff) / 2), because int_0^1 s = 1/2 (Simpson's rule integrates the cubic exactly).
#[test]
fn spot_light_intensity_has_its_closed_form_falloff() {
    use pathspace::math::Frame;
    use pathspace::scene::light::emitted_by;
    use pathspace::scene::Light;
    let axis = Vec3::new(0.0, -0.6, 0.8);
    let (cos_total, cos_falloff) = (0.5f32, 0.8f32);
    let spot = Light::Spot {
        position: Vec3::ZERO,
        frame: Frame::from_normal(axis),
        intensity: Vec3::splat(2.0),
        cos_total,
        cos_falloff,
    };
    let frame = Frame::from_normal(axis);
    let at = |c: f32| {
        let s = (1.0 - c * c).max(0.0).sqrt();
        let w = frame.to_world(Vec3::new(s * 0.6, s * 0.8, c));
        emitted_by(&spot, &[], 0, (Vec3::ZERO, Vec3::ZERO), w).x as f64
    };
    let smooth = |x: f64| x * x * (3.0 - 2.0 * x);
    for (c, expect) in [
        (-1.0f32, 0.0),
        (0.2, 0.0),
        (0.499, 0.0),
        (0.5 + 0.3 * 0.25, 2.0 * smooth(0.25)),
        (0.5 + 0.3 * 0.7, 2.0 * smooth(0.7)),
        (0.8, 2.0),
        (1.0, 2.0),
    ] {
        let got = at(c);
        assert!(
            (got - expect).abs() < 1e-5,
            "I({c}) = {got}, closed form {expect}"
        );
    }
    // composite Simpson on [-1, cos_total], [cos_total, cos_falloff], [cos_falloff, 1]
    let simpson = |a: f32, b: f32| {
        let n = 64;
        let h = (b - a) / n as f32;
        (0..=n)
            .map(|i| {
                let w = if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                w * at(a + h * i as f32)
            })
            .sum::<f64>()
            * h as f64
            / 3.0
    };
    // the three pieces, each clear of the kinks at the ends (on one side the integrand is 0)
    let eps = 1e-6;
    let integral = simpson(-1.0, cos_total - eps)
        + simpson(cos_total + eps, cos_falloff - eps)
        + simpson(cos_falloff + eps, 1.0);
    let power = spot.power(1.0) as f64;
    let from_falloff = 2.0 * std::f64::consts::PI * integral;
    assert!(
        (from_falloff - power).abs() < 1e-4 * power,
        "2 pi int I(c) dc = {from_falloff}, Light::power = {power}"
    );
}

/// A path through a mirror: light x_0 on the floor, the mirror ceiling x_1 (a Dirac: its
/// outgoing direction was sampled from the singular lobe), the meter x_2. No strategy can
/// connect at x_1 or end at it, so the only strategy that samples this path, the eye walk that
/// hits the light (s = 0), has MIS weight one exactly: the sum over the other strategies skips
/// every one whose connection touches a Dirac vertex.
#[test]
fn a_path_through_a_mirror_has_one_strategy_of_weight_one() {
    // the mirror and light of the book's mirror-chain figure, a meter on the floor
    let text = format!(
        "{}{}",
        pathspace::figures::MIRROR_OVER_LIGHT,
        r#"
[[sensors]]
type = "irradiance_meter"
name = "floor"
origin = [-0.6, -0.9, -0.1]
u = [0.0, 0.0, 0.2]
v = [0.2, 0.0, 0.0]
"#
    );
    let scene = Scene::load(&SceneSource::embedded("mirror.toml", &text)).unwrap();
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(4), Strategies::All);
    // this light is in vacuum
    assert_eq!(scene.light_media, [None]);
    let x0 = Vertex::new(
        VertexKind::Light {
            light: 0,
            prim: Some(1),
        },
        Vec3::new(0.5, -1.0, 0.0),
        Vec3::Y,
        None,
        None,
    );
    // the reflection point of x_0 towards x_2 (the image of x_2 in the mirror is at y = 2.9)
    let x2p = Vec3::new(-0.5, -0.9, 0.0);
    let along = 2.0 / 3.9;
    let mut x1 = v(
        VertexKind::Surface { prim: 0 },
        Vec3::new(0.5 - along, 1.0, 0.0),
        Vec3::NEG_Y,
    );
    x1.delta = true;
    let x2 = v(VertexKind::Meter { meter: 0 }, x2p, Vec3::Y);
    let path = Path {
        vertices: vec![x0, x1, x2],
    };
    let mut sampler = Sampler::new(1, 0, 0);
    let d = densities(&scene, &pathspace::path::PLAIN, &path, &mut sampler);
    let w = mis_weight_of_path(&b, &scene, &path, 0, &d);
    assert!((w - 1.0).abs() < 1e-6, "w(s = 0) = {w}");
}

/// A Dirac chain between two strategies: light x_0 on the floor, the mirror ceiling x_1, a
/// Lambertian wall x_2, the meter x_3. Two strategies sample this path: the eye walk that hits
/// the light through the mirror (s = 0) and the light walk that reaches x_2 through it and
/// connects to the meter (s = 3). Their densities differ only at the chain's ends: through a
/// mirror the chain's geometry term G_chain(x_0 <-> x_2) is the same both ways, so
/// p_3 / p_0 = p(x_0) (p_e(x_0 -> x_1) / cos_0) / (p(x_2 | x_3) (p_f(x_2 -> x_1) / cos_2)),
/// and with a cosine emitter and a Lambertian wall (each density per projected solid angle
/// 1 / pi) p_3 / p_0 = p(x_0) / p(x_2 | x_3): the power heuristic's weights follow from two
/// densities no Dirac vertex touches (Veach 1997, sec. 10.3.5). Counting the mirror's Dirac
/// density as one per unit area instead leaves d^2 and cosines of the two edges in the ratio.
#[test]
fn a_mirror_chain_weighs_its_two_strategies_by_their_end_densities() {
    // the scene and path the book's figure of the chain draws
    let (scene, path) = pathspace::figures::mirror_chain();
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(4), Strategies::All);
    // x_1 is the mirror point: equal angles with the mirror's normal on both sides
    let v = &path.vertices;
    let (to_0, to_2) = ((v[0].p - v[1].p).normalize(), (v[2].p - v[1].p).normalize());
    assert!(
        (to_0.y - to_2.y).abs() < 1e-6 && v[1].delta,
        "x_1 reflects x_0 to x_2"
    );
    let mut sampler = Sampler::new(1, 0, 0);
    let d = densities(&scene, &pathspace::path::PLAIN, &path, &mut sampler);
    let r = d.light[0] as f64 / d.eye[2] as f64;
    assert_chain_weights(&b, &scene, &path, &d, r);
}

/// The weights of a four-vertex chain's two strategies (s = 0 and s = 3) for the ratio
/// r = p_3 / p_0 of their densities, against `mis_weight_of_path`, by both heuristics:
/// 1 / (1 + r^beta) and r^beta / (1 + r^beta).
fn assert_chain_weights(b: &Bdpt, scene: &Scene, path: &Path, d: &Densities, r: f64) {
    // neither strategy dominates, so a wrong ratio shows in both weights
    assert!((0.2..5.0).contains(&r), "p_3 / p_0 = {r}");
    for (h, beta) in [(MisHeuristic::Balance, 1), (MisHeuristic::Power, 2)] {
        let b = b.clone().with_heuristic(h);
        let rb = r.powi(beta);
        let expected = [1.0 / (1.0 + rb), rb / (1.0 + rb)];
        for (s, want) in [0, 3].into_iter().zip(expected) {
            let w = mis_weight_of_path(&b, scene, path, s, d) as f64;
            assert!(
                (w - want).abs() < 1e-4 * want.max(1e-3),
                "{h:?}: w(s = {s}) = {w}, expected {want} (p_3 / p_0 = {r})"
            );
        }
    }
}

/// The mirror chain with its wall point replaced by a collision x_2 in a fog that fills the
/// room: the ends' projected densities now differ (1/pi at the light, the isotropic phase
/// function's 1/(4 pi) at x_2), and the chain's edges carry propagation pdfs, the one that ends
/// at x_2 with its sigma_t. Then p_3 / p_0 = p(x_0) (1/pi) q(x_0 -> x_1) q(x_1 -> x_2) /
/// (p(x_2 | x_3) (1/(4 pi)) q(x_2 -> x_1) q(x_1 -> x_0)), with the q's from
/// `path::pdf::densities`: a density read as one where a Dirac vertex left none, or a
/// projected density left per unit area, gives other weights.
#[test]
fn a_mirror_chain_in_fog_weighs_its_ends_with_their_propagation_pdfs() {
    let text = format!(
        "{}{}",
        pathspace::figures::MIRROR_OVER_LIGHT,
        r#"
[media.fog]
type = "homogeneous"
sigma_a = 0.2
sigma_s = 0.6
phase = { type = "isotropic" }
[[shapes]]
type = "box"
min = [-2.0, -2.0, -2.0]
max = [2.0, 2.0, 2.0]
material = "null"
interior = "fog"
[[sensors]]
type = "irradiance_meter"
name = "facing the fog"
origin = [-0.5, -0.5, -0.6]
u = [0.0, 0.2, 0.0]
v = [0.2, 0.0, 0.0]
"#
    );
    let scene = Scene::load(&SceneSource::embedded("mirror-fog.toml", &text)).unwrap();
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(4), Strategies::All);
    let fog = |kind, p: Vec3, n| Vertex::new(kind, p, n, Some(0), Some(0));
    let x0 = Vec3::new(0.5, -1.0, 0.0);
    let x2 = Vec3::new(-0.3, -0.2, -0.9);
    let image = Vec3::new(x2.x, 2.0 - x2.y, x2.z);
    let x1 = x0 + (image - x0) * ((1.0 - x0.y) / (image.y - x0.y));
    let mut mirror = fog(VertexKind::Surface { prim: 0 }, x1, Vec3::NEG_Y);
    mirror.delta = true;
    let light = VertexKind::Light {
        light: 0,
        prim: Some(1),
    };
    let path = Path {
        vertices: vec![
            fog(light, x0, Vec3::Y),
            mirror,
            fog(VertexKind::Medium { medium: 0 }, x2, Vec3::ZERO),
            fog(
                VertexKind::Meter { meter: 0 },
                Vec3::new(-0.4, -0.4, -0.6),
                Vec3::NEG_Z,
            ),
        ],
    };
    let mut sampler = Sampler::new(1, 0, 0);
    let d = densities(&scene, &pathspace::path::PLAIN, &path, &mut sampler);
    let pi = std::f64::consts::PI;
    let light_side = d.light[0] as f64 / pi * (d.prop_up[0] * d.prop_up[1]) as f64;
    let eye_side = d.eye[2] as f64 / (4.0 * pi) * (d.prop_down[1] * d.prop_down[0]) as f64;
    assert_chain_weights(&b, &scene, &path, &d, light_side / eye_side);
}

/// A Dirac vertex's density per projected solid angle needs G of its edge, which is zero for
/// coincident vertices (and at grazing angles): there the density is left as it is, finite,
/// rather than divided by zero.
#[test]
fn a_projected_density_over_a_zero_geometry_term_stays_finite() {
    use pathspace::path::subpath::projected;
    let at = |p: Vec3| v(VertexKind::Surface { prim: 0 }, p, Vec3::Y);
    let (a, b) = (at(Vec3::ZERO), at(Vec3::ZERO));
    assert_eq!(projected(0.5, &a, &b), 0.5);
    // an edge in the surfaces' plane: both cosines zero
    let c = at(Vec3::X);
    assert_eq!(projected(0.5, &a, &c), 0.5);
    // and a regular edge: divided by G = cos cos / d^2 = 1 / 4
    let d = at(Vec3::new(0.0, 2.0, 0.0));
    assert_eq!(projected(0.5, &a, &d), 2.0);
}

/// The volume caustic (a glass ball in haze under a small square light, a floor), with every
/// length multiplied by `k` and the coefficients divided by it: the same scene in another
/// unit of length.
fn ball_in_haze(k: f32) -> Scene {
    let text = format!(
        r#"
[camera]
type = "pinhole"
eye = [0.0, {cy}, {cz}]
look_at = [0.0, {k}, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 38.0
resolution = [16, 16]
[materials.floor]
type = "lambert"
albedo = 0.5
[materials.glass]
type = "dielectric"
ior = 1.5
[media.haze]
type = "homogeneous"
sigma_a = {sa}
sigma_s = {ss}
phase = {{ type = "hg", g = 0.3 }}
[[shapes]]
type = "quad"
origin = [{m3}, 0.0, {m3}]
u = [0.0, 0.0, {six}]
v = [{six}, 0.0, 0.0]
material = "floor"
[[shapes]]
type = "box"
min = [{m3}, 0.0, {m3}]
max = [{p3}, {top}, {p3}]
material = "null"
interior = "haze"
[[shapes]]
type = "sphere"
center = [0.0, {by}, 0.0]
radius = {r}
material = "glass"
interior = "vacuum"
exterior = "haze"
[[shapes]]
type = "quad"
origin = [{lo}, {ly}, {lo}]
u = [{lw}, 0.0, 0.0]
v = [0.0, 0.0, {lw}]
emission = 1500.0
"#,
        cy = 1.2 * k,
        cz = 5.5 * k,
        sa = 0.02 / k,
        ss = 0.18 / k,
        m3 = -3.0 * k,
        p3 = 3.0 * k,
        six = 6.0 * k,
        top = 3.5 * k,
        by = 1.9 * k,
        r = 0.5 * k,
        lo = -0.1 * k,
        ly = 3.3 * k,
        lw = 0.2 * k,
    );
    Scene::load(&SceneSource::embedded("ball-in-haze.toml", &text)).unwrap()
}

/// MIS weights are ratios of densities of one path in one measure, so they cannot depend on
/// the unit of length. Paths through the glass ball and the haze, drawn with the same random
/// numbers in the scene and in its copy twice the size (lengths times 2, coefficients over 2:
/// every position doubles exactly), must get the same weight for every strategy. A Dirac
/// density counted as one where the strategies' measures differ (per unit area or volume at a
/// vertex next to the glass) would leave a d^2, a cosine or a sigma_t in the ratios, and the
/// weights of the paths with a Dirac vertex next to a medium vertex would change with the unit.
#[test]
fn mis_weights_do_not_depend_on_the_unit_of_length() {
    let scenes = [ball_in_haze(1.0), ball_in_haze(2.0)];
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(8), Strategies::All);
    let mut scratch = [Scratch::default(), Scratch::default()];
    let (mut compared, mut dirac_by_medium) = (0, 0);
    for i in 0..20_000u64 {
        for (scene, sc) in scenes.iter().zip(scratch.iter_mut()) {
            let mut sampler = Sampler::new(7, i, 0);
            b.light_subpath(scene, WalkLimits::BDPT, &mut sampler, &mut sc.light);
            let u = sampler.next_2d();
            let raster = glam::Vec2::new(u.x * 16.0, u.y * 16.0);
            b.camera_subpath(scene, raster, WalkLimits::BDPT, &mut sampler, &mut sc.eye);
        }
        let [a, c] = &scratch;
        let same = |x: &[Vertex], y: &[Vertex]| {
            x.len() == y.len()
                && x.iter().zip(y).all(|(p, q)| {
                    p.delta == q.delta && (2.0 * p.p - q.p).length() <= 1e-4 * (1.0 + q.p.length())
                })
        };
        if !same(&a.light, &c.light) || !same(&a.eye, &c.eye) {
            continue; // an offset of the lifted origins sent one walk elsewhere
        }
        for s in 0..=a.light.len() {
            for t in 1..=a.eye.len() {
                let joined = |x: &Scratch| Path {
                    vertices: x.light[..s]
                        .iter()
                        .chain(x.eye[..t].iter().rev())
                        .copied()
                        .collect(),
                };
                let paths = [joined(a), joined(c)];
                let v = &paths[0].vertices;
                if v[0].area_light_point(&scenes[0]).is_none()
                    || (s > 0 && (v[s - 1].delta || v[s].delta))
                {
                    continue; // an eye subpath off the light, a connection to a Dirac vertex
                }
                let d = [0, 1].map(|k| {
                    let mut sampler = Sampler::new(0, 0, 0);
                    densities(&scenes[k], &pathspace::path::PLAIN, &paths[k], &mut sampler)
                });
                // a density that is zero where no Dirac vertex explains it (a vertex outside
                // the frame, behind the light or a wall's back): a path no image sees, whose
                // ratio is left out as one
                let n = v.len();
                let dark = (1..n - 1).any(|j| !v[j - 1].delta && d[0].light[j] == 0.0)
                    || (0..n - 1).any(|j| !v[j + 1].delta && d[0].eye[j] == 0.0);
                if dark {
                    continue;
                }
                let dirac = (1..v.len()).any(|j| {
                    let medium = |x: &Vertex| matches!(x.kind, VertexKind::Medium { .. });
                    (v[j].delta && medium(&v[j - 1])) || (v[j - 1].delta && medium(&v[j]))
                });
                let w =
                    [0, 1].map(|k| mis_weight_of_path(&b, &scenes[k], &paths[k], s, &d[k]) as f64);
                if !w.iter().all(|x| x.is_finite()) {
                    continue;
                }
                assert!(
                    (w[0] - w[1]).abs() <= 1e-3 * (1.0 + w[0]),
                    "path {i}, s = {s}, t = {t}: weight {} at unit 1, {} at unit 2",
                    w[0],
                    w[1]
                );
                compared += 1;
                dirac_by_medium += dirac as usize;
            }
        }
    }
    assert!(
        compared > 20_000 && dirac_by_medium > 500,
        "{compared} weights compared, {dirac_by_medium} with a Dirac vertex next to the haze"
    );
}

/// The medium an edge from a vertex runs through: on an interface (a glass surface between
/// media 0 outside and 1 inside) the one on the side the direction points to, the normal's
/// side being the front; on a surface between equal media and at a medium vertex (no normal)
/// the one medium. Edges (transmittance, propagation pdfs) are traced in it.
#[test]
fn vertex_media_follow_the_side_of_the_direction() {
    let up = Vec3::new(0.0, 1.0, 0.0);
    let w = Vec3::new(0.3, 0.5, 0.1);
    let interface = Vertex::new(
        VertexKind::Surface { prim: 0 },
        Vec3::ZERO,
        up,
        Some(0),
        Some(1),
    );
    assert_eq!(interface.medium_towards(w), Some(0));
    assert_eq!(interface.medium_towards(-w), Some(1));
    assert_eq!(interface.edge_end(-w).medium, Some(1));
    assert_eq!(interface.edge_end(w).medium, Some(0));
    let wall = Vertex::new(
        VertexKind::Surface { prim: 0 },
        Vec3::ZERO,
        up,
        Some(1),
        Some(1),
    );
    assert_eq!(wall.medium_towards(-w), Some(1));
    let fog = Vertex::new(
        VertexKind::Medium { medium: 1 },
        Vec3::ZERO,
        Vec3::ZERO,
        Some(1),
        Some(1),
    );
    assert_eq!(fog.medium_towards(-w), Some(1));
    assert_eq!(fog.medium_towards(w), Some(1));
}

/// For random paths, the weights of all strategies sum to one and each equals
/// p_s^beta / sum p_i^beta computed directly from the strategy densities: beta = 1 for the
/// balance heuristic, 2 for the power heuristic.
#[test]
fn mis_weights_sum_to_one_and_match_each_heuristic() {
    for (h, beta) in [(MisHeuristic::Balance, 1), (MisHeuristic::Power, 2)] {
        mis_weights_match(h, beta);
    }
}

fn mis_weights_match(h: MisHeuristic, beta: i32) {
    let scene = room();
    let b = Bdpt::new(&pathspace::path::PLAIN, Some(4), Strategies::All).with_heuristic(h);
    let mut sampler = Sampler::new(3, 1, 0);
    let mut scratch = Scratch::default();
    let mut checked = 0;
    for _ in 0..5000 {
        b.meter_subpath(&scene, 0, WalkLimits::BDPT, &mut sampler, &mut scratch.eye);
        b.light_subpath(&scene, WalkLimits::BDPT, &mut sampler, &mut scratch.light);
        // join the light subpath's first two vertices to the eye subpath: a random full path
        if scratch.light.len() < 2 || scratch.eye.len() < 2 {
            continue;
        }
        let mut verts: Vec<Vertex> = scratch.light[..2].to_vec();
        verts.extend(scratch.eye.iter().rev().copied());
        let path = Path { vertices: verts };
        if measurement_contribution(&scene, &path, &mut sampler) == Vec3::ZERO {
            continue; // the joining edge is blocked: not a path of positive contribution
        }
        let d = densities(&scene, &pathspace::path::PLAIN, &path, &mut sampler);
        let n = path.vertices.len();
        let p: Vec<f64> = (0..n).map(|s| strategy_pdf(&d, s)).collect(); // s = n (t = 0) excluded
        let total: f64 = p.iter().map(|x| x.powi(beta)).sum();
        if total.is_nan() || total <= 0.0 || !total.is_finite() {
            continue;
        }
        let mut sum = 0.0f64;
        for (s, ps) in p.iter().enumerate() {
            let w = mis_weight_of_path(&b, &scene, &path, s, &d) as f64;
            let direct = ps.powi(beta) / total;
            assert!(
                (w - direct).abs() < 1e-3,
                "strategy s={s}: weight {w}, {h:?} heuristic {direct}"
            );
            sum += w;
        }
        assert!((sum - 1.0).abs() < 1e-3, "weights sum to {sum}");
        checked += 1;
    }
    assert!(checked > 1000, "only {checked} paths checked");
}

fn meter(
    scene: &Scene,
    kind: IntegratorKind,
    seed: u64,
    max_depth: Option<u32>,
    only: Option<(usize, usize)>,
    (spp, meter_samples): (u32, u64),
) -> (f64, f64, f64) {
    let mut r = Renderer::new(scene, kind, seed, max_depth);
    // the scene's `[render] meter_samples` (the renderer starts from the defaults)
    r.meter_samples = meter_samples;
    if let Some((s, t)) = only {
        r.integrator = Box::new(Bdpt::new(
            &pathspace::path::PLAIN,
            max_depth,
            Strategies::Only(s, t),
        ));
    }
    r.pass(spp, &|| {});
    common::meter_mean(&r.meter_estimates()[0], 0)
}

/// The difference a - b of two independent estimates (mean, standard error, degrees of
/// freedom), with Welch-Satterthwaite degrees of freedom.
fn difference(a: (f64, f64, f64), b: (f64, f64, f64)) -> (f64, f64, f64) {
    let (va, vb) = (a.1 * a.1, b.1 * b.1);
    let dof = (va + vb).powi(2) / (va * va / a.2 + vb * vb / b.2);
    (a.0 - b.0, (va + vb).sqrt(), dof)
}

/// Every strategy alone is an unbiased estimator of the paths of its length: (s, t) with
/// s + t - 2 = k scattering vertices against the path tracer's depth-k contribution,
/// path(max_depth = k) - path(max_depth = k - 1).
#[test]
fn every_strategy_alone_is_unbiased() {
    let scene = room();
    let mut fam = Family::new("path space: every strategy alone");
    for k in 1u32..=2 {
        let a = meter(&scene, IntegratorKind::Path, 11, Some(k), None, (64, 1024));
        let b = meter(
            &scene,
            IntegratorKind::Path,
            12,
            Some(k - 1),
            None,
            (64, 1024),
        );
        let truth = difference(a, b);
        for s in 0..=(k as usize + 1) {
            let t = k as usize + 2 - s;
            let x = meter(
                &scene,
                IntegratorKind::Bdpt,
                13 + s as u64,
                Some(k),
                Some((s, t)),
                (16, 1024),
            );
            fam.means_agree(
                &format!("strategy ({s}, {t}) at depth {k} vs the path tracer"),
                x,
                truth,
            );
        }
    }
    fam.finish();
}

/// bdpt, light tracing and path tracing agree on the room's meter, on the slab's meters
/// (directional light) and on the fog box's image mean.
#[test]
fn bdpt_light_and_path_agree() {
    let scene = room();
    let mut fam = Family::new("path space: bdpt, light and path agree");
    let p = meter(&scene, IntegratorKind::Path, 1, None, None, (32, 1024));
    for kind in [IntegratorKind::Bdpt, IntegratorKind::Light] {
        let x = meter(&scene, kind, 2, None, None, (32, 1024));
        fam.means_agree(&format!("room: {kind:?} vs path"), x, p);
    }
    let slab = Scene::load(
        &SceneSource::read(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/slab.toml"
        )))
        .unwrap(),
    )
    .unwrap();
    let run = |kind, seed| {
        let mut r = Renderer::new(&slab, kind, seed, None);
        r.meter_samples = 2048;
        r.pass(8, &|| {});
        r.meter_estimates()
    };
    let base = run(IntegratorKind::Path, 3);
    let other = run(IntegratorKind::Bdpt, 4);
    for (a, b) in base.iter().zip(&other) {
        fam.means_agree(
            &format!("slab {}: path vs bdpt", a.name),
            common::meter_mean(a, 0),
            common::meter_mean(b, 0),
        );
    }
    fam.finish();
}

/// Refraction into a medium: a meter inside a glass box of absorbing ink, under an area light
/// outside. Every path leaves through the glass, where the walk must switch from the ink to the
/// vacuum outside (the path tracer by the side the refracted direction takes, BDPT by
/// `Vertex::medium_towards`); the two agree only if both switch.
#[test]
fn refraction_out_of_an_absorbing_box_switches_the_medium() {
    let scene = Scene::load(&SceneSource::embedded(
        "ink.toml",
        r#"
[render]
meter_samples = 4096
[materials.glass]
type = "dielectric"
ior = 1.3
[media.ink]
type = "homogeneous"
sigma_a = 0.5
sigma_s = 0.0
[[shapes]]
type = "box"
min = [-0.5, -0.5, -0.5]
max = [0.5, 0.5, 0.5]
material = "glass"
interior = "ink"
[[shapes]]
type = "quad"
origin = [-1.5, 2.0, -1.5]
u = [3.0, 0.0, 0.0]
v = [0.0, 0.0, 3.0]
emission = 1.0
[[sensors]]
type = "irradiance_meter"
name = "inside"
origin = [-0.05, -0.3, -0.05]
u = [0.0, 0.0, 0.1]
v = [0.1, 0.0, 0.0]
"#,
    ))
    .unwrap();
    let mut fam = Family::new("path space: refraction out of an absorbing box");
    let p = meter(&scene, IntegratorKind::Path, 1, Some(8), None, (8, 4096));
    let b = meter(&scene, IntegratorKind::Bdpt, 2, Some(8), None, (8, 4096));
    assert!(p.0 > 0.0, "no light reaches the meter: {p:?}");
    fam.means_agree("bdpt vs path", b, p);
    fam.finish();
}

/// Independent runs of the splatting estimators (BDPT's light-tracing strategies, light
/// tracing): their standard error comes from the runs' spread (Student-t with runs - 1 degrees
/// of freedom), so many short runs rather than a few long ones.
const SPLAT_RUNS: u64 = 32;

/// The fog box's image mean agrees between the three integrators.
#[test]
fn fog_box_image_means_agree() {
    let text =
        pathspace::scene::FOG_BOX.replace("resolution = [256, 256]", "resolution = [24, 24]");
    let scene = Scene::load(&SceneSource::embedded("fog-box.toml", &text)).unwrap();
    let mean = |kind, seed, spp| {
        let mut r = Renderer::new(&scene, kind, seed, None);
        r.pass(spp, &|| {});
        let film = r.film.unwrap();
        let img = film.image();
        let n = img.pixels.len() as f64;
        let m = img.pixels.iter().map(|p| p.y as f64).sum::<f64>() / n;
        (m, film)
    };
    let (_, film) = mean(IntegratorKind::Path, 1, 256);
    let path = common::film_mean(&film, 1);
    let mut fam = Family::new("path space: fog box image means");
    // splatted estimators have no per-pixel variance: their error comes from independent runs
    for kind in [IntegratorKind::Bdpt, IntegratorKind::Light] {
        let runs: Vec<f64> = (0..SPLAT_RUNS).map(|i| mean(kind, 100 + i, 4).0).collect();
        fam.means_agree(&format!("{kind:?} vs path"), runs_mean(&runs), path);
    }
    fam.finish();
}

/// The volume caustic (a spot light focused by glass into haze), where singular vertices decide
/// everything: BDPT and light tracing, two independent estimators, agree on every pixel the ball
/// does not cover (light tracing cannot render what the camera sees through glass).
#[test]
fn volume_caustic_bdpt_agrees_with_light_tracing() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/volume-caustic.toml"
    ))
    .unwrap()
    .replace("resolution = [256, 256]", "resolution = [20, 20]");
    let scene = Scene::load(&SceneSource::embedded("volume-caustic.toml", &text)).unwrap();
    let cam = scene.camera.as_ref().unwrap();
    // pixels whose four corners all miss every singular surface
    let seen_through_glass = |x: u32, y: u32| {
        [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
            .iter()
            .any(|(dx, dy)| {
                let ray = cam.generate_ray(glam::Vec2::new(x as f32 + dx, y as f32 + dy));
                let mut t_min = 0.0;
                while let Some(hit) = scene.bvh.intersect_range(
                    &scene.prims,
                    &scene.prim_opaque,
                    &ray,
                    t_min,
                    f32::INFINITY,
                ) {
                    let shape = scene.shape_of(&hit);
                    if shape.bsdf.as_ref().is_some_and(|b| b.has_dirac_lobe()) {
                        return true;
                    }
                    t_min = hit.t * (1.0 + 1e-5) + 1e-5;
                }
                false
            })
    };
    let mask: Vec<bool> = (0..cam.height)
        .flat_map(|y| (0..cam.width).map(move |x| (x, y)))
        .map(|(x, y)| !seen_through_glass(x, y))
        .collect();
    assert!(
        mask.iter().filter(|m| !**m).count() > 10,
        "the ball should cover some pixels"
    );
    let masked_mean = |kind, seed| {
        let mut r = Renderer::new(&scene, kind, seed, None);
        r.pass(4, &|| {});
        let img = r.film.unwrap().image();
        let (mut s, mut n) = (0.0f64, 0.0f64);
        for (p, m) in img.pixels.iter().zip(&mask) {
            if *m {
                s += p.y as f64;
                n += 1.0;
            }
        }
        s / n
    };
    let runs = |kind| -> Vec<f64> {
        (0..SPLAT_RUNS)
            .map(|i| masked_mean(kind, 500 + i))
            .collect()
    };
    let bdpt = runs_mean(&runs(IntegratorKind::Bdpt));
    let light = runs_mean(&runs(IntegratorKind::Light));
    let mut fam = Family::new("path space: volume caustic");
    fam.means_agree("bdpt vs light tracing", bdpt, light);
    fam.finish();
    // and the caustic is really there: the path tracer, blind to it, is darker beyond doubt
    // (else two estimators that both lost it would agree)
    let path = runs_mean(&runs(IntegratorKind::Path));
    eprintln!(
        "masked mean: bdpt {:.4} +- {:.4}, light {:.4} +- {:.4}, path {:.4} +- {:.4}",
        bdpt.0, bdpt.1, light.0, light.1, path.0, path.1
    );
    assert!(path.0 < bdpt.0, "the path tracer is brighter than bdpt");
    assert_significant("the caustic the path tracer misses", p_welch(path, bdpt));
}

/// Veach's power heuristic with beta = 2 by hand: a^2 / (a^2 + b^2), 0 when neither strategy
/// can produce the sample, 1 for a strategy with an infinite (Dirac) density.
#[test]
fn power_heuristic_by_hand() {
    use pathspace::integrator::path::power_heuristic;
    let check = |a: f32, b: f32, expected: f32| {
        let got = power_heuristic(a, b);
        assert!(
            (got - expected).abs() <= 1e-6 * expected.abs().max(1.0),
            "power_heuristic({a}, {b}): got {got}, expected {expected}"
        );
    };
    check(1.0, 1.0, 0.5);
    check(3.0, 1.0, 0.9);
    check(1.0, 3.0, 0.1);
    check(0.2, 0.1, 0.8);
    for (a, b) in [(0.3f32, 7.0f32), (2.0, 2.5), (1e-3, 1e-4)] {
        let sum = power_heuristic(a, b) + power_heuristic(b, a);
        assert!(
            (sum - 1.0).abs() <= 1e-6,
            "w({a}, {b}) + w({b}, {a}): got {sum}, expected 1"
        );
    }
    // neither strategy can make the sample, or a Dirac density on one side
    check(0.0, 2.0, 0.0);
    check(0.0, 0.0, 0.0);
    check(f32::INFINITY, 1.0, 1.0);
    check(1.0, f32::INFINITY, 0.0);
}

/// A corridor of two perfect mirrors at x = -1 and x = 1, open at the camera's end and closed
/// 12 units down by an emitter of radiance 1 facing back up it. The camera at the origin looks
/// down the corridor at 45 degrees through a 1-degree field, so every ray of every pixel
/// reflects exactly six times (at z = -1, -3, ..., -11) and then meets the emitter.
const MIRROR_CORRIDOR: &str = r#"
[render]
spp = 16
seed = 3
[camera]
type = "pinhole"
eye = [0.0, 0.0, 0.0]
look_at = [1.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_deg = 1.0
resolution = [4, 4]
[materials.mirror]
type = "mirror"
reflectance = 1.0
[[shapes]]
type = "quad"
origin = [1.0, -1.0, -13.0]
u = [0.0, 0.0, 14.0]
v = [0.0, 2.0, 0.0]
material = "mirror"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -13.0]
u = [0.0, 2.0, 0.0]
v = [0.0, 0.0, 14.0]
material = "mirror"
[[shapes]]
type = "quad"
origin = [-1.0, -1.0, -12.0]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
emission = 1.0
"#;

/// Russian roulette starts after the third vertex whose direction has a density (the path
/// tracer's after the fifth), not after the third vertex: a chain of specular vertices carries
/// all its light on one ray, so ending it at random only adds variance, and paths that cross
/// glass before they scatter would otherwise be rouletted at their first diffuse bounce. In the
/// mirror corridor no vertex has a density: every eye walk of BDPT reaches the emitter after
/// its six reflections (eight vertices with the camera and the emitter), and the path tracer's
/// every sample is exactly 1, so each pixel is 1 however many samples it takes. Counting the
/// mirrors as the roulette's vertices ends a fifth of the walks before the emitter, and leaves
/// samples of 0 and 1 / 0.95^2 in the path tracer's pixels.
#[test]
fn a_chain_of_mirrors_does_not_start_the_roulette() {
    let scene = Scene::load(&SceneSource::embedded("corridor.toml", MIRROR_CORRIDOR)).unwrap();
    let b = Bdpt::new(&pathspace::path::PLAIN, None, Strategies::All);
    let raster = glam::Vec2::new(2.0, 2.0);
    let mut path = Vec::new();
    for i in 0..64 {
        let mut sampler = Sampler::new(1, i, 0);
        b.camera_subpath(&scene, raster, WalkLimits::BDPT, &mut sampler, &mut path);
        assert_eq!(path.len(), 8, "eye walk {i}");
        assert!(path[1..7].iter().all(|v| v.delta), "eye walk {i}");
    }
    let mut rd = Renderer::new(&scene, IntegratorKind::Path, 1, None);
    rd.pass(16, &|| {});
    let image = rd.film.as_ref().unwrap().image();
    for (k, px) in image.pixels.iter().enumerate() {
        for c in px.to_array() {
            // the filter's weighted mean of sixteen samples of exactly 1
            assert!((c - 1.0).abs() < 1e-6, "pixel {k}: {px:?}");
        }
    }
}

/// The other half of the roulette's rule: it waits for three vertices with a density. In the
/// closed fog-filled room lit by a point light instead of its ceiling lamp no light walk can end
/// but by the roulette (no emitter to hit, nothing absorbs all, nothing escapes), so every walk
/// holds the light and at least three scattering vertices, and since the first roulette (after
/// the third) ends about half of them, some hold exactly that.
#[test]
fn the_roulette_waits_for_three_vertices_with_a_density() {
    let lamp = "[[shapes]]\ntype = \"quad\"\norigin = [-0.3, 0.99, -0.3]\nu = [0.6, 0.0, 0.0]\nv = [0.0, 0.0, 0.6]\nemission = 5.0\n";
    let point = "[[lights]]\ntype = \"point\"\nposition = [0.1, 0.2, 0.3]\nintensity = 1.0\n";
    assert!(ROOM.contains(lamp), "the room's lamp changed");
    let text = ROOM.replace(lamp, point);
    let scene = Scene::load(&SceneSource::embedded("point-lit-room.toml", &text)).unwrap();
    let b = Bdpt::new(&pathspace::path::PLAIN, None, Strategies::All);
    let mut path = Vec::new();
    let mut shortest = 0;
    for i in 0..256 {
        let mut sampler = Sampler::new(2, i, 0);
        b.light_subpath(&scene, WalkLimits::BDPT, &mut sampler, &mut path);
        assert!(path.len() >= 4, "light walk {i}: {} vertices", path.len());
        shortest += usize::from(path.len() == 4);
    }
    assert!(shortest > 0, "no walk ended at the first roulette");
}
