//! Edges by one any-hit query and the null boundaries alone (`Scene::edge`, `edge_exact`,
//! `transmittance`): the shortcut must give the bits of the plain segment walk, whose closest-hit
//! queries see every primitive. Random edges between points in the media, on the surfaces and
//! outside the scene, in every shipped scene with a null boundary, in both directions.
//! Book: "Measuring a renderer", section "Edges: one any-hit query, then the boundaries".

use glam::{Vec2, Vec3};
use pathspace::math::Sampler;
use pathspace::scene::{EdgeEnd, Scene, SceneSource};

fn shipped(name: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    Scene::load(&SceneSource::read(&path).unwrap()).unwrap()
}

/// A point of the scene's box (grown by a tenth), as a medium vertex (`n` zero).
fn free_point(scene: &Scene, s: &mut Sampler) -> EdgeEnd {
    let b = scene.bounds;
    let grow = 0.1 * (b.max - b.min);
    let (lo, hi) = (b.min - grow, b.max + grow);
    let u = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32());
    let p = lo + u * (hi - lo);
    let medium = scene.medium_at(p);
    EdgeEnd {
        p,
        n: Vec3::ZERO,
        medium,
        in_medium: medium.is_some(),
        prim: None,
        camera: false,
    }
}

/// A point on a primitive (null boundaries included), on the side of its normal facing `toward`.
fn surface_point(scene: &Scene, toward: Vec3, s: &mut Sampler) -> EdgeEnd {
    let i = s.next_index(scene.prims.len());
    let (p, n) = scene.prims[i].sample_area(Vec2::new(s.next_f32(), s.next_f32()));
    let side = if (toward - p).dot(n) >= 0.0 { n } else { -n };
    EdgeEnd {
        p,
        n: side,
        medium: scene.medium_at(p + 1e-3 * side),
        in_medium: false,
        prim: None,
        camera: false,
    }
}

/// `n` random edges of `scene`: free-free, free-surface and surface-surface pairs.
fn random_edges(scene: &Scene, n: u64) -> Vec<(EdgeEnd, EdgeEnd)> {
    (0..n)
        .map(|i| {
            let mut s = Sampler::new(11, i, 0);
            let a = free_point(scene, &mut s);
            match i % 3 {
                0 => (a, free_point(scene, &mut s)),
                1 => (a, surface_point(scene, a.p, &mut s)),
                _ => {
                    let b = surface_point(scene, a.p, &mut s);
                    (surface_point(scene, b.p, &mut s), b)
                }
            }
        })
        .collect()
}

const SCENES: [&str; 6] = [
    "fog-box.toml",
    "door-slit-strips.toml",
    "door-slit.toml",
    "maze-fog.toml",
    "volume-caustic.toml",
    "cloud.toml",
];

/// Every edge evaluates to the same transmittance and propagation pdfs, bit for bit, with the
/// shortcut and by the walk; a good share of them is occluded, crosses a boundary, or neither.
#[test]
fn the_any_hit_shortcut_gives_the_walks_bits() {
    for name in SCENES {
        let scene = shipped(name);
        assert!(scene.has_null, "{name} has a null boundary");
        let (mut occluded, mut crossing, mut neither) = (0, 0, 0);
        let edges = random_edges(&scene, 3000);
        for &(a, b) in &edges {
            for (from, to) in [(a, b), (b, a)] {
                let fast = scene.edge_exact(from, to);
                let walked = scene.edge_exact_walked(from, to);
                let bits = |e: &pathspace::scene::EdgeEval| {
                    let t = e.transmittance;
                    [t[0], t[1], t[2], e.pdf_ab, e.pdf_ba].map(f32::to_bits)
                };
                assert_eq!(
                    bits(&fast),
                    bits(&walked),
                    "{name}: edge {:?} -> {:?}: shortcut {fast:?}, walk {walked:?}",
                    from.p,
                    to.p
                );
                let blocked = walked.transmittance == pathspace::spectrum::Rgb::ZERO;
                occluded += usize::from(blocked);
                crossing += usize::from(from.medium != to.medium);
                // open and in one medium: mostly edges the any-hit query finds clear
                neither += usize::from(!blocked && from.medium == to.medium);
            }
        }
        let n = 2 * edges.len();
        let counts = [
            ("occluded", occluded),
            ("crossing a boundary", crossing),
            ("open in one medium", neither),
        ];
        for (what, k) in counts {
            assert!(
                k >= n / 50 && k <= n - n / 50,
                "{name}: {k} of {n} edges {what}: the sample does not exercise both branches"
            );
        }
    }
}

