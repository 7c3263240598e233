//! Enlightened local path sampling, the guiding half (Kristensen 2010, sec. 5.2.3-5.3, and
//! the medium extension): equal-area maps (density integrates to one, sampler against density
//! by chi-square, texel round trip), the kd-tree and the regions of eq. (5.16), the guided
//! mixtures at surface and medium vertices in both modes (density integrates to one, sampler
//! against density), the walks' cached densities against `path::pdf::densities`, MIS weights
//! with guiding on, and guided BDPT and MLT against unguided BDPT over independent runs.

use crate::common;

use std::sync::Arc;

use glam::{Vec2, Vec3};
use pathspace::bidir::WalkLimits;
use pathspace::bsdf::TransportMode;
use pathspace::enlightened::guide::build_guide;
use pathspace::enlightened::regions::{surface_distance, KdTree};
use pathspace::enlightened::{
    DirectionMap, Enlightened, GuideKind, GuideSettings, RegionParams, RegionPoint, Regions,
};
use pathspace::integrator::bdpt::{mis_weight_of_path, Bdpt, MisHeuristic, Scratch, Strategies};
use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::math::{Frame, Sampler};
use pathspace::path::pdf::{densities, strategy_pdf};
use pathspace::path::{measurement_contribution, LocalSampling, Path, Vertex, VertexKind, PLAIN};
use pathspace::scene::{Scene, SceneSource};

use common::stats::Family;
use common::SphereGrid;

/// The world frame: the maps' (cos theta, phi) are those of +z and atan2(y, x).
fn world() -> Frame {
    Frame {
        s: Vec3::X,
        t: Vec3::Y,
        n: Vec3::Z,
    }
}

/// Expected counts of `n_samples` directions from density `pdf` in the bins of `grid` (whose
/// `n_cos` x `n_phi` bins subdivide the maps' texels), by the midpoint rule on `sub` x `sub`
/// cells per bin: exact for the piecewise-constant maps (no evaluation on a texel border,
/// where Simpson's end points would read the neighbour texel), second order for the smooth
/// BSDF and phase-function parts.
fn expected_midpoint(grid: &SphereGrid, pdf: impl Fn(Vec3) -> f64, sub: usize, n: u64) -> Vec<f64> {
    let (nc, np) = (grid.n_cos, grid.n_phi);
    let dc = 2.0 / (nc * sub) as f64;
    let dp = std::f64::consts::TAU / (np * sub) as f64;
    let mut out = vec![0.0; nc * np];
    for i in 0..nc * sub {
        let c = -1.0 + dc * (i as f64 + 0.5);
        for j in 0..np * sub {
            let phi = dp * (j as f64 + 0.5);
            let w = common::direction(&grid.frame, c, phi);
            out[(i / sub) * np + j / sub] += pdf(w) * dc * dp * n as f64;
        }
    }
    out
}

/// A map with random, partly zero weights.
fn random_map(cols: u32, rows: u32, seed: u64) -> DirectionMap {
    let mut m = DirectionMap::new(cols, rows);
    let mut s = Sampler::new(seed, 0, 0);
    for _ in 0..(cols * rows * 4) {
        let w = DirectionMap::direction_at(s.next_2d());
        // a peaked weight: some texels get almost nothing, many none
        if s.next_f32() < 0.7 {
            m.splat(w, s.next_f32().powi(4));
        }
    }
    m.build();
    m
}

#[test]
fn direction_map_texels_round_trip() {
    for (cols, rows) in [(8, 4), (32, 16), (7, 5)] {
        let m = DirectionMap::new(cols, rows);
        for r in 0..rows {
            for c in 0..cols {
                let uv = Vec2::new(
                    (c as f32 + 0.5) / cols as f32,
                    (r as f32 + 0.5) / rows as f32,
                );
                let w = DirectionMap::direction_at(uv);
                assert!((w.length() - 1.0).abs() < 1e-5);
                let got = m.texel_of(w);
                assert_eq!(
                    got,
                    (c, r),
                    "{cols}x{rows} map, the direction {w} at the centre of texel ({c}, {r}): got \
                     texel {got:?}, expected ({c}, {r})"
                );
            }
        }
    }
}

/// Every texel subtends 4 pi / n, so the density integrates to one exactly when summed over
/// texel centres; a Monte Carlo integral over uniform directions agrees within its error.
#[test]
fn direction_map_pdf_integrates_to_one() {
    let mut fam = Family::new("guiding: direction map pdf integrates to one");
    for (cols, rows) in [(8, 4), (16, 8), (32, 16)] {
        let m = random_map(cols, rows, 3);
        let n = (cols * rows) as f64;
        let mut sum = 0.0f64;
        for r in 0..rows {
            for c in 0..cols {
                let uv = Vec2::new(
                    (c as f32 + 0.5) / cols as f32,
                    (r as f32 + 0.5) / rows as f32,
                );
                sum +=
                    m.pdf(DirectionMap::direction_at(uv)) as f64 * 4.0 * std::f64::consts::PI / n;
            }
        }
        assert!((sum - 1.0).abs() < 1e-5, "{cols}x{rows}: sum {sum}");
        let mut s = Sampler::new(5, 1, 0);
        let xs: Vec<f64> = (0..200_000)
            .map(|_| {
                let w = DirectionMap::direction_at(s.next_2d());
                m.pdf(w) as f64 * 4.0 * std::f64::consts::PI
            })
            .collect();
        let (mean, se) = common::mean_and_stderr(&xs);
        let dof = (xs.len() - 1) as f64;
        fam.mean_is(
            &format!("{cols}x{rows}: pdf over the sphere"),
            mean,
            se,
            dof,
            1.0,
        );
    }
    fam.finish();
}

