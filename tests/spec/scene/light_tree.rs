//! The light tree's selection (`light_selection = "tree"`, `scene::light_tree`): its
//! probabilities sum to one over the lights at any point, the probability it reports when it
//! samples a light is the one `pmf` evaluates for that light, and it samples with those
//! frequencies (chi-square); the importances the descent computes in vector lanes are the
//! scalar ones bit for bit; in nine rooms it prefers the light of the point's room; single
//! scattering along a ray agrees between power and tree selection, with and without
//! equiangular MIS. The integrators' agreement on a many-light scene is the `many-lights` row
//! of `tests/oracles/agreement.rs`. Book: "The Neumann series", section "Light selection".

use crate::common;

use common::stats::Family;
use glam::Vec3;
use pathspace::math::{warp, Sampler};
use pathspace::scene::{LightSelection, LightSelectionKind, Scene, SceneSource};

fn load(name: &str, text: String) -> Scene {
    let source = SceneSource {
        name: name.to_string(),
        text,
        base_dir: std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")),
        origin: None,
        inputs: Default::default(),
    };
    pathspace::integrator::settings::load(&source)
        .unwrap_or_else(|e| panic!("{e}"))
        .0
}

/// The many-light fixture of the agreement matrix (area, sphere, point, spot and directional
/// lights) and nine rooms of `pathspace rooms` (lights facing down behind walls).
fn scenes() -> Vec<(&'static str, Scene)> {
    let fixture = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/agreement/many-lights.toml"
    );
    vec![
        (
            "many-lights",
            load("many-lights", std::fs::read_to_string(fixture).unwrap()),
        ),
        (
            "rooms-3",
            load("rooms-3", pathspace::cli::rooms::rooms_scene(3)),
        ),
    ]
}

fn tree(scene: &Scene) -> LightSelection {
    let t = LightSelection::build(LightSelectionKind::Tree, scene);
    assert!(matches!(t, LightSelection::Tree(_)), "no tree was built");
    t
}

/// A shading point in (a little beyond) the scene's box, on a surface with a random normal or
/// in a medium (no normal), from `sampler`.
fn shading_point(scene: &Scene, sampler: &mut Sampler) -> (Vec3, Option<Vec3>) {
    let b = scene.bounds;
    let u = Vec3::new(sampler.next_f32(), sampler.next_f32(), sampler.next_f32());
    let p = b.min - 0.1 * b.extent() + 1.2 * b.extent() * u;
    let n = (sampler.next_f32() < 0.5).then(|| warp::uniform_sphere(sampler.next_2d()));
    (p, n)
}

/// The probabilities of all lights sum to 1 at every point where some light can be reached
/// (to the rounding of a product of one factor per tree level), and to 0 where sampling
/// finds no light; the power selection's sum is 1 everywhere.
#[test]
fn tree_pmf_sums_to_one_over_the_lights() {
    for (name, scene) in scenes() {
        let sel = tree(&scene);
        let mut sampler = Sampler::new(7, 0, 0);
        let mut reached = 0;
        for _ in 0..2000 {
            let (p, n) = shading_point(&scene, &mut sampler);
            let sum: f64 = (0..scene.lights.len() as u32)
                .map(|l| sel.pmf(&scene, p, n, l) as f64)
                .sum();
            let power: f64 = (0..scene.lights.len() as u32)
                .map(|l| LightSelection::Power.pmf(&scene, p, n, l) as f64)
                .sum();
            assert!(
                (power - 1.0).abs() < 1e-5,
                "{name}: power pmf sums to {power}"
            );
            match sel.sample(&scene, p, n, 0.5) {
                Some(_) => {
                    reached += 1;
                    assert!(
                        (sum - 1.0).abs() < 1e-5,
                        "{name}: the tree's pmf sums to {sum} at {p} (normal {n:?})"
                    );
                }
                None => assert_eq!(sum, 0.0, "{name}: no light sampled at {p}, pmf sum {sum}"),
            }
        }
        assert!(
            reached > 1900,
            "{name}: only {reached} of 2000 points reach a light"
        );
    }
}

