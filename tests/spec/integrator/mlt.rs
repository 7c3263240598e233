//! Metropolis light transport (Pauly, Kollig, Keller 2000 sec. 5; Veach 1997 ch. 11): every
//! proposal has a density both ways, eq. (8), p(D) ~ 1/D, reuse of edge factors, the refined
//! b, and the MLT image against BDPT over independent runs, initialization included, for all
//! mutations and for each perturbation paired with the bidirectional mutation. The transition
//! densities themselves (proposal histograms, stationarity of chains) are
//! `tests/spec/integrator/mlt/mutation.rs`.

use crate::common;

use glam::Vec3;
use pathspace::film::Film;
use pathspace::integrator::mlt::acceptance::acceptance;
use pathspace::integrator::mlt::contribution::{image_contribution, scalar_contribution};
use pathspace::integrator::mlt::init::Bootstrap;
use pathspace::integrator::mlt::mutation::{InverseDistance, MutationKind, Workspace};
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::math::Sampler;
use pathspace::path::Vertex;
use pathspace::scene::{Scene, SceneSource};

use common::stats::Family;

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

fn engine(scene: &Scene, weights: [f64; 5], max_depth: Option<u32>, seed: u64) -> Mlt<'_> {
    let settings = MltSettings {
        weights,
        bootstrap: 2000,
        chains: 4,
        ..MltSettings::default()
    };
    Mlt::new(scene, &pathspace::path::PLAIN, settings, seed, max_depth)
        .expect("mlt applies to the scene")
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