/// Chi-square over a grid twice as fine as the texels: the texel choice and the uniform
/// position inside the texel both follow the density.
#[test]
fn direction_map_sampler_agrees_with_pdf() {
    let m = random_map(16, 8, 9);
    let grid = SphereGrid::new(world(), 16, 32);
    let mut s = Sampler::new(11, 0, 0);
    let n = 200_000;
    let observed = grid.observe(
        || {
            let (w, p) = m.sample(s.next_2d())?;
            assert!(
                (p - m.pdf(w)).abs() <= 1e-4 * p,
                "returned pdf {p} vs {}",
                m.pdf(w)
            );
            Some(w)
        },
        n,
    );
    let expected = expected_midpoint(&grid, |w| m.pdf(w) as f64, 1, n);
    let mut fam = Family::new("guiding: direction map sampler vs pdf");
    fam.chi_square("map sampler", &observed, &expected);
    fam.finish();
    // an empty map cannot be sampled and has density zero
    let mut e = DirectionMap::new(4, 2);
    e.build();
    assert!(e.sample(Vec2::splat(0.3)).is_none());
    assert_eq!(e.pdf(Vec3::Z), 0.0);
}

#[test]
fn kd_tree_nearest_matches_brute_force() {
    let mut s = Sampler::new(1, 2, 3);
    let pts: Vec<Vec3> = (0..500)
        .map(|_| Vec3::new(s.next_f32(), s.next_f32(), s.next_f32() * 0.1))
        .collect();
    let tree = KdTree::build(&pts);
    for _ in 0..300 {
        let q = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32()) * 1.2 - 0.1;
        let mut buf = [(0.0f32, 0u32); 5];
        assert_eq!(tree.nearest(q, &mut buf), 5);
        let mut brute: Vec<(f32, u32)> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| ((*p - q).length_squared(), i as u32))
            .collect();
        brute.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(&buf[..], &brute[..5]);
    }
}

/// Two coincident walls facing opposite ways (a thin table top and the floor under it) stay in
/// different regions by eq. (5.16); volume points of two interleaved media never share a
/// region; the result is the same on a second build.
#[test]
fn regions_separate_normals_and_media() {
    let mut s = Sampler::new(4, 0, 0);
    let mut pts = Vec::new();
    for i in 0..4000 {
        let p = Vec3::new(s.next_f32(), 0.0, s.next_f32());
        let n = if i % 2 == 0 { Vec3::Y } else { -Vec3::Y };
        pts.push(RegionPoint { p, n, medium: None });
        let q = Vec3::new(s.next_f32(), 1.0 + s.next_f32(), s.next_f32());
        pts.push(RegionPoint {
            p: q,
            n: Vec3::ZERO,
            medium: Some((i % 2) as u32),
        });
    }
    // alpha = 1: turning a normal around (cost 2) outweighs any distance in the unit square,
    // so eq. (5.16) must keep the two sides apart
    let params = RegionParams {
        regions: 64,
        alpha: 1.0,
        candidates: 16,
        ..RegionParams::for_radius(1.0)
    };
    let regions = Regions::build(&pts, params);
    let again = Regions::build(&pts, params);
    assert_eq!(regions.len(), 64);
    assert!(regions.surface_len() > 0 && regions.surface_len() < 64);
    for x in &pts {
        let r = regions.region_of(x).expect("every point has a region");
        assert_eq!(Some(r), again.region_of(x), "deterministic");
        if x.medium.is_none() {
            assert!((r as usize) < regions.surface_len());
        } else {
            assert!((r as usize) >= regions.surface_len());
        }
    }
    // up-facing and down-facing floor points never share a region
    let mut up = std::collections::HashSet::new();
    let mut down = std::collections::HashSet::new();
    for x in pts.iter().filter(|x| x.medium.is_none()) {
        let r = regions.region_of(x).unwrap();
        if x.n == Vec3::Y {
            up.insert(r);
        } else {
            down.insert(r);
        }
    }
    assert!(up.is_disjoint(&down), "regions mix opposite normals");
    // the media never share a region
    let mut m0 = std::collections::HashSet::new();
    let mut m1 = std::collections::HashSet::new();
    for x in pts.iter().filter(|x| x.medium.is_some()) {
        let r = regions.region_of(x).unwrap();
        if x.medium == Some(0) {
            m0.insert(r);
        } else {
            m1.insert(r);
        }
    }
    assert!(m0.is_disjoint(&m1), "regions mix media");
    assert!(regions.volume_region(Vec3::ONE, 7).is_none());
    // eq. (5.16) itself
    assert_eq!(
        surface_distance(2.0, Vec3::ZERO, Vec3::Y, Vec3::X, Vec3::Y),
        2.0
    );
    assert_eq!(
        surface_distance(2.0, Vec3::ZERO, Vec3::Y, Vec3::ZERO, -Vec3::Y),
        2.0
    );
}

/// The fog box at `w` x `w` pixels.
fn fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

/// The guide weight c of the tests' guides: the map's share of the mixtures (eq. 5.18) and of
/// the guided lobe choice. Not the default 0.5, at which c and 1 - c are equal, so that
/// exchanging them (in a density, in a sampler, or in both) changed nothing any test sees.
const GUIDE_WEIGHT: f32 = 0.3;

/// A scene with the enlightened technique that guides it.
type Guided = (Scene, Enlightened);

/// The technique of a guide alone (no adjoint image).
fn guiding(guide: pathspace::enlightened::Guide) -> Enlightened {
    Enlightened {
        guide: Some(Arc::new(guide)),
        adjoint: None,
    }
}