/// The shadow ray of next-event estimation (`Scene::transmittance`) takes the same shortcut in
/// scenes of homogeneous media: it equals the walked edge between the same two free points.
#[test]
fn shadow_rays_with_the_shortcut_match_the_walked_edges() {
    for name in ["fog-box.toml", "door-slit-strips.toml", "maze-fog.toml"] {
        let scene = shipped(name);
        assert!(scene.closed_form_tau, "{name} has homogeneous media only");
        let mut sampler = Sampler::new(5, 0, 0);
        for i in 0..3000 {
            let mut s = Sampler::new(13, i, 0);
            let (a, b) = (free_point(&scene, &mut s), free_point(&scene, &mut s));
            let full = b.p - a.p;
            let dist = full.length();
            let tr = scene.transmittance(a.p, full / dist, dist, a.medium, &mut sampler);
            let walked = scene.edge_exact_walked(a, b).transmittance;
            assert_eq!(
                tr.to_array().map(f32::to_bits),
                walked.to_array().map(f32::to_bits),
                "{name}: shadow ray {:?} -> {:?}",
                a.p,
                b.p
            );
        }
    }
}

/// The fog box with a dense fog (sigma_t = 20), so that a few micrometres of length show.
fn dense_fog_box() -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fog-box.toml");
    let text = std::fs::read_to_string(path)
        .unwrap()
        .replace("sigma_a = 0.1", "sigma_a = 4.0")
        .replace("sigma_s = 0.4", "sigma_s = 16.0");
    Scene::load(&SceneSource::embedded("dense-fog-box.toml", &text)).unwrap()
}

/// An edge from a point in a homogeneous medium to a wall is measured between the true end
/// points, although its queries run between points lifted off the surfaces: transmittance and
/// passage probability exp(-sigma_t L), collision density sigma_t exp(-sigma_t L), with L = |b - a|
/// (Pauly et al. 2000, eq. 3 and Table 1). The tolerance is f32 rounding of L times sigma_t L = 20
/// (a relative 2e-6); leaving out the lifts (4e-6 long here) moves the result by 8e-5.
#[test]
fn an_edge_to_a_wall_is_measured_between_the_true_end_points() {
    let scene = dense_fog_box();
    let fog = scene.medium_at(Vec3::ZERO);
    assert!(fog.is_some());
    let sigma_t = 20.0f64;
    let a = EdgeEnd {
        p: Vec3::new(0.1, 0.2, -0.3),
        n: Vec3::ZERO,
        medium: fog,
        in_medium: true,
        prim: None,
        camera: false,
    };
    for b_p in [Vec3::new(0.3, -1.0, 0.2), Vec3::new(-0.6, -1.0, -0.1)] {
        let b = EdgeEnd {
            p: b_p,
            n: Vec3::Y,
            medium: fog,
            in_medium: false,
            prim: None,
            camera: false,
        };
        let l = f64::from((b.p - a.p).length());
        let passage = (-sigma_t * l).exp();
        let close = |got: f32, want: f64, what: &str| {
            let rel = (f64::from(got) - want).abs() / want;
            assert!(
                rel < 1e-5,
                "{what}: {got} against {want} (relative {rel:.1e})"
            );
        };
        let (ab, ba) = (scene.edge_exact(a, b), scene.edge_exact(b, a));
        for e in [ab, ba] {
            close(e.transmittance[1], passage, "transmittance");
        }
        // reaching the wall is a passage, reaching the medium point a collision
        close(ab.pdf_ab, passage, "a -> b");
        close(ab.pdf_ba, sigma_t * passage, "b -> a");
        close(ba.pdf_ab, sigma_t * passage, "b -> a, reversed edge");
        close(ba.pdf_ba, passage, "a -> b, reversed edge");
    }
}