/// The probability `sample` returns with a light is exactly (bit for bit) what `pmf`
/// evaluates for that light at the same point: MIS at an emitter found by chance uses the
/// latter for the density next-event estimation had.
#[test]
fn sampled_probability_is_the_evaluated_pmf() {
    for (name, scene) in scenes() {
        let sel = tree(&scene);
        let mut sampler = Sampler::new(11, 0, 0);
        for _ in 0..20_000 {
            let (p, n) = shading_point(&scene, &mut sampler);
            let Some((l, pmf, rem)) = sel.sample(&scene, p, n, sampler.next_f32()) else {
                continue;
            };
            assert!((0.0..1.0).contains(&rem), "{name}: remapped u {rem}");
            assert!(
                pmf > 0.0,
                "{name}: light {l} sampled with probability {pmf}"
            );
            let eval = sel.pmf(&scene, p, n, l as u32);
            assert_eq!(
                pmf.to_bits(),
                eval.to_bits(),
                "{name}: light {l} at {p} (normal {n:?}): sampled {pmf}, evaluated {eval}"
            );
        }
    }
}

/// The descent computes the importances of two children, and of their children, in vector
/// lanes; each is bit for bit the scalar `LightBounds::importance` (Conty Estevez and Kulla
/// 2018, eq. 3) of its node, at points inside and outside the nodes' bounding spheres, on
/// surfaces and in media, so that no image changes by the vector form.
#[test]
fn importances_in_lanes_are_the_scalar_ones_bit_for_bit() {
    let mut all = scenes();
    all.push((
        "rooms-10",
        load("rooms-10", pathspace::cli::rooms::rooms_scene(10)),
    ));
    for (name, scene) in all {
        let LightSelection::Tree(t) = tree(&scene) else {
            unreachable!()
        };
        let mut sampler = Sampler::new(13, 0, 0);
        for _ in 0..5000 {
            let (p, n) = shading_point(&scene, &mut sampler);
            assert!(
                t.lanes_match_scalar(p, n),
                "{name}: at {p} (normal {n:?}) an importance in lanes differs from the scalar one"
            );
        }
    }
}

/// The frequencies of the sampled lights at fixed points against the evaluated pmf, by
/// Pearson's chi-square (one family over the points of both scenes).
#[test]
fn tree_samples_lights_with_the_evaluated_frequencies() {
    let mut fam = Family::new("light tree: sampling frequencies");
    const N: u64 = 40_000;
    for (name, scene) in scenes() {
        let sel = tree(&scene);
        let mut points = Sampler::new(3, 0, 0);
        for k in 0..4 {
            let (p, n) = shading_point(&scene, &mut points);
            let mut counts = vec![0u64; scene.lights.len()];
            let mut sampler = Sampler::new(5, k, 1);
            let mut drawn = 0u64;
            for _ in 0..N {
                if let Some((l, _, _)) = sel.sample(&scene, p, n, sampler.next_f32()) {
                    counts[l] += 1;
                    drawn += 1;
                }
            }
            if drawn == 0 {
                continue;
            }
            assert_eq!(drawn, N, "{name}: some draws found no light at {p}");
            let expected: Vec<f64> = (0..scene.lights.len() as u32)
                .map(|l| N as f64 * sel.pmf(&scene, p, n, l) as f64)
                .collect();
            fam.chi_square(&format!("{name} point {k}"), &counts, &expected);
        }
    }
    fam.finish();
}