/// A cheap, coarse guide of `kind` for `scene` (`particles` subpaths of each kind, 64 regions,
/// 16x8 maps, guide weight [`GUIDE_WEIGHT`]).
fn with_guide(scene: Scene, kind: GuideKind, particles: usize) -> Guided {
    let mut settings = GuideSettings::for_radius(scene.radius);
    settings.c_guide = GUIDE_WEIGHT;
    settings.kind = kind;
    settings.particles = particles;
    settings.regions.regions = 64;
    settings.cols = 16;
    settings.rows = 8;
    let technique = guiding(build_guide(&scene, &PLAIN, settings));
    (scene, technique)
}

/// The fog box with a guide of `kind`.
fn guided_fog_box(w: u32, kind: GuideKind) -> Guided {
    with_guide(fog_box(w), kind, 20_000)
}

/// Guided vertices of eye walks in the fog box: surface and medium vertices with a map in both
/// modes, and the direction they were reached from.
fn guided_vertices(
    (scene, tech): (&Scene, &Enlightened),
    want_medium: bool,
    count: usize,
) -> Vec<(Vertex, Vec3)> {
    let g = tech.guide.as_deref().unwrap();
    let b = Bdpt::new(tech, Some(4), Strategies::All);
    let mut s = Sampler::new(21, 0, 0);
    let mut out = Vec::new();
    let mut eye = Vec::new();
    let cam = scene.camera.as_ref().unwrap();
    for _ in 0..5000 {
        let raster = s.next_2d() * Vec2::new(cam.width as f32, cam.height as f32);
        b.camera_subpath(scene, raster, WalkLimits::BDPT, &mut s, &mut eye);
        for i in 1..eye.len() {
            let v = eye[i];
            if v.is_medium() != want_medium {
                continue;
            }
            if g.map_at(scene, &v, TransportMode::Radiance).is_some()
                && g.map_at(scene, &v, TransportMode::Importance).is_some()
            {
                out.push((v, (eye[i - 1].p - v.p).normalize()));
                break;
            }
        }
        if out.len() == count {
            break;
        }
    }
    assert_eq!(out.len(), count, "too few guided vertices");
    out
}

/// Eqs. (5.18), (5.19) and the phase-function mixtures: each density integrates to one over
/// the sphere (quadrature on a grid aligned with the maps' texels) and the one-sample mixture
/// sampler follows it (chi-square), at surface and medium vertices, in both modes.
#[test]
fn guided_mixture_pdfs_integrate_to_one_and_match_their_samplers() {
    let (scene, tech) = guided_fog_box(8, GuideKind::Both);
    let mut fam = Family::new("guiding: guided mixtures vs their samplers");
    for want_medium in [false, true] {
        for (k, (v, wo)) in guided_vertices((&scene, &tech), want_medium, 3)
            .into_iter()
            .enumerate()
        {
            for mode in [TransportMode::Radiance, TransportMode::Importance] {
                let what = format!(
                    "{} vertex {k} {mode:?}",
                    if want_medium { "medium" } else { "surface" }
                );
                let grid = SphereGrid::new(world(), 16, 32);
                let pdf = |w: Vec3| tech.scatter_pdf(&scene, &v, wo, w, mode) as f64;
                check_mixture_weights((&scene, &tech), &v, wo, mode);
                let n = 100_000;
                let expected = expected_midpoint(&grid, pdf, 6, n);
                let mass: f64 = expected.iter().sum::<f64>() / n as f64;
                assert!((mass - 1.0).abs() < 2e-3, "{what}: integral {mass}");
                let mut s = Sampler::new(31, k as u64, want_medium as u64);
                let observed = grid.observe(
                    || {
                        let ss = tech.sample_scatter(&scene, &v, wo, mode, &mut s)?;
                        let p = tech.scatter_pdf(&scene, &v, wo, ss.wi, mode);
                        assert!((ss.pdf - p).abs() <= 1e-4 * p, "{what}: {} vs {p}", ss.pdf);
                        Some(ss.wi)
                    },
                    n,
                );
                fam.chi_square(&what, &observed, &expected);
            }
        }
    }
    fam.finish();
}

/// Eq. (5.18) and its medium form: the guided density is (1 - c) p_local + c p_map with c the
/// guide weight (the map's share), at the vertex's own BSDF or phase-function density and its
/// region's map; deterministic (f32 rounding of one sum of two products).
fn check_mixture_weights(
    (scene, tech): (&Scene, &Enlightened),
    v: &Vertex,
    wo: Vec3,
    mode: TransportMode,
) {
    let g = tech.guide.as_deref().unwrap();
    let c = g.settings.c_guide;
    assert_eq!(c, GUIDE_WEIGHT);
    let (map, _) = g.map_at(scene, v, mode).expect("a guided vertex");
    for wi in common::test_directions(61, 32) {
        let local = match v.kind {
            VertexKind::Surface { .. } => v.bsdf(scene).unwrap().pdf(wo, wi, v.n),
            VertexKind::Medium { medium } => scene.media[medium as usize].phase().pdf(wo, wi),
            _ => unreachable!("guided vertices are surface or medium vertices"),
        };
        let want = (1.0 - c) * local + c * map.pdf(wi);
        let got = tech.scatter_pdf(scene, v, wo, wi, mode);
        assert!(
            (got - want).abs() <= 4.0 * f32::EPSILON * want,
            "{mode:?}: guided density {got}, (1 - c) p_local + c p_map = {want}"
        );
    }
}

/// Relative tolerance of cached against recomputed densities.
const TOL: f32 = 1e-2;

/// Eye walks with guiding on: the densities the walk cached (forward and reverse) equal the
/// densities recomputed from the finished path by `path::pdf::densities`, which is what BDPT's
/// MIS and MLT's transition densities evaluate.
#[test]
fn guided_walk_densities_match_path_densities() {
    // unguided first: the same check and tolerance hold without the guide
    check_walk_densities(&fog_box(8), &Enlightened::default());
    let (scene, tech) = guided_fog_box(8, GuideKind::Both);
    check_walk_densities(&scene, &tech);
}