/// Degenerate edges are zero, never NaN: coincident ends (with and without normals) and an end
/// that is not finite.
#[test]
fn degenerate_edges_are_zero() {
    let scene = shipped("fog-box.toml");
    let fog = scene.medium_at(Vec3::ZERO);
    let at = |p: Vec3, n: Vec3| EdgeEnd {
        p,
        n,
        medium: fog,
        in_medium: n == Vec3::ZERO,
        prim: None,
        camera: false,
    };
    let p = Vec3::new(0.2, -1.0, 0.1);
    let cases = [
        (at(p, Vec3::Y), at(p, Vec3::Y)),
        (at(p, Vec3::ZERO), at(p, Vec3::ZERO)),
        (
            at(Vec3::ZERO, Vec3::ZERO),
            at(Vec3::splat(f32::NAN), Vec3::ZERO),
        ),
        (
            at(Vec3::ZERO, Vec3::ZERO),
            at(Vec3::new(f32::INFINITY, 0.0, 0.0), Vec3::ZERO),
        ),
    ];
    for (a, b) in cases {
        for e in [scene.edge_exact(a, b), scene.edge_exact_walked(a, b)] {
            assert_eq!(
                e.transmittance,
                pathspace::spectrum::Rgb::ZERO,
                "{a:?} -> {b:?}"
            );
            assert_eq!((e.pdf_ab, e.pdf_ba), (0.0, 0.0), "{a:?} -> {b:?}");
        }
    }
}

// The modules of `src/scene/` (the layout: tests/repository/index.rs).
/// Propagation draws a homogeneous medium's free flight before the segment's intersection
/// query and stops the query at the collision (`Scene::propagate_from`,
/// `propagate_weight_from`); the result must be the walk's that queries first
/// (`propagate_along` the segments `Segments` gives), bit for bit, with the same random
/// numbers drawn. Rays from points in and outside the media and from surfaces (lifted, with a
/// lead), in every shipped scene with a null boundary and in a dense fog box, where most
/// flights end before the first wall.
#[test]
fn drawing_the_flight_before_the_query_gives_the_walks_bits() {
    use pathspace::geometry::Ray;
    use pathspace::scene::Segments;
    let scenes = SCENES.map(|name| (name, shipped(name)));
    for (name, scene) in scenes
        .into_iter()
        .chain([("dense fog box", dense_fog_box())])
    {
        let (mut collided, mut surfaces) = (0, 0);
        const RAYS: u64 = 4000;
        for i in 0..RAYS {
            let mut s = Sampler::new(17, i, 0);
            let (o, medium, lead) = if i % 2 == 0 {
                let a = free_point(&scene, &mut s);
                (a.p, a.medium, 0.0)
            } else {
                let a = surface_point(&scene, Vec3::ZERO, &mut s);
                let lead = 1e-4 * s.next_f32();
                (a.p + a.n * lead, a.medium, lead)
            };
            let d = pathspace::math::warp::uniform_sphere(Vec2::new(s.next_f32(), s.next_f32()));
            let ray = Ray::new(o, d);
            let along = || Segments::new(&scene, ray, medium, f32::INFINITY).lead(lead);
            // each pair of walks from one stream
            let stream = |k| Sampler::new(19, i, k);
            let (mut s1, mut s2, mut s3, mut s4) = (stream(0), stream(0), stream(1), stream(1));
            let first = scene.propagate_from(ray, lead, medium, false, &mut s1);
            let walked = scene.propagate_along(ray, along(), &mut s2);
            let at = format!("{name}: ray {i} from {o} along {d}, lead {lead}");
            assert_eq!(format!("{first:?}"), format!("{walked:?}"), "{at}");
            assert_eq!(s1.next_f32(), s2.next_f32(), "random numbers, {at}");
            let w_first = scene.propagate_weight_from(ray, lead, medium, false, &mut s3);
            let w_walked = scene.propagate_weight_along(ray, along(), &mut s4);
            assert_eq!(
                format!("{w_first:?}"),
                format!("{w_walked:?}"),
                "weight only, {at}"
            );
            assert_eq!(
                s3.next_f32(),
                s4.next_f32(),
                "random numbers, weight only, {at}"
            );
            match walked.event {
                pathspace::scene::Event::Medium { .. } => collided += 1,
                pathspace::scene::Event::Surface { .. } => surfaces += 1,
                pathspace::scene::Event::Escape => {}
            }
        }
        assert!(
            collided >= RAYS / 100 && surfaces >= RAYS / 100,
            "{name}: {collided} collisions and {surfaces} surfaces do not exercise both outcomes"
        );
    }
}