/// In the rooms, the light above a point on a room's floor is the likeliest choice, and far
/// more likely than under power selection (every light has the same power there): what the
/// tree is for.
#[test]
fn tree_prefers_the_light_of_the_room() {
    let scene = load("rooms-3", pathspace::cli::rooms::rooms_scene(3));
    let sel = tree(&scene);
    // the centre of room (1, 1) is (6, z, 6); its light is the one closest above it
    let p = Vec3::new(5.0, 0.0, 7.0);
    let own = (0..scene.lights.len() as u32)
        .min_by(|&a, &b| {
            let d = |l: u32| match &scene.lights[l as usize] {
                pathspace::scene::Light::Area { prims, .. } => {
                    let c = scene.prims[prims[0] as usize].bounds().centroid();
                    (c - Vec3::new(6.0, 3.0, 6.0)).length()
                }
                _ => f32::INFINITY,
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    let pmf = |l| sel.pmf(&scene, p, Some(Vec3::Y), l);
    for l in 0..scene.lights.len() as u32 {
        if l != own {
            assert!(
                pmf(own) > pmf(l),
                "light {l}: {} >= own {}",
                pmf(l),
                pmf(own)
            );
        }
    }
    let power = LightSelection::Power.pmf(&scene, p, Some(Vec3::Y), own);
    assert!(
        pmf(own) > 3.0 * power,
        "own light: tree {} against power {power}",
        pmf(own)
    );
}

/// The path tracer's single scattering (one vertex) along a ray through the haze of the
/// many-light fixture: free flight and equiangular MIS with the tree against free flight with
/// power selection (Welch, per channel). Equiangular sampling picks its light at the ray's
/// origin, but its MIS weight against phase sampling must take the tree's probability at the
/// vertex, the one the walk's emitter hits use.
#[test]
fn single_scattering_agrees_across_selections_and_distance_sampling() {
    use pathspace::integrator::path::{DistanceSampling, PathTracer};
    const N: u64 = 400_000;
    let mut fam = Family::new("light tree: single scattering with equiangular MIS");
    let (_, scene) = scenes().swap_remove(0);
    let o = Vec3::new(0.0, 0.6, 1.9);
    let ray = pathspace::geometry::Ray::new(o, Vec3::new(-0.3, -0.1, -1.0).normalize());
    let medium = scene.medium_at(o);
    let tree = || LightSelection::build(LightSelectionKind::Tree, &scene);
    let configs = [
        (
            "power free-flight",
            DistanceSampling::FreeFlight,
            LightSelection::Power,
        ),
        ("tree free-flight", DistanceSampling::FreeFlight, tree()),
        ("tree equiangular", DistanceSampling::EquiangularMis, tree()),
    ];
    let mut stats = Vec::new();
    for (k, (name, distance, selection)) in configs.into_iter().enumerate() {
        let pt = PathTracer::new(Some(1))
            .with_distance(distance)
            .with_light_selection(selection);
        let (mut sum, mut sum_sq) = ([0.0f64; 3], [0.0f64; 3]);
        for n in 0..N {
            let mut s = Sampler::new(21, n, k as u64);
            let l = pt.radiance(&scene, ray, medium, &mut s);
            for c in 0..3 {
                sum[c] += l[c] as f64;
                sum_sq[c] += (l[c] as f64).powi(2);
            }
        }
        let per_channel: Vec<(f64, f64, f64)> = (0..3)
            .map(|c| {
                let mean = sum[c] / N as f64;
                let var = (sum_sq[c] / N as f64 - mean * mean) * N as f64 / (N - 1) as f64;
                (mean, (var / N as f64).sqrt(), (N - 1) as f64)
            })
            .collect();
        stats.push((name, per_channel));
    }
    for (name, s) in &stats[1..] {
        for (c, (&a, &b)) in s.iter().zip(&stats[0].1).enumerate() {
            eprintln!(
                "{name} channel {c}: {:.5e} +- {:.1e} against {:.5e} +- {:.1e}",
                a.0, a.1, b.0, b.1
            );
            fam.means_agree(&format!("{name} against {} channel {c}", stats[0].0), a, b);
        }
    }
    fam.finish();
}