fn check_walk_densities(scene: &Scene, tech: &Enlightened) {
    let b = Bdpt::new(tech, Some(5), Strategies::All);
    let mut s = Sampler::new(41, 0, 0);
    let mut scratch = Scratch::default();
    let cam = scene.camera.as_ref().unwrap();
    let (mut checked, mut guided_medium, mut vertices, mut impassable) = (0, 0, 0u64, 0u64);
    let mut off: Vec<String> = Vec::new();
    for _ in 0..4000 {
        let raster = s.next_2d() * Vec2::new(cam.width as f32, cam.height as f32);
        b.camera_subpath(scene, raster, WalkLimits::BDPT, &mut s, &mut scratch.eye);
        b.light_subpath(scene, WalkLimits::BDPT, &mut s, &mut scratch.light);
        let (light, eye) = (&scratch.light, &scratch.eye);
        if light.len() < 3 || eye.len() < 3 {
            continue;
        }
        // a full path: the whole light subpath joined to the whole eye subpath
        let mut verts: Vec<Vertex> = light.clone();
        verts.extend(eye.iter().rev().copied());
        let path = Path { vertices: verts };
        let d = densities(scene, tech, &path, &mut s);
        let n = path.vertices.len();
        // f32 free-flight exponentials over edges from lifted origins put up to a few 1e-3
        // between walk and recomputation (the unguided walk in the fog box shows the same);
        // a wrong mixture weight or map is off by tens of percent
        let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-12);
        // an edge between two vertices on the fog's null boundary (coplanar with the walls)
        // can be found impassable when recomputed (propagation pdf zero) although the walk
        // crossed it: a rare geometric edge case of `Scene::edge`, present without guiding
        // too; such vertices are counted, not compared
        let mut compare = |what: &str, i: usize, recomputed: f32, cached: f32, prop: f32| {
            vertices += 1;
            if prop == 0.0 {
                impassable += 1;
                return;
            }
            if rel(recomputed, cached) >= TOL {
                // the direction recomputed from two positions can fall into the neighbouring
                // texel of a map when the sampled one lay on its border (short edges amplify
                // the positions' rounding): rare and never systematic
                off.push(format!(
                    "{what} x_{i}: recomputed {recomputed} vs cached {cached}"
                ));
            }
        };
        for (i, lv) in light.iter().enumerate().skip(1) {
            compare("light fwd", i, d.light[i], lv.pdf_fwd, d.prop_up[i - 1]);
            if i + 2 < light.len() {
                compare("light rev", i, d.eye[i], lv.pdf_rev, d.prop_down[i]);
            }
        }
        for (k, ev) in eye.iter().enumerate().skip(1) {
            let i = n - 1 - k;
            compare("eye fwd", i, d.eye[i], ev.pdf_fwd, d.prop_down[i]);
            if k + 2 < eye.len() {
                compare("eye rev", i, d.light[i], ev.pdf_rev, d.prop_up[i - 1]);
            }
            if ev.is_medium() {
                guided_medium += 1;
            }
        }
        checked += 1;
    }
    assert!(
        checked > 200 && guided_medium > 100,
        "{checked} paths, {guided_medium} medium vertices"
    );
    assert!(
        impassable * 100 < vertices,
        "{impassable} of {vertices} edges impassable when recomputed"
    );
    assert!(
        (off.len() as u64) * 200 < vertices,
        "guided: {}; {} of {vertices} densities disagree: {:?}",
        tech.guide.is_some(),
        off.len(),
        &off[..off.len().min(5)]
    );
    eprintln!(
        "guided {}: {vertices} densities, {} off by >= {TOL}, {impassable} impassable",
        tech.guide.is_some(),
        off.len()
    );
}

/// With guiding on, the weights of all strategies of a path sum to one and equal
/// p_s^beta / sum p_i^beta from the guided densities, by the balance (beta = 1) and the power
/// heuristic (beta = 2).
#[test]
fn guided_mis_weights_sum_to_one() {
    let (scene, tech) = guided_fog_box(8, GuideKind::Both);
    for (h, beta) in [(MisHeuristic::Balance, 1), (MisHeuristic::Power, 2)] {
        let b = Bdpt::new(&tech, Some(5), Strategies::All).with_heuristic(h);
        guided_weights_match(&scene, &b, beta);
    }
}

fn guided_weights_match(scene: &Scene, b: &Bdpt, beta: i32) {
    let mut s = Sampler::new(43, 0, 0);
    let mut scratch = Scratch::default();
    let cam = scene.camera.as_ref().unwrap();
    let mut checked = 0;
    for _ in 0..3000 {
        let raster = s.next_2d() * Vec2::new(cam.width as f32, cam.height as f32);
        b.camera_subpath(scene, raster, WalkLimits::BDPT, &mut s, &mut scratch.eye);
        b.light_subpath(scene, WalkLimits::BDPT, &mut s, &mut scratch.light);
        if scratch.light.len() < 2 || scratch.eye.len() < 2 {
            continue;
        }
        let mut verts: Vec<Vertex> = scratch.light[..2].to_vec();
        verts.extend(scratch.eye.iter().rev().copied());
        let path = Path { vertices: verts };
        if measurement_contribution(scene, &path, &mut s) == Vec3::ZERO {
            continue;
        }
        let d = densities(scene, b.tech, &path, &mut s);
        let n = path.vertices.len();
        let p: Vec<f64> = (0..n).map(|k| strategy_pdf(&d, k)).collect();
        let total: f64 = p.iter().map(|x| x.powi(beta)).sum();
        if !(total > 0.0 && total.is_finite()) {
            continue;
        }
        let mut sum = 0.0;
        for (k, pk) in p.iter().enumerate() {
            let w = mis_weight_of_path(b, scene, &path, k, &d) as f64;
            let want = pk.powi(beta) / total;
            assert!((w - want).abs() < 1e-3, "s={k}: {w} vs {want}");
            sum += w;
        }
        assert!((sum - 1.0).abs() < 1e-3, "weights sum to {sum}");
        checked += 1;
    }
    assert!(checked > 200, "only {checked} paths");
}