/// Every proposal is in the support of its own T, and the perturbations can always take it
/// back (T(y -> x) > 0), so eq. (8) sees both densities. (Whether T is the right density is
/// `tests/spec/integrator/mlt/mutation.rs`: the proposals' histograms and the chains' stationarity; the
/// identity f(x) T(x -> y) alpha(x -> y) = f(y) T(y -> x) alpha(y -> x) holds for any T, so it
/// tests nothing about T and is not asserted here.)
#[test]
fn every_proposal_has_a_density_and_perturbations_can_take_it_back() {
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
        let (mut work, mut y) = (Workspace::default(), Vec::new());
        let (mut checked, mut irreversible) = (0, 0);
        for x in &paths {
            let (fx, _) = image_contribution(&scene, x).unwrap();
            let fx = scalar_contribution(fx) as f64;
            for _ in 0..4 {
                if m.sample(
                    &scene,
                    &pathspace::path::PLAIN,
                    x,
                    &mut sampler,
                    &mut work,
                    &mut y,
                )
                .is_none()
                {
                    continue;
                }
                let Some((fy, _)) = image_contribution(&scene, &y) else {
                    continue;
                };
                if y.len() == x.len() && y.iter().zip(x).all(|(a, b)| a.p == b.p) {
                    // k_d = k_a = 1 reconnecting the same two vertices: a move to x itself
                    continue;
                }
                let fy = scalar_contribution(fy) as f64;
                let t_xy = m.transition_density(&scene, &pathspace::path::PLAIN, x, &y, &mut work);
                let t_yx = m.transition_density(&scene, &pathspace::path::PLAIN, &y, x, &mut work);
                assert!(
                    t_xy > 0.0 && t_xy.is_finite(),
                    "{}: T(x -> y) = {t_xy} for a y it proposed",
                    kind.name()
                );
                if t_yx <= 0.0 {
                    // y cannot give x back (only the bidirectional mutation: x's section next
                    // to a specular vertex has no joining edge with two non-specular ends
                    // when seen from y); then alpha must be zero
                    assert_eq!(acceptance(fx, fy, t_xy, t_yx), 0.0);
                    irreversible += 1;
                    continue;
                }
                assert!(t_yx.is_finite(), "{}: T(y -> x) = {t_yx}", kind.name());
                checked += 1;
            }
        }
        eprintln!(
            "{}: {checked} proposals checked, {irreversible} irreversible",
            kind.name()
        );
        if kind != MutationKind::Bidirectional {
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

/// The quadrant means (RGB) of two sets of independent runs agree (Welch, per component).
fn quadrants_agree(fam: &mut Family, name: &str, a: &[Vec<f64>], b: &[Vec<f64>]) {
    for i in 0..a[0].len() {
        let ra: Vec<f64> = a.iter().map(|r| r[i]).collect();
        let rb: Vec<f64> = b.iter().map(|r| r[i]).collect();
        fam.runs_agree(
            &format!("{name}: quadrant {} channel {}", i / 3, i % 3),
            &ra,
            &rb,
        );
    }
}

#[test]
fn mlt_image_is_unbiased_against_bdpt_with_every_mutation_set() {
    let mut fam = Family::new("mlt: image against BDPT");
    let scene = fog_box(RES);
    let bdpt = bdpt_runs(&scene);
    quadrants_agree(
        &mut fam,
        "all mutations",
        &mlt_runs(&scene, [1.0; 5]),
        &bdpt,
    );
    for kind in [
        MutationKind::Sensor,
        MutationKind::Light,
        MutationKind::Propagation,
    ] {
        let mut w = [0.0; 5];
        w[0] = 1.0;
        w[kind.index()] = 1.0;
        quadrants_agree(&mut fam, kind.name(), &mlt_runs(&scene, w), &bdpt);
    }
    fam.finish();
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
    let err = merge(&[("c".into(), img(1.0), ImageMeta::default())])
        .unwrap_err()
        .to_string();
    assert!(err.contains("spp"), "{err}");
}

#[test]
fn bad_mlt_settings_are_clear_errors() {
    let err = MltSettings::parse_weights("bidirectional=1,lens=3")
        .unwrap_err()
        .to_string();
    assert!(err.contains("unknown mutation `lens`"), "{err}");
    let text =
        pathspace::scene::FOG_BOX.replace("seed = 1", "seed = 1\n\n[render.mlt]\nchains = 0");
    let err = pathspace::integrator::settings::load(&SceneSource::embedded("bad", &text))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("chains"), "{err}");
    let text =
        pathspace::scene::FOG_BOX.replace("seed = 1", "seed = 1\n\n[render.mlt]\nsensor = -1.0");
    assert!(pathspace::integrator::settings::load(&SceneSource::embedded("bad", &text)).is_err());
}

/// The chain re-evaluates f(y) reusing the edge factors of x for the edges y shares with it
/// (aligned from either end). That must change nothing: for proposals of every mutation type
/// the reused evaluation equals the evaluation from scratch to the bit, and the edges it
/// reports are the path's own.
/// In a heterogeneous medium too: f's transmittance is the exact one, a function of the edge
/// alone (ratio tracking's estimate would depend on the random numbers earlier edges drew).
#[test]
fn reused_edge_factors_give_the_same_contribution_to_the_bit() {
    check_reuse(&mixed_scene(), "mixed");
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cloud.toml");
    let text = std::fs::read_to_string(path).expect("the cloud scene");
    let mut cloud = Scene::load(&SceneSource::embedded("cloud", &text)).expect("valid cloud");
    let tracking = pathspace::medium::heterogeneous::LineIntegral::DeltaTracking;
    assert_eq!(cloud.set_line_integral(tracking), 1);
    check_reuse(&cloud, "cloud");
}

fn check_reuse(scene: &Scene, name: &str) {
    use pathspace::integrator::mlt::contribution::image_contribution_reusing;
    let mlt = engine(scene, [1.0; 5], Some(6), 31);
    let paths = test_paths(scene, &mlt, 200, 31);
    let mut reused_any = [0usize; 5];
    for kind in MutationKind::ALL {
        let m = mlt.mutations.get(kind);
        let mut sampler = Sampler::new(32, kind.index() as u64, 0);
        let (mut work, mut y) = (Workspace::default(), Vec::new());
        for x in &paths {
            let mut ex = Vec::new();
            image_contribution_reusing(scene, x, None, &mut ex).unwrap();
            if m.sample(
                scene,
                &pathspace::path::PLAIN,
                x,
                &mut sampler,
                &mut work,
                &mut y,
            )
            .is_none()
            {
                continue;
            }
            let (mut fresh, mut reused) = (Vec::new(), Vec::new());
            let a = image_contribution_reusing(scene, &y, None, &mut fresh);
            let b = image_contribution_reusing(scene, &y, Some((x, &ex)), &mut reused);
            assert_eq!(a, b, "{name}, {}: f(y) differs with reuse", kind.name());
            if a.is_some() {
                assert_eq!(
                    fresh,
                    reused,
                    "{name}, {}: edge factors differ",
                    kind.name()
                );
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
        assert!(
            reused_any[k.index()] > 10,
            "{name}, {}: {reused_any:?}",
            k.name()
        );
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
    let mut mlt = Mlt::new(&scene, &pathspace::path::PLAIN, settings, 41, None).unwrap();
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
    let check = |fx: f64, fy: f64, txy: f64, tyx: f64, expected: f64, what: &str| {
        let got = acceptance(fx, fy, txy, tyx);
        assert!(
            close(got, expected),
            "{what}: acceptance(f(x) {fx}, f(y) {fy}, T(x->y) {txy}, T(y->x) {tyx}): got {got}, \
             expected {expected}"
        );
    };
    check(1.0, 2.0, 1.0, 1.0, 1.0, "uphill");
    check(2.0, 1.0, 1.0, 1.0, 0.5, "downhill");
    check(1.0, 1.0, 4.0, 1.0, 0.25, "T ratio");
    check(
        3.0,
        2.0,
        0.5,
        0.25,
        (2.0 * 0.25) / (3.0 * 0.5),
        "both ratios",
    );
    check(1.0, 0.0, 1.0, 1.0, 0.0, "f(y) = 0");
    check(1.0, 1.0, 1.0, 0.0, 0.0, "T(y -> x) = 0");
    check(1.0, 1.0, 0.0, 1.0, 0.0, "T(x -> y) = 0");
    check(0.0, 1.0, 1.0, 1.0, 1.0, "leaving f(x) = 0");
    for (fx, fy, txy, tyx) in [
        (1.0, 2.0, 0.3, 0.7),
        (5.0, 0.1, 2.0, 0.01),
        (0.4, 0.4, 1.0, 3.0),
    ] {
        let lhs = fx * txy * acceptance(fx, fy, txy, tyx);
        let rhs = fy * tyx * acceptance(fy, fx, tyx, txy);
        assert!(
            close(lhs, rhs),
            "detailed balance: f(x) T(x->y) a(x->y) = {lhs}, expected f(y) T(y->x) a(y->x) = {rhs}"
        );
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
        let got = d.pdf(x);
        assert!(
            (got - expected).abs() < 1e-6 * expected,
            "p({x}): got {got}, expected 1 / (D ln(max/min)) = {expected}"
        );
    }
    assert_eq!(d.pdf(0.001), 0.0, "p(D) below min: expected 0");
    assert_eq!(d.pdf(2.0), 0.0, "p(D) above max: expected 0");
    // int p(D) dD over [min, max], in s = ln D where dD = D ds
    let n = 10_000;
    let h = ln_ratio / n as f64;
    let integral: f64 = (0..n)
        .map(|i| {
            let dd = ((min as f64).ln() + (i as f64 + 0.5) * h).exp();
            d.pdf(dd as f32) * dd * h
        })
        .sum();
    assert!(
        (integral - 1.0).abs() < 1e-4,
        "integral of p(D): got {integral}, expected 1"
    );
    let bins = 10;
    let mut counts = vec![0usize; bins];
    let samples = 100_000;
    for i in 0..samples {
        let x = d.sample((i as f32 + 0.5) / samples as f32);
        assert!(
            (min * 0.999..=max * 1.001).contains(&x),
            "sample({u}): got D = {x}, expected D in [{min}, {max}]",
            u = (i as f32 + 0.5) / samples as f32
        );
        let b = (((x / min) as f64).ln() / ln_ratio * bins as f64) as usize;
        counts[b.min(bins - 1)] += 1;
    }
    // the u are stratified, not random: D(u) is monotone, so each bin of equal width in ln D
    // holds exactly a tenth of the u, up to the one u at each edge that f32 rounding may move
    for (b, c) in counts.iter().enumerate() {
        assert!(
            c.abs_diff(samples / bins) <= 1,
            "bin {b} of ln D: got {c} samples, expected {} (+-1)",
            samples / bins
        );
    }
}

/// The probability of the lobe at a specular vertex (the Dirac-free density a bidirectional
/// mutation gives a direction through glass or a mirror) against Fresnel's equations in f64:
/// light leaving a glass surface (ior 1.5) at cos 0.8 towards the reflection takes the
/// reflection lobe with probability F, towards the refraction the transmission lobe with
/// 1 - F; a mirror reflects with probability one; any direction off both laws has zero.
#[test]
fn lobe_probability_is_fresnel_at_glass_and_one_at_a_mirror() {
    use pathspace::bsdf::TransportMode;
    use pathspace::integrator::mlt::contribution::lobe_probability;
    use pathspace::path::VertexKind;
    let scene = Scene::load(&SceneSource::embedded(
        "lobes.toml",
        r#"
[materials.glass]
type = "dielectric"
ior = 1.5
[materials.chrome]
type = "mirror"
[[shapes]]
type = "quad"
origin = [-1.0, 0.0, -1.0]
u = [0.0, 0.0, 2.0]
v = [2.0, 0.0, 0.0]
material = "glass"
[[shapes]]
type = "quad"
origin = [-1.0, 3.0, -1.0]
u = [0.0, 0.0, 2.0]
v = [2.0, 0.0, 0.0]
material = "chrome"
[[lights]]
type = "point"
position = [0.0, 1.0, 0.0]
intensity = 1.0
[[sensors]]
type = "irradiance_meter"
name = "M"
origin = [-0.1, 2.0, -0.1]
u = [0.0, 0.0, 0.2]
v = [0.2, 0.0, 0.0]
"#,
    ))
    .unwrap();
    let (cos_i, eta) = (0.8f64, 1.5f64);
    let cos_t = (1.0 - (1.0 - cos_i * cos_i) / (eta * eta)).sqrt();
    let r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let fresnel = 0.5 * (r_s * r_s + r_p * r_p);
    for (prim, p, n) in [
        (0u32, Vec3::ZERO, Vec3::Y),
        (1, Vec3::new(0.0, 3.0, 0.0), Vec3::Y),
    ] {
        let v = Vertex::new(VertexKind::Surface { prim }, p, n, None, None);
        let from = p + Vec3::new(0.6, 0.8, 0.0);
        let reflected = p + Vec3::new(-0.6, 0.8, 0.0);
        let refracted = p + Vec3::new(-0.6 / eta as f32, -cos_t as f32, 0.0);
        let off = p + Vec3::new(0.0, 1.0, 0.0);
        let (r, t) = if prim == 0 {
            (fresnel, 1.0 - fresnel)
        } else {
            (1.0, 0.0)
        };
        for mode in [TransportMode::Radiance, TransportMode::Importance] {
            for (what, to, expect) in [
                ("reflection", reflected, r),
                ("refraction", refracted, t),
                ("off both laws", off, 0.0),
            ] {
                let got =
                    lobe_probability(&scene, &pathspace::path::PLAIN, &v, from, to, mode) as f64;
                assert!(
                    (got - expect).abs() < 1e-5,
                    "prim {prim} {mode:?}, {what}: {got}, expected {expect}"
                );
            }
        }
    }
}

// The modules of `src/integrator/mlt/` (the layout: tests/repository/index.rs).
mod mutation;