/// `Segments::next_before(t)` against `next`, for collision distances `t` a few ulps and a few
/// tie windows either side of the segment's length: `Beyond` only when the segment is longer
/// than `t` in f32, and otherwise the very segment `next` gives, including the tie-break of
/// coplanar faces (the fog box's walls and its null boundary) cut by the query's end.
#[test]
fn a_query_stopped_at_a_collision_gives_the_segment_or_says_beyond() {
    use pathspace::geometry::Ray;
    use pathspace::scene::{Before, Segments};
    // the null boundary 2e-6 inside the walls: it comes first, and the wall behind it wins the
    // tie-break (within `TIE_EPSILON`) only if the query sees both
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fog-box.toml");
    let inset = std::fs::read_to_string(path)
        .unwrap()
        .replace(
            "min = [-1.0, -1.0, -1.0]",
            "min = [-0.999998, -0.999998, -0.999998]",
        )
        .replace("max = [1.0, 1.0, 1.0]", "max = [0.999998, 0.999998, 1.0]");
    let inset = Scene::load(&SceneSource::embedded("inset-fog-box.toml", &inset)).unwrap();
    for (name, scene) in [
        ("fog-box.toml", shipped("fog-box.toml")),
        ("dense fog box", dense_fog_box()),
        ("fog box, boundary inside the walls", inset),
    ] {
        let (mut beyond, mut segments) = (0, 0);
        for i in 0..2000u64 {
            let mut s = Sampler::new(23, i, 0);
            let a = free_point(&scene, &mut s);
            let d = pathspace::math::warp::uniform_sphere(Vec2::new(s.next_f32(), s.next_f32()));
            let ray = Ray::new(a.p, d);
            let fresh = || Segments::new(&scene, ray, a.medium, f32::INFINITY);
            let Some(seg) = fresh().next() else { continue };
            let len = seg.t1 - seg.t0;
            if !len.is_finite() {
                continue;
            }
            let ulps = (-4..=4).map(|k| f32::from_bits((len.to_bits() as i32 + k) as u32));
            let windows = (-30..=30).map(|k| len * (1.0 + k as f32 * 1e-6));
            for t in ulps.chain(windows) {
                let at = format!(
                    "{name}: ray {i} from {} along {d}, t {t}, length {len}",
                    a.p
                );
                match fresh().next_before(t) {
                    Before::Beyond => {
                        assert!(t < len, "beyond, but the segment is not longer: {at}");
                        beyond += 1;
                    }
                    Before::Segment(got) => {
                        assert_eq!(format!("{got:?}"), format!("{:?}", Some(seg)), "{at}");
                        segments += 1;
                    }
                }
            }
        }
        assert!(
            beyond >= 500 && segments >= 500,
            "{name}: {beyond} beyond, {segments} segments"
        );
    }
}

mod envmap;
mod halo;
mod hide_emitters;
mod light;
mod light_point;
mod light_tree;
mod normals;