/// Independent BDPT renders per quadrant comparison and their samples per pixel (the standard
/// error is Student-t over the runs: many short runs see more than a few long ones).
const RUNS: u64 = 64;
const SPP: u32 = 8;
/// Independent MLT renders per quadrant comparison, and their mutations per pixel.
const MLT_RUNS: u64 = 32;
const MLT_MUTATIONS: u64 = 64;
const RES: u32 = 8;
const DEPTH: u32 = 4;

fn bdpt_runs(scene: &Scene, tech: &dyn LocalSampling, seed: u64) -> Vec<Vec<f64>> {
    common::bdpt_quadrant_runs((scene, tech), RUNS, seed, DEPTH, SPP)
}

fn mlt_runs(scene: &Scene, tech: &dyn LocalSampling, seed: u64) -> Vec<Vec<f64>> {
    common::mlt_quadrant_runs_with((scene, tech), MLT_RUNS, seed, DEPTH, MLT_MUTATIONS)
}

/// Guided BDPT (surface guiding; surface and volume guiding) agrees with unguided BDPT on the
/// fog box, a scene with a medium, over independent runs.
#[test]
fn guided_bdpt_agrees_with_unguided_bdpt() {
    let mut fam = Family::new("guiding: guided bdpt vs bdpt");
    let plain = bdpt_runs(&fog_box(RES), &PLAIN, 1000);
    for kind in [GuideKind::Surface, GuideKind::Both] {
        let (scene, tech) = guided_fog_box(RES, kind);
        let guided = bdpt_runs(&scene, &tech, 5000);
        common::quadrants_agree(
            &mut fam,
            &pathspace::conventions::OptionValue::name(kind),
            &guided,
            &plain,
        );
    }
    // guided Russian roulette (sec. 5.3.4) on top: survival from the maps, still unbiased
    let scene = fog_box(RES);
    let mut settings = GuideSettings::for_radius(scene.radius);
    settings.kind = GuideKind::Both;
    settings.particles = 20_000;
    settings.regions.regions = 64;
    settings.roulette = Some(0.5);
    settings.c_guide = GUIDE_WEIGHT;
    let tech = guiding(build_guide(&scene, &PLAIN, settings));
    let deep = |scene: &Scene, tech: &dyn LocalSampling, seed: u64| -> Vec<Vec<f64>> {
        (0..RUNS)
            .map(|r| {
                let mut rd =
                    Renderer::try_with(scene, tech, IntegratorKind::Bdpt, seed + r, Some(8))
                        .unwrap();
                rd.pass(SPP, &|| {});
                common::quadrant_means(&rd.film.as_ref().unwrap().image())
            })
            .collect()
    };
    common::quadrants_agree(
        &mut fam,
        "guided roulette",
        &deep(&scene, &tech, 6000),
        &deep(&fog_box(RES), &PLAIN, 1000),
    );
    fam.finish();
}

/// Guided roulette (sec. 5.3.4) keeps the thesis's rule q = alpha beta'/beta_0 Lhat inside its
/// bounds, and never lets a survivor carry more than `ROULETTE_MAX_WEIGHT` times the walk's
/// starting throughput: without that window a map that underrates a direction gives q = 0.05
/// there, survivors 20 times heavier at each vertex, and an estimator whose runs are so skewed
/// that their mean sits below the truth in most finite samples.
#[test]
fn guided_roulette_follows_the_maps_within_a_weight_window() {
    use pathspace::enlightened::guide::{
        roulette_survival, ROULETTE_MAX_WEIGHT, ROULETTE_MIN_SURVIVAL,
    };
    let scene = fog_box(RES);
    let mut settings = GuideSettings::for_radius(scene.radius);
    settings.kind = GuideKind::Both;
    settings.particles = 2_000;
    settings.regions.regions = 16;
    settings.roulette = Some(2.0);
    let guide = build_guide(&scene, &PLAIN, settings);
    let q_max = 0.95;
    for ratio in [0.01f32, 0.1, 0.5, 1.0, 2.0, 3.0, 3.9, 10.0] {
        for lhat in [0.0f32, 1e-3, 0.05, 0.2, 1.0, 10.0, f32::NAN] {
            let q = roulette_survival(&guide, Some(lhat), ratio, q_max).unwrap();
            assert!((ROULETTE_MIN_SURVIVAL..=q_max).contains(&q), "q = {q}");
            let window = (ratio / ROULETTE_MAX_WEIGHT).max(ROULETTE_MIN_SURVIVAL);
            let expected = if lhat.is_nan() {
                q_max
            } else {
                (2.0 * ratio * lhat).clamp(window.min(q_max), q_max)
            };
            assert_eq!(q, expected, "ratio {ratio}, Lhat {lhat}");
            let heaviest = ROULETTE_MAX_WEIGHT.max(ratio / q_max);
            assert!(ratio / q <= heaviest * (1.0 + 1e-6), "ratio {ratio}, q {q}");
        }
    }
}

/// Guided MLT (surface and volume guiding in every subpath the bidirectional mutation
/// regenerates, and in its transition densities) agrees with unguided BDPT.
#[test]
fn guided_mlt_agrees_with_bdpt() {
    let plain = bdpt_runs(&fog_box(RES), &PLAIN, 3000);
    let (scene, tech) = guided_fog_box(RES, GuideKind::Both);
    let mut fam = Family::new("guiding: guided mlt vs bdpt");
    common::quadrants_agree(
        &mut fam,
        "guided mlt",
        &mlt_runs(&scene, &tech, 7000),
        &plain,
    );
    fam.finish();
}

/// Guiding off leaves the renderers' random streams untouched: an unguided scene renders the
/// same image whether or not a guide of kind `off` is installed.
#[test]
fn guide_off_changes_nothing() {
    let plain = fog_box(RES);
    let (off, off_tech) = guided_fog_box(RES, GuideKind::Off);
    let render = |scene: &Scene, tech: &dyn LocalSampling| {
        let mut rd =
            Renderer::try_with(scene, tech, IntegratorKind::Bdpt, 77, Some(DEPTH)).unwrap();
        rd.pass(4, &|| {});
        rd.film.as_ref().unwrap().image().pixels
    };
    assert_eq!(render(&plain, &PLAIN), render(&off, &off_tech));
}

/// `[render.guide]` is read and every bad value is reported at its key.
#[test]
fn render_guide_table_is_parsed_and_checked() {
    let load = |extra: &str| {
        let text = format!("{}\n[render.guide]\n{extra}\n", pathspace::scene::FOG_BOX);
        pathspace::integrator::settings::load(&SceneSource::embedded("guide.toml", &text))
    };
    let s = load("vertices = \"both\"\nmap = \"16x8\"\nregions = 128\nparticles = 1000\nweight = 0.25\nroulette = 2.0\nsampler = \"metropolis\"\nsigma = 0.03\ndefensive = 0.25").unwrap();
    let g = s.1.guide;
    assert_eq!(
        g.sampler,
        pathspace::enlightened::guide::ParticleSampler::Metropolis
    );
    assert_eq!((g.metropolis.sigma, g.metropolis.defensive), (0.03, 0.25));
    assert_eq!(
        (g.kind, g.cols, g.rows, g.regions.regions, g.particles),
        (GuideKind::Both, 16, 8, 128, 1000)
    );
    assert_eq!((g.c_guide, g.roulette), (0.25, Some(2.0)));
    for (extra, key, word) in [
        ("weight = 1.0", "render.guide.weight", "(0, 1)"),
        ("vertices = \"walls\"", "render.guide.vertices", "surface"),
        ("map = \"32by16\"", "render.guide.map", "COLSxROWS"),
        ("regions = 0", "render.guide.regions", "1..="),
        ("alpha = -1.0", "render.guide.alpha", "positive"),
        ("roulete = 1.0", "render.guide.roulete", "unknown field"),
        ("sampler = \"pssmlt\"", "render.guide.sampler", "metropolis"),
        ("sigma = 1.5", "render.guide.sigma", "(0, 1)"),
        ("defensive = -0.5", "render.guide.defensive", ">= 0"),
    ] {
        let e = load(extra)
            .err()
            .unwrap_or_else(|| panic!("`{extra}` loaded"));
        assert_eq!(e.key, key, "{e}");
        assert!(e.message.contains(word), "{e}");
    }
}

/// The guide (particles, k-means, maps) and the guided image are bit-identical whatever the
/// thread count.
#[test]
fn guided_render_is_deterministic_across_thread_counts() {
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (scene, tech) = guided_fog_box(RES, GuideKind::Both);
            let mut rd =
                Renderer::try_with(&scene, &tech, IntegratorKind::Bdpt, 5, Some(DEPTH)).unwrap();
            rd.pass(2, &|| {});
            rd.film.as_ref().unwrap().image().pixels
        })
    };
    assert_eq!(render(1), render(3));
}

/// Eq. (5.17): the guided emission density at area-light points integrates to one and the
/// emission sampler (the light's cosine lobe or, with c2, the importance map) follows it.
#[test]
fn guided_emission_pdf_integrates_to_one_and_matches_its_sampler() {
    use pathspace::enlightened::guide::{emission_pdf, sample_emission};
    use pathspace::math::warp;
    let (scene, tech) = guided_fog_box(8, GuideKind::Surface);
    let g = tech.guide.as_deref().unwrap();
    let b = Bdpt::new(&tech, Some(2), Strategies::All);
    let mut s = Sampler::new(51, 0, 0);
    let mut light = Vec::new();
    let mut points = Vec::new();
    let mut fam = Family::new("guiding: guided emission vs its sampler");
    while points.len() < 2 {
        b.light_subpath(&scene, WalkLimits::BDPT, &mut s, &mut light);
        if let Some(v) = light.first() {
            if points
                .iter()
                .all(|(p, _): &(Vec3, Vec3)| (*p - v.p).length() > 0.05)
            {
                points.push((v.p, v.n));
            }
        }
    }
    for (k, (p, n)) in points.into_iter().enumerate() {
        let cos_pdf = |w: Vec3| (w.dot(n).max(0.0)) * std::f32::consts::FRAC_1_PI;
        let pdf = |w: Vec3| emission_pdf(g, p, n, w, cos_pdf(w)) as f64;
        assert!(
            (pdf(n) - cos_pdf(n) as f64).abs() > 1e-6,
            "the point is guided"
        );
        let grid = SphereGrid::new(world(), 16, 32);
        let count = 100_000;
        let expected = expected_midpoint(&grid, pdf, 6, count);
        let mass: f64 = expected.iter().sum::<f64>() / count as f64;
        assert!(
            (mass - 1.0).abs() < 2e-3,
            "light point {k}: integral {mass}"
        );
        let mut sm = Sampler::new(52, k as u64, 0);
        let frame = Frame::from_normal(n);
        let observed = grid.observe(
            || {
                let u = sm.next_2d();
                let d = frame.to_world(warp::cosine_hemisphere(u));
                let (w, q) = sample_emission(g, (p, n), d, u, cos_pdf, &mut sm)?;
                assert!((q as f64 - pdf(w)).abs() <= 1e-4 * q as f64);
                Some(w)
            },
            count,
        );
        fam.chi_square(
            &format!("emission at light point {k}"),
            &observed,
            &expected,
        );
    }
    fam.finish();
}

/// Guides from indirect particles only and from each particle sampler: all have particles in
/// their maps, and their mixtures still integrate to one.
#[test]
fn guide_options_min_depth_and_particle_samplers() {
    use pathspace::enlightened::guide::ParticleSampler;
    for sampler in [
        ParticleSampler::Classical,
        ParticleSampler::Bidirectional,
        ParticleSampler::Metropolis,
    ] {
        let scene = fog_box(8);
        let mut settings = GuideSettings::for_radius(scene.radius);
        settings.kind = GuideKind::Both;
        settings.particles = match sampler {
            ParticleSampler::Classical => 20_000,
            _ => 200_000,
        };
        settings.regions.regions = 64;
        settings.min_depth = 2;
        settings.sampler = sampler;
        let g = build_guide(&scene, &PLAIN, settings);
        assert!(
            g.stats.photons > 1000 && g.stats.importons > 1000,
            "{sampler:?}: {:?}",
            g.stats
        );
        let all = {
            let mut s = settings;
            s.min_depth = 1;
            build_guide(&scene, &PLAIN, s).stats
        };
        assert!(
            all.photons > g.stats.photons,
            "min_depth 2 drops the direct photons"
        );
        let tech = guiding(g);
        let (v, wo) = guided_vertices((&scene, &tech), true, 1)[0];
        let grid = SphereGrid::new(world(), 16, 32);
        for mode in [TransportMode::Radiance, TransportMode::Importance] {
            let pdf = |w: Vec3| tech.scatter_pdf(&scene, &v, wo, w, mode) as f64;
            let mass: f64 = expected_midpoint(&grid, pdf, 4, 1).iter().sum();
            assert!((mass - 1.0).abs() < 3e-3, "{mode:?}: integral {mass}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Guided lobe choice at glass (Kristensen 2010, sec. 5.3)
// ---------------------------------------------------------------------------------------------

/// The fog box with a glass ball in the fog, at `w` x `w` pixels.
fn glass_fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    ) + "\n[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n\n[[shapes]]\ntype = \"sphere\"\n\
         center = [0.25, -0.55, 0.1]\nradius = 0.4\nmaterial = \"glass\"\nexterior = \"fog\"\n";
    Scene::load(&SceneSource::embedded("glass-fog-box", &text)).unwrap_or_else(|e| panic!("{e}"))
}

/// [`glass_fog_box`], surface-guided.
fn guided_glass_fog_box(w: u32) -> Guided {
    with_guide(glass_fog_box(w), GuideKind::Surface, 40_000)
}

/// At a guided glass vertex the choice between reflection and transmission follows Fresnel
/// times the map in each direction (mixed with plain Fresnel): the sampler picks reflection
/// with the probability `guided_fresnel` states (binomial test), reports it as the sample's
/// pdf, and MLT's transition densities (`lobe_probability`) use the same number, in both
/// modes. The guide does change the choice somewhere, and never to 0 or 1 where Fresnel is
/// strictly between them.
#[test]
fn guided_fresnel_choice_is_sampled_with_the_probability_its_densities_use() {
    use pathspace::bsdf::{Bsdf, Lobe};
    use pathspace::integrator::mlt::contribution::lobe_probability;
    let (scene, tech) = guided_glass_fog_box(16);
    let b = Bdpt::new(&tech, Some(6), Strategies::All);
    let mut s = Sampler::new(31, 0, 0);
    let cam = scene.camera.as_ref().unwrap();
    let mut eye = Vec::new();
    let mut glass = Vec::new();
    for _ in 0..20_000 {
        let raster = s.next_2d() * Vec2::new(cam.width as f32, cam.height as f32);
        b.camera_subpath(&scene, raster, WalkLimits::BDPT, &mut s, &mut eye);
        for i in 1..eye.len() {
            if matches!(eye[i].material(&scene), Some(Bsdf::Dielectric(_))) {
                glass.push((eye[i], (eye[i - 1].p - eye[i].p).normalize()));
                break;
            }
        }
        if glass.len() == 24 {
            break;
        }
    }
    assert_eq!(glass.len(), 24, "too few glass vertices");
    let mut fam = Family::new("guiding: guided Fresnel choice");
    let mut changed = 0;
    for (k, (v, wo)) in glass.iter().enumerate() {
        for mode in [TransportMode::Radiance, TransportMode::Importance] {
            let Some((p_r, r, t)) = tech.lobe_choice(&scene, v, *wo, mode) else {
                continue;
            };
            let f = r.pdf as f64;
            if let Some(t) = &t {
                assert!(p_r > 0.0 && p_r < 1.0, "P(reflect) = {p_r} with F = {f}");
                // sec. 5.3 with the mixture: (1 - c) F + c F L(w_r) / (F L(w_r) + (1 - F)
                // L(w_t)), L the map relative to its mean, c the map's share
                let g = tech.guide.as_deref().unwrap();
                let field = g.field(mode);
                let region = field.regions.surface_region(v.p, v.n).expect("a region");
                let map = &field.maps[region as usize];
                let c = g.settings.c_guide as f64;
                assert_eq!(c, GUIDE_WEIGHT as f64);
                let lr = f * map.relative(r.wi) as f64;
                let lt = (1.0 - f) * map.relative(t.wi) as f64;
                let want = if lr + lt > 0.0 {
                    (1.0 - c) * f + c * lr / (lr + lt)
                } else {
                    f
                };
                assert!(
                    (p_r as f64 - want).abs() <= 1e-6,
                    "P(reflect) = {p_r}, (1 - c) F + c F L_r / (F L_r + (1 - F) L_t) = {want}"
                );
            } else {
                assert_eq!(p_r, 1.0, "total internal reflection");
            }
            if (p_r as f64 - f).abs() > 0.02 {
                changed += 1;
            }
            let n = 4000u64;
            let mut hits = 0;
            let mut sm = Sampler::new(32, k as u64, mode as u64);
            for _ in 0..n {
                let ss = tech
                    .sample_scatter(&scene, v, *wo, mode, &mut sm)
                    .expect("a lobe");
                let want = if ss.lobe == Lobe::SingularReflection {
                    hits += 1;
                    p_r
                } else {
                    1.0 - p_r
                };
                assert!((ss.pdf - want).abs() <= 1e-6, "pdf {} vs {want}", ss.pdf);
                let density = lobe_probability(&scene, &tech, v, v.p + *wo, v.p + ss.wi, mode);
                assert!(
                    (density - want).abs() <= 1e-5,
                    "lobe_probability {density} vs sampled {want}"
                );
            }
            if t.is_some() {
                fam.binomial(&format!("vertex {k} {mode:?}"), hits, n, p_r as f64);
            }
        }
    }
    fam.finish();
    assert!(
        changed >= 4,
        "the maps changed the choice at only {changed} vertices"
    );
}

/// Guided BDPT and guided MLT (surface guiding, with the guided lobe choice at the glass ball)
/// agree with unguided BDPT through glass in fog.
#[test]
fn guided_bdpt_and_mlt_agree_with_bdpt_through_glass() {
    let (scene, tech) = guided_glass_fog_box(RES);
    let reference = bdpt_runs(&glass_fog_box(RES), &PLAIN, 8000);
    let mut fam = Family::new("guiding: guided bdpt and mlt through glass");
    let guided = bdpt_runs(&scene, &tech, 9000);
    common::quadrants_agree(&mut fam, "guided bdpt, glass", &guided, &reference);
    let guided = mlt_runs(&scene, &tech, 9500);
    common::quadrants_agree(&mut fam, "guided mlt, glass", &guided, &reference);
    fam.finish();
}

/// MLT's transition densities divide by the probability of each glass lobe with the mode of
/// the subpath that drew it: at a glass vertex x_j of a full path, the density of x_{j+1} as
/// the light walk's next vertex carries the importance-guided choice, the density of x_{j-1}
/// as the eye walk's next vertex the radiance-guided one (each relative to plain Fresnel, which
/// the unguided densities carry). With the previous test (the walks choose with exactly
/// `guided_fresnel`'s probability), this ties MLT's densities to the walks' frequencies.
#[test]
fn mlt_densities_carry_each_subpaths_guided_lobe_choice() {
    use pathspace::bsdf::{Bsdf, Lobe};
    use pathspace::integrator::mlt::contribution::{lobe_between, singular_densities_in};
    use pathspace::integrator::mlt::init::Bootstrap;
    let (scene, tech) = guided_glass_fog_box(16);
    let bdpt = Bdpt::new(&tech, Some(8), Strategies::All);
    let boot = Bootstrap::run(&scene, &bdpt, 20_000, 5);
    let mut s = Sampler::new(5, 99, 0);
    let (mut checked, mut modes_differ) = (0, 0);
    for _ in 0..2000 {
        let Some(c) = boot.select(s.next_f64()) else {
            break;
        };
        let Some(x) = Bootstrap::path_of(&scene, &bdpt, 5, c) else {
            continue;
        };
        let n = x.len();
        let Some(j) =
            (1..n - 1).find(|&j| matches!(x[j].material(&scene), Some(Bsdf::Dielectric(_))))
        else {
            continue;
        };
        let guided = singular_densities_in(&scene, &tech, &x, 0..n);
        let plain = singular_densities_in(&scene, &PLAIN, &x, 0..n);
        let lobe = lobe_between(&scene, &x[j], x[j - 1].p, x[j + 1].p);
        let choice = |from: Vec3, mode| {
            let (p_r, r, _) = tech.lobe_choice(&scene, &x[j], (from - x[j].p).normalize(), mode)?;
            Some(match lobe {
                Lobe::SingularTransmission => ((1.0 - p_r) / (1.0 - r.pdf)) as f64,
                _ => (p_r / r.pdf) as f64,
            })
        };
        let (Some(light), Some(eye)) = (
            choice(x[j - 1].p, TransportMode::Importance),
            choice(x[j + 1].p, TransportMode::Radiance),
        ) else {
            continue;
        };
        let ratio_light = guided.light[j + 1] as f64 / plain.light[j + 1] as f64;
        let ratio_eye = guided.eye[j - 1] as f64 / plain.eye[j - 1] as f64;
        assert!(
            (ratio_light - light).abs() <= 1e-4 * light,
            "light side: densities {ratio_light}, guided choice {light}"
        );
        assert!(
            (ratio_eye - eye).abs() <= 1e-4 * eye,
            "eye side: densities {ratio_eye}, guided choice {eye}"
        );
        if (light - eye).abs() > 0.05 * light {
            modes_differ += 1;
        }
        checked += 1;
    }
    assert!(checked >= 50, "only {checked} paths through glass");
    assert!(
        modes_differ >= 5,
        "the two modes' choices differ at only {modes_differ} vertices: the test cannot tell them apart"
    );
}
