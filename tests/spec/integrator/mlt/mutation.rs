//! The mutations of Metropolis light transport against their transition densities (Veach 1997
//! sec. 11.3-11.4; Pauly, Kollig, Keller 2000 sec. 5.2), in two ways that a wrong T cannot pass:
//!
//! (a) Proposal histograms. From a fixed path x, many proposals y = sample(x) are binned over a
//!     partition of what the mutation changes (the moved vertices' positions on their surfaces,
//!     in the medium or on the light, crossed with the bidirectional mutation's discrete
//!     choices), and the counts are compared with N times the integral of T(x -> y) over each
//!     cell. The integrals are estimated by importance sampling with a sampler of the test's own
//!     (positions on the known geometry, with a density of its own), so their noise enters the
//!     chi-square; failed proposals (`None`) fall into no cell, so a T that integrates to more
//!     than the success probability fails too.
//!     The bidirectional mutation is tested at k = 1 ..= 5 edges on a box with a large light,
//!     where its s' = 0 term (the eye side reaches the light by itself) carries weight.
//! (b) Stationarity. On the 4 x 4 fog box (and a mirror box for the multi-chain perturbation),
//!     many independent chains of one mutation (plus the bidirectional one, for ergodicity) run
//!     from seed paths and their last states are binned by pixel and path class; the counts
//!     must follow f/b, estimated per cell by an independent path tracer. The fog box without
//!     its ceiling, lit by the sun (a directional light), and the mirror box without its
//!     ceiling, lit by a sky (an environment), check the mutations on paths that start at
//!     infinity.
//!
//! Set `MLT_DEBUG` to list the cells more than 3 standard deviations off.
//!
//! Specular vertices: T keeps the Dirac-free convention of `contribution` (each edge through a
//! mirror contributes g / d^2), so against the area of the chain's end on a planar mirror the
//! real density is T times d1^2 d2^2 / ((d1 + d2)^2 cos_mirror) per mirror vertex (the unfolded
//! edge of the mirror image; Veach 1997 sec. 8.3.2's generalized geometry term).

use crate::common;

use std::sync::OnceLock;

use glam::{Vec2, Vec3};
use pathspace::bsdf::TransportMode;
use pathspace::integrator::mlt::contribution::{
    anchor_infinite, image_contribution, is_specular, same_vertex, scalar_contribution,
    singular_densities,
};
use pathspace::integrator::mlt::init::Bootstrap;
use pathspace::integrator::mlt::mutation::{
    Bidirectional, InverseDistance, LightPerturbation, MultiChainPerturbation, Mutation,
    PropagationPerturbation, SensorPerturbation, Workspace,
};
use pathspace::integrator::mlt::trace::{
    extend, extend_or_escape, sample_direction, sample_light_vertex,
};
use pathspace::integrator::mlt::{Chain, Mlt, MltSettings};
use pathspace::math::{Frame, Sampler};
use pathspace::path::{Vertex, VertexKind};
use pathspace::scene::{Scene, SceneSource};
use rayon::prelude::*;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use common::stats::Family;

// ------------------------------------------------------------------------------------------
// scenes

/// The fog box at `w` x `w` pixels.
fn fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

/// Height of the mirror on the floor of [`mirror_box`].
const MIRROR_Y: f32 = -0.98;

/// The fog box with a planar mirror lying on the floor (x in [-0.6, 0.6], z in [-0.9, 0.8]):
/// the camera sees the back wall in it and the back wall sees the light in it, so the box has
/// L S D S E paths (the multi-chain perturbation's) and lens and caustic chains through it.
fn mirror_box(w: u32) -> Scene {
    let text = mirror_box_text(w);
    Scene::load(&SceneSource::embedded("mirror-box", &text)).expect("valid mirror box")
}

/// The scene text of [`mirror_box`].
fn mirror_box_text(w: u32) -> String {
    pathspace::scene::FOG_BOX
        .replace(
            "resolution = [256, 256]",
            &format!("resolution = [{w}, {w}]"),
        )
        .replace(
            "[materials.white]",
            "[materials.chrome]\ntype = \"mirror\"\n\n[materials.white]",
        )
        + &format!(
            "\n[[shapes]]\ntype = \"quad\"\norigin = [-0.6, {MIRROR_Y}, -0.9]\nu = [0.0, 0.0, 1.7]\nv = [1.2, 0.0, 0.0]\nmaterial = \"chrome\"\n"
        )
}

/// The fog box with the light grown to 1.8 x 1.8 (of the ceiling's 2 x 2): eye subpaths then
/// reach it often, so the bidirectional mutation's s' = 0 term (the eye side finds the light)
/// carries a large share of T.
fn big_light_box(w: u32) -> Scene {
    Scene::load(&SceneSource::embedded(
        "big-light-box",
        &big_light_box_text(w),
    ))
    .expect("valid box")
}

/// The scene text of [`big_light_box`].
fn big_light_box_text(w: u32) -> String {
    let text = fog_box_text(w).replace(
        "origin = [-0.25, 0.999, -0.25]\nu = [0.5, 0.0, 0.0]\nv = [0.0, 0.0, 0.5]",
        "origin = [-0.9, 0.999, -0.9]\nu = [1.8, 0.0, 0.0]\nv = [0.0, 0.0, 1.8]",
    );
    assert!(text.contains("[-0.9, 0.999, -0.9]"), "light replaced");
    text
}

/// Aperture radius and focus distance of the thin-lens twins: a lens of radius 0.3 focused on
/// the box's centre, so the back wall and the light are out of focus.
const LENS: (f32, f32) = (0.3, 3.9);

/// `text` (a box's) seen through the thin lens [`LENS`] instead of the pinhole.
fn with_lens(text: &str) -> String {
    let lens = format!(
        "fov_deg = 40.0\naperture_radius = {}\nfocus_distance = {}\n",
        LENS.0, LENS.1
    );
    let out = text.replacen("fov_deg = 40.0\n", &lens, 1);
    assert!(out.contains("aperture_radius"), "the camera found");
    out
}

/// A scene from the text of a box through the thin lens [`LENS`].
fn lens_scene(name: &str, text: &str) -> Scene {
    let scene = Scene::load(&SceneSource::embedded(name, &with_lens(text))).expect("valid box");
    assert!(!scene.camera.as_ref().unwrap().is_pinhole());
    scene
}

/// The fog box's text at `w` x `w` pixels.
fn fog_box_text(w: u32) -> String {
    pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    )
}

/// A camera vertex at a point of the thin lens drawn uniformly on its disk by the test (polar
/// coordinates, not the renderer's concentric map), and its area density 1 / (pi r^2) from
/// [`LENS`] (the pinhole: the eye, density 1, no numbers drawn).
fn lens_vertex(scene: &Scene, s: &mut Sampler) -> (Vertex, f64) {
    let cam = scene.camera.as_ref().unwrap();
    let mut v = eye_vertex(scene);
    if cam.is_pinhole() {
        return (v, 1.0);
    }
    let u = s.next_2d();
    let r = LENS.0 * u.x.sqrt();
    let phi = std::f32::consts::TAU * u.y;
    v.p = cam.eye + cam.right * (r * phi.cos()) + cam.up * (r * phi.sin());
    let pdf = 1.0 / (std::f64::consts::PI * LENS.0 as f64 * LENS.0 as f64);
    (v, pdf)
}

/// The quadrant of the lens (by the signs along the camera's right and up) a camera vertex
/// lies in.
fn lens_quadrant(scene: &Scene, v: &Vertex) -> usize {
    let cam = scene.camera.as_ref().unwrap();
    let d = v.p - cam.eye;
    usize::from(d.dot(cam.right) < 0.0) + 2 * usize::from(d.dot(cam.up) < 0.0)
}

/// The light of [`big_light_box`].
fn big_light_rect() -> Rect {
    Rect {
        o: Vec3::new(-0.9, 0.999, -0.9),
        a: Vec3::new(1.8, 0.0, 0.0),
        b: Vec3::new(0.0, 0.0, 1.8),
        n: -Vec3::Y,
    }
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

// ------------------------------------------------------------------------------------------
// geometry the test knows independently of the renderer

/// A rectangle o + s a + t b, s, t in [0, 1], with unit normal `n` (the side paths come from).
#[derive(Clone, Copy, Debug)]
struct Rect {
    o: Vec3,
    a: Vec3,
    b: Vec3,
    n: Vec3,
}

impl Rect {
    fn area(&self) -> f64 {
        self.a.cross(self.b).length() as f64
    }

    fn uv(&self, p: Vec3) -> (f32, f32) {
        let d = p - self.o;
        (
            d.dot(self.a) / self.a.length_squared(),
            d.dot(self.b) / self.b.length_squared(),
        )
    }

    fn contains(&self, p: Vec3) -> bool {
        let (s, t) = self.uv(p);
        (0.0..=1.0).contains(&s)
            && (0.0..=1.0).contains(&t)
            && (p - self.o).dot(self.n).abs() < 1e-3
    }

    fn uniform(&self, u: Vec2) -> Vec3 {
        self.o + self.a * u.x + self.b * u.y
    }

    /// The point where a direction uniform on the sphere about `anchor` meets the rectangle,
    /// if it does.
    fn near(&self, anchor: Vec3, u: Vec2) -> Option<Vec3> {
        let d = uniform_sphere(u);
        let denom = d.dot(self.n);
        if denom.abs() < 1e-6 {
            return None;
        }
        let t = (self.o - anchor).dot(self.n) / denom;
        let p = anchor + d * t;
        (t > 0.0 && self.contains(p)).then_some(p)
    }

    /// The density per area of [`Rect::near`] at `p`: |cos| / (4 pi d^2).
    fn near_pdf(&self, anchor: Vec3, p: Vec3) -> f64 {
        let d = p - anchor;
        let d2 = d.length_squared() as f64;
        if d2 == 0.0 {
            return 0.0;
        }
        let cos = (d.normalize().dot(self.n)).abs() as f64;
        cos / (4.0 * std::f64::consts::PI * d2)
    }
}

fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Below the light's plane (y = 0.999) every point of the box sees every other point of the
/// box (it is convex) and the pinhole: the test's regions stay there, so T > 0 on them means
/// the mutation can reach them.
const REGION_TOP: f32 = 0.99;
/// The medium region: the box below `REGION_TOP`.
const BOX_MIN: Vec3 = Vec3::new(-1.0, -1.0, -1.0);
const BOX_MAX: Vec3 = Vec3::new(1.0, REGION_TOP, 1.0);
/// Largest distance of [`medium_near`] (more than the box's diagonal).
const NEAR_REACH: f32 = 3.5;

fn in_box(p: Vec3) -> bool {
    p.cmpge(BOX_MIN).all() && p.cmple(BOX_MAX).all()
}

fn box_volume() -> f64 {
    let d = BOX_MAX - BOX_MIN;
    (d.x * d.y * d.z) as f64
}

/// A medium point at a uniform direction and a uniform distance in (0, NEAR_REACH) from
/// `anchor`; density 1 / (4 pi d^2 NEAR_REACH) per volume.
fn medium_near(anchor: Vec3, u: Vec2, w: f32) -> Option<Vec3> {
    let p = anchor + uniform_sphere(u) * (w * NEAR_REACH);
    in_box(p).then_some(p)
}

fn medium_near_pdf(anchor: Vec3, p: Vec3) -> f64 {
    let d2 = (p - anchor).length_squared() as f64;
    if d2 == 0.0 {
        return 0.0;
    }
    1.0 / (4.0 * std::f64::consts::PI * d2 * NEAR_REACH as f64)
}

/// The fog box's walls below `REGION_TOP`, with normals into the box.
fn walls() -> [(&'static str, Rect); 4] {
    let h = 1.0 + REGION_TOP;
    [
        (
            "floor",
            Rect {
                o: Vec3::new(-1.0, -1.0, -1.0),
                a: Vec3::new(2.0, 0.0, 0.0),
                b: Vec3::new(0.0, 0.0, 2.0),
                n: Vec3::Y,
            },
        ),
        (
            "back",
            Rect {
                o: Vec3::new(-1.0, -1.0, -1.0),
                a: Vec3::new(2.0, 0.0, 0.0),
                b: Vec3::new(0.0, h, 0.0),
                n: Vec3::Z,
            },
        ),
        (
            "left",
            Rect {
                o: Vec3::new(-1.0, -1.0, -1.0),
                a: Vec3::new(0.0, 0.0, 2.0),
                b: Vec3::new(0.0, h, 0.0),
                n: Vec3::X,
            },
        ),
        (
            "right",
            Rect {
                o: Vec3::new(1.0, -1.0, -1.0),
                a: Vec3::new(0.0, 0.0, 2.0),
                b: Vec3::new(0.0, h, 0.0),
                n: -Vec3::X,
            },
        ),
    ]
}

/// The ceiling light of the fog box (facing down).
fn light_rect() -> Rect {
    Rect {
        o: Vec3::new(-0.25, 0.999, -0.25),
        a: Vec3::new(0.5, 0.0, 0.0),
        b: Vec3::new(0.0, 0.0, 0.5),
        n: -Vec3::Y,
    }
}

/// A vertex as the renderer's own tracing makes it on the non-null surface at `target`
/// (normal `n` towards the side it is approached from): kind, normal and media of a vertex
/// that `extend` returned there, moved to `target`.
fn vertex_at(scene: &Scene, target: Vec3, n: Vec3) -> Vertex {
    let from = Vertex::new(
        VertexKind::Medium { medium: 0 },
        target + n * 0.3,
        Vec3::ZERO,
        Some(0),
        Some(0),
    );
    for i in 0..1000 {
        let mut s = Sampler::new(7, i, 0);
        if let Some(v) = extend(scene, &from, -n, &mut s) {
            if !v.is_medium() && (v.p - target).length() < 1e-3 {
                let mut v = v;
                v.p = target;
                return v;
            }
        }
    }
    panic!("no surface at {target}");
}

/// The light vertex at `p` on the fog box's light, as `sample_light_vertex` makes it.
fn light_vertex_at(scene: &Scene, p: Vec3) -> Vertex {
    let mut s = Sampler::new(8, 0, 0);
    let mut v = sample_light_vertex(scene, &pathspace::path::PLAIN, &mut s)
        .expect("the light samples a vertex");
    v.p = p;
    v
}

fn medium_vertex(p: Vec3) -> Vertex {
    Vertex::new(
        VertexKind::Medium { medium: 0 },
        p,
        Vec3::ZERO,
        Some(0),
        Some(0),
    )
}

fn eye_vertex(scene: &Scene) -> Vertex {
    let cam = scene.camera.as_ref().unwrap();
    Vertex::new(VertexKind::Camera, cam.eye, cam.forward, None, None)
}

/// `p` mirrored in the plane y = `MIRROR_Y`.
fn mirrored(p: Vec3) -> Vec3 {
    Vec3::new(p.x, 2.0 * MIRROR_Y - p.y, p.z)
}

/// The point of the floor mirror where light from `a` to `b` reflects (through the mirror
/// image of `b`).
fn mirror_point(a: Vec3, b: Vec3) -> Vec3 {
    let bm = mirrored(b);
    let s = (a.y - MIRROR_Y) / (a.y - bm.y);
    a + (bm - a) * s
}

fn mirror_rect() -> Rect {
    Rect {
        o: Vec3::new(-0.6, MIRROR_Y, -0.9),
        a: Vec3::new(0.0, 0.0, 1.7),
        b: Vec3::new(1.2, 0.0, 0.0),
        n: Vec3::Y,
    }
}

/// The real density per area of a chain end through mirror vertex `m` (from `a` to `b`) over
/// the Dirac-free density T: d1^2 d2^2 / ((d1 + d2)^2 cos_m).
fn mirror_factor(a: Vec3, m: Vec3, b: Vec3) -> f64 {
    let d1 = (m - a).length() as f64;
    let d2 = (b - m).length() as f64;
    let cos = ((a - m).normalize().y).abs() as f64;
    d1 * d1 * d2 * d2 / ((d1 + d2) * (d1 + d2) * cos)
}

/// (radius, azimuth in [0, 2 pi)) of `p` about `c` in the frame of normal `n`.
fn polar(c: Vec3, n: Vec3, p: Vec3) -> (f64, f64) {
    let f = Frame::from_normal(n);
    let l = f.to_local(p - c);
    let phi = (l.y as f64)
        .atan2(l.x as f64)
        .rem_euclid(std::f64::consts::TAU);
    ((l.x as f64).hypot(l.y as f64), phi)
}

/// A point at log-uniform radius in [r0, r1] and uniform azimuth about `c` in the plane of
/// normal `n`, and its density per area 1 / (2 pi r ln(r1 / r0)).
fn log_polar(c: Vec3, n: Vec3, r0: f64, r1: f64, u: Vec2) -> (Vec3, f64) {
    let f = Frame::from_normal(n);
    let r = r0 * (r1 / r0).powf(u.x as f64);
    let phi = std::f64::consts::TAU * u.y as f64;
    let p = c + (f.s * phi.cos() as f32 + f.t * phi.sin() as f32) * r as f32;
    (p, log_polar_pdf(r, r0, r1))
}

fn log_polar_pdf(r: f64, r0: f64, r1: f64) -> f64 {
    if r < r0 || r > r1 {
        return 0.0;
    }
    1.0 / (std::f64::consts::TAU * r * r * (r1 / r0).ln())
}

/// Cell of a radius in log-spaced bins over [r0, r1] crossed with `sectors` azimuth sectors.
fn polar_cell(r: f64, phi: f64, r0: f64, r1: f64, bins: usize, sectors: usize) -> Option<usize> {
    if !(r >= r0 && r < r1) {
        return None;
    }
    let b = (((r / r0).ln() / (r1 / r0).ln()) * bins as f64) as usize;
    let s = (phi / std::f64::consts::TAU * sectors as f64) as usize;
    Some(b.min(bins - 1) * sectors + s.min(sectors - 1))
}

// ------------------------------------------------------------------------------------------
// the comparison

/// Observed counts of `n` draws per cell against estimated cell probabilities `p` whose
/// estimates have variances `var` (zero for exact ones): Pearson's statistic with each
/// cell's variance n p + n^2 var (the multinomial's n p (1 - p) is below n p, so the test is
/// conservative), cells expecting fewer than 5 pooled; chi-square with one degree of freedom
/// per term. A count where nothing is expected (the estimate is exactly zero) is an outcome
/// the density says is impossible: p-value 0.
fn cells_agree(fam: &mut Family, what: &str, observed: &[u64], n: u64, p: &[f64], var: &[f64]) {
    let n = n as f64;
    let mut terms: Vec<(f64, f64, f64)> = Vec::new();
    let mut pool = (0.0, 0.0, 0.0);
    let mut impossible = 0u64;
    for (i, ((&o, &p), &v)) in observed.iter().zip(p).zip(var).enumerate() {
        if p <= 0.0 {
            impossible += o;
            continue;
        }
        let e = n * p;
        let cell = (o as f64, e, e + n * n * v);
        if std::env::var("MLT_DEBUG").is_ok() && ((cell.0 - e) / cell.2.sqrt()).abs() > 3.0 {
            eprintln!(
                "  {what}: cell {i}: observed {o} expected {e:.1} (sd {:.1})",
                cell.2.sqrt()
            );
        }
        if e < 5.0 {
            pool = (pool.0 + cell.0, pool.1 + cell.1, pool.2 + cell.2);
        } else {
            terms.push(cell);
        }
    }
    if pool.1 > 0.0 {
        terms.push(pool);
    }
    let statistic: f64 = terms.iter().map(|(o, e, v)| (o - e) * (o - e) / v).sum();
    let dof = terms.len();
    let pv = if impossible > 0 || dof == 0 {
        0.0
    } else {
        ChiSquared::new(dof as f64).unwrap().sf(statistic)
    };
    let worst = terms
        .iter()
        .map(|(o, e, v)| (o - e) / v.sqrt())
        .fold(0.0f64, |a, z| if z.abs() > a.abs() { z } else { a });
    let total_o: f64 = observed.iter().map(|&o| o as f64).sum();
    let total_e: f64 = p.iter().sum::<f64>() * n;
    let detail = format!(
        "chi-square {statistic:.1} on {dof} cells; {impossible} samples where T = 0; \
         worst cell {worst:+.2} sd; {total_o} counted vs {total_e:.1} expected"
    );
    eprintln!("{what}: p = {pv:.3e}: {detail}");
    fam.p_value(what, pv, detail);
}

/// A sampler of paths y for the cell integrals: y and its weight (see `proposals_follow_t`).
type Draw<'a> = dyn Fn(&mut Sampler) -> Option<(Vec<Vertex>, f64)> + Sync + 'a;

/// Test (a) for one fixed x: `n_prop` proposals of `m` binned by `cell_of` against the cell
/// integrals of T(x -> y), estimated from `n_q` draws of `draw` (a path y and its weight
/// 1 / q(y), times the Dirac-free-to-real factor where specular vertices are moved).
#[allow(clippy::too_many_arguments)]
fn proposals_follow_t(
    fam: &mut Family,
    what: &str,
    scene: &Scene,
    m: &dyn Mutation,
    x: &[Vertex],
    cells: usize,
    cell_of: &(dyn Fn(&[Vertex]) -> Option<usize> + Sync),
    n_prop: u64,
    n_q: u64,
    draw: &Draw<'_>,
    seed: u64,
) {
    const CHUNK: u64 = 4096;
    let chunks = n_prop.div_ceil(CHUNK);
    let observed = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut s = Sampler::new(seed, c, 0);
            let (mut work, mut y) = (Workspace::default(), Vec::new());
            let mut counts = vec![0u64; cells];
            for _ in c * CHUNK..((c + 1) * CHUNK).min(n_prop) {
                let plain = &pathspace::path::PLAIN;
                if m.sample(scene, plain, x, &mut s, &mut work, &mut y)
                    .is_some()
                {
                    if let Some(i) = cell_of(&y) {
                        counts[i] += 1;
                    }
                }
            }
            counts
        })
        .reduce(
            || vec![0u64; cells],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    let q_chunks = n_q.div_ceil(CHUNK);
    let sums = (0..q_chunks)
        .into_par_iter()
        .map(|c| {
            let mut s = Sampler::new(seed ^ 0x5eed, c, 1);
            let mut work = Workspace::default();
            let mut acc = vec![(0.0f64, 0.0f64); cells];
            for _ in c * CHUNK..((c + 1) * CHUNK).min(n_q) {
                let Some((y, factor)) = draw(&mut s) else {
                    continue;
                };
                let Some(i) = cell_of(&y) else {
                    continue;
                };
                let w =
                    m.transition_density(scene, &pathspace::path::PLAIN, x, &y, &mut work) * factor;
                acc[i].0 += w;
                acc[i].1 += w * w;
            }
            acc
        })
        .reduce(
            || vec![(0.0, 0.0); cells],
            |a, b| {
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| (x.0 + y.0, x.1 + y.1))
                    .collect()
            },
        );
    let nq = n_q as f64;
    let p: Vec<f64> = sums.iter().map(|s| s.0 / nq).collect();
    let var: Vec<f64> = sums
        .iter()
        .zip(&p)
        .map(|(s, p)| ((s.1 / nq - p * p) / nq).max(0.0))
        .collect();
    if std::env::var("MLT_DEBUG").is_ok() {
        let nn = n_prop as f64;
        for i in 0..cells {
            let e = nn * p[i];
            let v = e + nn * nn * var[i];
            let z = (observed[i] as f64 - e) / v.sqrt();
            if z.abs() > 3.0 {
                eprintln!(
                    "  cell {i}: observed {} expected {e:.1} (sd {:.1}) z {z:+.2}",
                    observed[i],
                    v.sqrt()
                );
            }
        }
    }
    cells_agree(fam, what, &observed, n_prop, &p, &var);
}

/// The path with a moved vertex at a point, and its real-over-Dirac-free factor.
type Rebuild<'a> = dyn Fn(Vec3) -> Option<(Vec<Vertex>, f64)> + Sync + 'a;

/// A move of vertex `i` on the back wall (normal +z) about `c`, binned by radius in
/// `r0..r1` and sector, each proposal rebuilt by `rebuild`.
fn back_wall_move<'a>(
    c: Vec3,
    (r0, r1): (f64, f64),
    i: usize,
    rebuild: &'a Rebuild<'a>,
) -> PlaneMove<'a> {
    PlaneMove {
        c,
        n: Vec3::Z,
        r0,
        r1,
        i,
        rect: walls()[1].1,
        rebuild,
    }
}

/// The path `x` with vertex `i` moved to a point, at no extra factor.
fn moving_vertex(
    x: &[Vertex],
    i: usize,
) -> impl Fn(Vec3) -> Option<(Vec<Vertex>, f64)> + Sync + '_ {
    move |p| {
        let mut y = x.to_vec();
        y[i].p = p;
        Some((y, 1.0))
    }
}

/// Cells and draws for a perturbation that moves one vertex `i` of x on a plane (normal `n`)
/// around x_i, with `factor(y)` the real-over-Dirac-free factor: radius bins over [r0, r1]
/// crossed with 8 sectors; the draws log-polar over [r0 / 2, 2 r1] (the rectangle `rect`
/// bounds the surface), the other moved vertices rebuilt by `rebuild`.
struct PlaneMove<'a> {
    c: Vec3,
    n: Vec3,
    r0: f64,
    r1: f64,
    i: usize,
    rect: Rect,
    rebuild: &'a Rebuild<'a>,
}

const RADIUS_BINS: usize = 8;
const SECTORS: usize = 8;

impl PlaneMove<'_> {
    fn cells(&self) -> usize {
        RADIUS_BINS * SECTORS
    }

    fn cell_of(&self, y: &[Vertex]) -> Option<usize> {
        let v = y.get(self.i)?;
        if !self.rect.contains(v.p) || v.is_medium() {
            return None;
        }
        let (r, phi) = polar(self.c, self.n, v.p);
        polar_cell(r, phi, self.r0, self.r1, RADIUS_BINS, SECTORS)
    }

    fn draw(&self, s: &mut Sampler) -> Option<(Vec<Vertex>, f64)> {
        let (lo, hi) = (self.r0 * 0.5, self.r1 * 2.0);
        let (p, q) = log_polar(self.c, self.n, lo, hi, s.next_2d());
        if !self.rect.contains(p) {
            return None;
        }
        let (y, factor) = (self.rebuild)(p)?;
        Some((y, factor / q))
    }
}

// ------------------------------------------------------------------------------------------
// (a) the perturbations

/// The fog box's path light -> floor -> back wall -> pinhole, the back wall point `wall`.
fn floor_wall_path(scene: &Scene, wall: Vec3) -> Vec<Vertex> {
    let l = light_vertex_at(scene, Vec3::new(0.05, 0.999, -0.1));
    let floor = vertex_at(scene, Vec3::new(0.1, -1.0, 0.0), Vec3::Y);
    let wall = vertex_at(scene, wall, Vec3::Z);
    vec![l, floor, wall, eye_vertex(scene)]
}

#[test]
fn sensor_perturbation_proposals_follow_t_on_a_wall_through_a_mirror_and_in_the_fog() {
    let mut fam = Family::new("mlt_mutations: sensor perturbation proposals");
    let scene = fog_box(64);
    // 0.1 .. 4 pixels; a pixel is ~0.056 at the back wall
    let m = SensorPerturbation {
        offset: InverseDistance::new(0.1, 4.0).unwrap(),
    };
    // on the back wall, seen directly
    let x = floor_wall_path(&scene, Vec3::new(-0.05, 0.1, -1.0));
    let wall = x[2];
    let rebuild = moving_vertex(&x, 2);
    let mv = back_wall_move(wall.p, (3e-3, 0.4), 2, &rebuild);
    proposals_follow_t(
        &mut fam,
        "back wall",
        &scene,
        &m,
        &x,
        mv.cells(),
        &|y| mv.cell_of(y),
        100_000,
        200_000,
        &|s| mv.draw(s),
        11,
    );
    // in the fog: x_2 at its distance d from the pinhole; y_2 on the sphere of radius d,
    // binned by the angle about the old direction (solid angle times d^2 is the area there)
    let mut xm = x.clone();
    let eye = xm[3].p;
    let d_old = (xm[2].p - eye).normalize();
    let dist = 3.0f32;
    xm[2] = medium_vertex(eye + d_old * dist);
    let (t0, t1) = (3e-3 / dist as f64, 0.4 / dist as f64);
    let angle_cell = |y: &[Vertex]| -> Option<usize> {
        if y.len() != 4 || !y[2].is_medium() {
            return None;
        }
        let w = (y[2].p - eye).normalize();
        let theta = (w.cross(d_old).length() as f64).atan2(w.dot(d_old) as f64);
        let f = Frame::from_normal(d_old);
        let l = f.to_local(w);
        let phi = (l.y as f64)
            .atan2(l.x as f64)
            .rem_euclid(std::f64::consts::TAU);
        polar_cell(theta, phi, t0, t1, RADIUS_BINS, SECTORS)
    };
    let xm2 = xm.clone();
    let draw = move |s: &mut Sampler| -> Option<(Vec<Vertex>, f64)> {
        // theta log-uniform in [t0 / 2, 2 t1], uniform azimuth: density per solid angle
        // 1 / (2 pi theta sin(theta) ln(4 t1 / t0)), per area of the sphere / d^2
        let (lo, hi) = (t0 * 0.5, t1 * 2.0);
        let u = s.next_2d();
        let theta = lo * (hi / lo).powf(u.x as f64);
        let phi = std::f64::consts::TAU * u.y as f64;
        let f = Frame::from_normal(d_old);
        let w = f.to_world(Vec3::new(
            (theta.sin() * phi.cos()) as f32,
            (theta.sin() * phi.sin()) as f32,
            theta.cos() as f32,
        ));
        let q = 1.0
            / (std::f64::consts::TAU * theta * theta.sin() * (hi / lo).ln())
            / (dist as f64 * dist as f64);
        let mut y = xm2.clone();
        y[2] = medium_vertex(eye + w * dist);
        Some((y, 1.0 / q))
    };
    proposals_follow_t(
        &mut fam,
        "fog vertex",
        &scene,
        &m,
        &xm,
        RADIUS_BINS * SECTORS,
        &angle_cell,
        100_000,
        200_000,
        &draw,
        12,
    );
    // through the floor mirror: light -> back wall -> mirror -> pinhole
    let ms = mirror_box(64);
    let eye = eye_vertex(&ms);
    let wall_p = Vec3::new(0.1, -0.6, -1.0);
    let xs = vec![
        light_vertex_at(&ms, Vec3::new(0.05, 0.999, -0.1)),
        vertex_at(&ms, wall_p, Vec3::Z),
        vertex_at(&ms, mirror_point(eye.p, wall_p), Vec3::Y),
        eye,
    ];
    assert!(
        image_contribution(&ms, &xs).is_some(),
        "the mirror path carries light"
    );
    let (xs2, ms2) = (xs.clone(), &ms);
    let rebuild = move |p: Vec3| {
        let mp = mirror_point(eye.p, p);
        if !mirror_rect().contains(mp) {
            return None;
        }
        let mut y = xs2.clone();
        y[1] = vertex_at(ms2, p, Vec3::Z);
        y[2].p = mp;
        Some((y, mirror_factor(eye.p, mp, p)))
    };
    let mv = back_wall_move(wall_p, (3e-3, 0.4), 1, &rebuild);
    proposals_follow_t(
        &mut fam,
        "back wall through the mirror",
        &ms,
        &m,
        &xs,
        mv.cells(),
        &|y| mv.cell_of(y),
        100_000,
        200_000,
        &|s| mv.draw(s),
        13,
    );
    fam.finish();
}

/// The sensor perturbation through a thin lens keeps the lens point and moves the film point:
/// the new ray runs from the old lens point through the new film point's image on the focus
/// plane, so the back wall (out of focus) moves by another Jacobian than the pinhole's; the
/// proposals must keep the lens point and follow T.
#[test]
fn sensor_perturbation_proposals_through_a_thin_lens_follow_t_on_a_wall() {
    let mut fam = Family::new("mlt_mutations: sensor perturbation proposals through a thin lens");
    let scene = lens_scene("fog box (thin lens)", &fog_box_text(64));
    let m = SensorPerturbation {
        offset: InverseDistance::new(0.1, 4.0).unwrap(),
    };
    let cam = scene.camera.as_ref().unwrap();
    let lens_p = cam.eye + cam.right * 0.2 - cam.up * 0.15;
    let mut x = floor_wall_path(&scene, Vec3::new(-0.05, 0.1, -1.0));
    x[3].p = lens_p;
    assert!(
        image_contribution(&scene, &x).is_some(),
        "the wall seen through the lens"
    );
    let wall = x[2];
    let rebuild = moving_vertex(&x, 2);
    let mv = back_wall_move(wall.p, (3e-3, 0.4), 2, &rebuild);
    // a proposal that moved the lens point is in no cell: T counts only the kept one
    let cell_of = |y: &[Vertex]| (y[3].p == lens_p).then(|| mv.cell_of(y)).flatten();
    proposals_follow_t(
        &mut fam,
        "back wall through the lens",
        &scene,
        &m,
        &x,
        mv.cells(),
        &cell_of,
        100_000,
        200_000,
        &|s| mv.draw(s),
        14,
    );
    fam.finish();
}

#[test]
fn light_perturbation_proposals_follow_t_on_a_wall_in_the_fog_and_through_a_mirror() {
    let mut fam = Family::new("mlt_mutations: light perturbation proposals");
    let scene = fog_box(64);
    let m = LightPerturbation {
        angle: InverseDistance::new(1e-3, 0.1).unwrap(),
    };
    // the direction floor -> back wall turned; the back wall point ~1.1 away
    let x = floor_wall_path(&scene, Vec3::new(-0.05, 0.1, -1.0));
    let rebuild = moving_vertex(&x, 2);
    let mv = back_wall_move(x[2].p, (5e-4, 0.3), 2, &rebuild);
    proposals_follow_t(
        &mut fam,
        "back wall",
        &scene,
        &m,
        &x,
        mv.cells(),
        &|y| mv.cell_of(y),
        100_000,
        200_000,
        &|s| mv.draw(s),
        21,
    );
    // x_2 in the fog at distance 0.9 from the floor point: y_2 on that sphere about x_1
    let mut xm = x.clone();
    let from = xm[1].p;
    let d_old = (xm[2].p - from).normalize();
    let dist = 0.9f32;
    xm[2] = medium_vertex(from + d_old * dist);
    let (t0, t1) = (1e-3, 0.1);
    let angle_cell = |y: &[Vertex]| -> Option<usize> {
        if y.len() != 4 || !y[2].is_medium() {
            return None;
        }
        let w = (y[2].p - from).normalize();
        let theta = (w.cross(d_old).length() as f64).atan2(w.dot(d_old) as f64);
        let l = Frame::from_normal(d_old).to_local(w);
        let phi = (l.y as f64)
            .atan2(l.x as f64)
            .rem_euclid(std::f64::consts::TAU);
        polar_cell(theta, phi, t0, t1, RADIUS_BINS, SECTORS)
    };
    let xm2 = xm.clone();
    let draw = move |s: &mut Sampler| -> Option<(Vec<Vertex>, f64)> {
        let (lo, hi) = (t0 * 0.5, t1 * 2.0);
        let u = s.next_2d();
        let theta = lo * (hi / lo).powf(u.x as f64);
        let phi = std::f64::consts::TAU * u.y as f64;
        let w = Frame::from_normal(d_old).to_world(Vec3::new(
            (theta.sin() * phi.cos()) as f32,
            (theta.sin() * phi.sin()) as f32,
            theta.cos() as f32,
        ));
        let q = 1.0
            / (std::f64::consts::TAU * theta * theta.sin() * (hi / lo).ln())
            / (dist as f64 * dist as f64);
        let mut y = xm2.clone();
        y[2] = medium_vertex(from + w * dist);
        Some((y, 1.0 / q))
    };
    proposals_follow_t(
        &mut fam,
        "fog vertex",
        &scene,
        &m,
        &xm,
        RADIUS_BINS * SECTORS,
        &angle_cell,
        100_000,
        200_000,
        &draw,
        22,
    );
    // a caustic through the floor mirror: light -> mirror -> back wall -> pinhole; the
    // emission direction is turned at the light and retraced through the mirror
    let ms = mirror_box(64);
    let lp = Vec3::new(0.05, 0.999, -0.1);
    let wall_p = Vec3::new(0.1, -0.6, -1.0);
    let xs = vec![
        light_vertex_at(&ms, lp),
        vertex_at(&ms, mirror_point(lp, wall_p), Vec3::Y),
        vertex_at(&ms, wall_p, Vec3::Z),
        eye_vertex(&ms),
    ];
    assert!(
        image_contribution(&ms, &xs).is_some(),
        "the caustic path carries light"
    );
    let (xs2, ms2) = (xs.clone(), &ms);
    let rebuild = move |p: Vec3| {
        let mp = mirror_point(lp, p);
        if !mirror_rect().contains(mp) {
            return None;
        }
        let mut y = xs2.clone();
        y[1].p = mp;
        y[2] = vertex_at(ms2, p, Vec3::Z);
        Some((y, mirror_factor(lp, mp, p)))
    };
    let mv = back_wall_move(wall_p, (1e-3, 0.5), 2, &rebuild);
    proposals_follow_t(
        &mut fam,
        "back wall through the mirror",
        &ms,
        &m,
        &xs,
        mv.cells(),
        &|y| mv.cell_of(y),
        100_000,
        200_000,
        &|s| mv.draw(s),
        23,
    );
    fam.finish();
}

/// [`floor_wall_path`] from the scene's primitives alone (no tracing, no free flights).
fn floor_wall_path_by_hand(scene: &Scene, wall_p: Vec3) -> Vec<Vertex> {
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
    let light = VertexKind::Light {
        light: 0,
        prim: Some(light_prim),
    };
    let l = Vertex::new(light, Vec3::new(0.05, 0.999, -0.1), -Vec3::Y, fog, fog);
    let floor_p = Vec3::new(0.1, -1.0, 0.0);
    let floor_kind = VertexKind::Surface {
        prim: prim_at(floor_p, Vec3::Y),
    };
    let floor = Vertex::new(floor_kind, floor_p, Vec3::Y, fog, fog);
    let wall_kind = VertexKind::Surface {
        prim: prim_at(wall_p, Vec3::Z),
    };
    let wall = Vertex::new(wall_kind, wall_p, Vec3::Z, fog, fog);
    vec![l, floor, wall, eye_vertex(scene)]
}

#[test]
fn propagation_perturbation_proposals_follow_t_along_the_line_and_out_of_the_medium() {
    let mut fam = Family::new("mlt_mutations: propagation perturbation proposals");
    let scene = fog_box(64);
    // the mutation as `Mlt::new` configures it and the path built by hand, so that this test
    // (the `propagation_perturbation` assignment's) reaches nothing else of MLT or the media
    let (d0, d1) = MltSettings::default().propagation_distance;
    let r = scene.radius.max(f32::MIN_POSITIVE);
    let m = &PropagationPerturbation {
        distance: InverseDistance::new(d0 * r, d1 * r).unwrap(),
    };
    let d = m.distance;
    // x_2 in the fog, 1.0 from the floor point towards the back wall and (second case) just
    // before the back wall, so that forward moves leave the medium (no proposal)
    let base = floor_wall_path_by_hand(&scene, Vec3::new(-0.05, 0.1, -1.0));
    let from = base[1].p;
    let w = (base[2].p - from).normalize();
    let to_wall = (base[2].p - from).length();
    for (what, t) in [("mid-air", 1.0f32), ("near the wall", to_wall - 0.02)] {
        let mut x = base.clone();
        x[2] = medium_vertex(from + w * t);
        let (lo, hi) = (d.min as f64, d.max as f64);
        let bins = 8;
        // signed displacement: log bins of |t_y - t_x| over [lo, hi], forward or backward
        let cell_of = |y: &[Vertex]| -> Option<usize> {
            if y.len() != 4 || !y[2].is_medium() {
                return None;
            }
            let s = ((y[2].p - from).length() - t) as f64;
            let b = polar_cell(s.abs(), 0.0, lo * 0.999, hi * 1.001, bins, 1)?;
            Some(b + if s > 0.0 { 0 } else { bins })
        };
        let x2 = x.clone();
        let draw = move |s: &mut Sampler| -> Option<(Vec<Vertex>, f64)> {
            // |D| log-uniform over [lo / 2, 2 hi], either sign: density per dt, and T is per
            // t^2 dt (dV = t^2 dw dt)
            let (a, b) = (lo * 0.5, hi * 2.0);
            let dd = a * (b / a).powf(s.next_f64());
            let sign = if s.next_f64() < 0.5 { 1.0 } else { -1.0 };
            let ty = t as f64 + sign * dd;
            let p = from + w * ty as f32;
            if ty <= 0.0 || !in_box(p) {
                return None; // the medium ends at the walls: no proposal there
            }
            let q = 0.5 / (dd * (b / a).ln()) / (ty * ty);
            let mut y = x2.clone();
            y[2] = medium_vertex(p);
            Some((y, 1.0 / q))
        };
        proposals_follow_t(
            &mut fam,
            what,
            &scene,
            m,
            &x,
            2 * bins,
            &cell_of,
            100_000,
            200_000,
            &draw,
            31,
        );
    }
    fam.finish();
}

#[test]
fn multichain_perturbation_proposals_follow_t_on_the_wall_and_the_light() {
    let mut fam = Family::new("mlt_mutations: multi-chain perturbation proposals");
    let ms = mirror_box(64);
    let eye = eye_vertex(&ms);
    multichain_wall_and_light(&mut fam, "wall and light", &ms, eye, 41);
    fam.finish();
}

/// The same through a thin lens, from a lens point off the centre: the lens chain turns about
/// the kept lens point (through the new film point's image on the focus plane).
#[test]
fn multichain_perturbation_proposals_through_a_thin_lens_follow_t() {
    let mut fam = Family::new("mlt_mutations: multi-chain perturbation proposals (thin lens)");
    let ms = lens_scene("mirror box (thin lens)", &mirror_box_text(64));
    let cam = ms.camera.as_ref().unwrap();
    let mut eye = eye_vertex(&ms);
    eye.p = cam.eye - cam.right * 0.1 + cam.up * 0.25;
    multichain_wall_and_light(&mut fam, "wall and light through the lens", &ms, eye, 42);
    fam.finish();
}

/// Test (a) of the multi-chain perturbation on light -> mirror -> back wall -> mirror -> eye
/// (camera vertex `eye`): the lens chain eye -> mirror -> back wall (film offset), then the
/// chain back wall -> mirror -> light (turned direction).
fn multichain_wall_and_light(fam: &mut Family, what: &str, ms: &Scene, eye: Vertex, seed: u64) {
    let m = MultiChainPerturbation {
        offset: InverseDistance::new(0.1, 4.0).unwrap(),
        angle: InverseDistance::new(1e-3, 0.05).unwrap(),
    };
    let lp = Vec3::new(0.05, 0.999, -0.1);
    let wall_p = Vec3::new(0.1, -0.6, -1.0);
    let x = vec![
        light_vertex_at(ms, lp),
        vertex_at(ms, mirror_point(wall_p, lp), Vec3::Y),
        vertex_at(ms, wall_p, Vec3::Z),
        vertex_at(ms, mirror_point(eye.p, wall_p), Vec3::Y),
        eye,
    ];
    assert!(
        image_contribution(ms, &x).is_some(),
        "the L S D S E path carries light"
    );
    let back = walls()[1].1;
    let light = light_rect();
    let d_old = (x[1].p - x[2].p).normalize();
    let (w0, w1) = (3e-3, 0.4); // wall offsets
    let (t0, t1) = (1e-3, 0.05); // turning angles
    let unfolded = (mirrored(lp) - wall_p).length() as f64;
    let (l0, l1) = (t0 * unfolded * 0.3, t1 * unfolded * 3.0); // light offsets
    let cell_of = |y: &[Vertex]| -> Option<usize> {
        if y.len() != 5 || !back.contains(y[2].p) || !light.contains(y[0].p) {
            return None;
        }
        let (r, phi) = polar(wall_p, Vec3::Z, y[2].p);
        let a = polar_cell(r, phi, w0, w1, 4, 4)?;
        let w = (y[1].p - y[2].p).normalize();
        let theta = (w.cross(d_old).length() as f64).atan2(w.dot(d_old) as f64);
        let l = Frame::from_normal(d_old).to_local(w);
        let phi = (l.y as f64)
            .atan2(l.x as f64)
            .rem_euclid(std::f64::consts::TAU);
        let b = polar_cell(theta, phi, t0, t1, 4, 4)?;
        Some(a * 16 + b)
    };
    let x2 = x.clone();
    let msr = ms;
    let draw = move |s: &mut Sampler| -> Option<(Vec<Vertex>, f64)> {
        // the wall point log-polar about x_2; the light point log-polar about where the old
        // direction from the new wall point reaches the light through the mirror
        let (pw, qw) = log_polar(wall_p, Vec3::Z, w0 * 0.5, w1 * 2.0, s.next_2d());
        if !back.contains(pw) {
            return None;
        }
        let hit = pw + d_old * ((MIRROR_Y - pw.y) / d_old.y);
        let up = Vec3::new(d_old.x, -d_old.y, d_old.z);
        let centre = hit + up * ((0.999 - hit.y) / up.y);
        let (pl, ql) = log_polar(centre, Vec3::Y, l0, l1, s.next_2d());
        if !light.contains(pl) {
            return None;
        }
        let m1 = mirror_point(eye.p, pw);
        let m2 = mirror_point(pw, pl);
        if !mirror_rect().contains(m1) || !mirror_rect().contains(m2) {
            return None;
        }
        let mut y = x2.clone();
        y[0].p = pl;
        y[1].p = m2;
        y[2] = vertex_at(msr, pw, Vec3::Z);
        y[3].p = m1;
        let factor = mirror_factor(eye.p, m1, pw) * mirror_factor(pw, m2, pl);
        Some((y, factor / (qw * ql)))
    };
    proposals_follow_t(
        fam,
        what,
        ms,
        &m,
        &x,
        16 * 16,
        &cell_of,
        200_000,
        800_000,
        &draw,
        seed,
    );
}

// ------------------------------------------------------------------------------------------
// (a) the bidirectional mutation at depths 1 to 5

/// Where a new vertex of a bidirectional proposal lies: the light (as the path's first
/// vertex), one of the four walls below `REGION_TOP`, or the fog below it.
const REGIONS: usize = 6;
const LIGHT_REGION: usize = 0;
const MEDIUM_REGION: usize = 5;
/// New vertices a cell resolves (k_a up to 3 edges).
const MAX_NEW: usize = 2;

struct BidirCells<'s> {
    x: Vec<Vertex>,
    /// (l, k_d, k_a) of every resolved decomposition.
    structures: Vec<(i64, usize, usize)>,
    /// Each structure's draw probability.
    weights: Vec<f64>,
    /// Wall templates (kind, media, normal) and their rectangles.
    walls: Vec<(Vertex, Rect)>,
    light: Vertex,
    light_rect: Rect,
    /// Where a new first vertex x_0 lies: the light, or the fog when it glows (eq. 5).
    first_region: usize,
    /// Cells of a new lens point (the quadrants of a thin lens; 1 for the pinhole).
    lens_cells: usize,
    scene: &'s Scene,
}

impl<'s> BidirCells<'s> {
    fn new(scene: &'s Scene, mlt: &Mlt, x: Vec<Vertex>, light_rect: Rect) -> Self {
        Self::with_first(scene, mlt, x, Some(light_rect))
    }

    /// Cells whose new x_0 lies on the light `light_rect`, or in the glowing fog (`None`).
    fn with_first(scene: &'s Scene, mlt: &Mlt, x: Vec<Vertex>, light_rect: Option<Rect>) -> Self {
        let b = &mlt.mutations.bidirectional;
        let n = x.len();
        let k = n - 1;
        let mut structures = Vec::new();
        let mut weights = Vec::new();
        for kd in 1..=k + 1 {
            for l in -1..=(k - kd) as i64 {
                for ka in 1..=MAX_NEW + 1 {
                    let p =
                        b.deletion_pmf(kd, k) / (k + 2 - kd) as f64 * b.addition_pmf(ka, kd, l, n);
                    if p > 0.0 {
                        structures.push((l, kd, ka));
                        weights.push(p.max(1e-3));
                    }
                }
            }
        }
        let total: f64 = weights.iter().sum();
        weights.iter_mut().for_each(|w| *w /= total);
        if std::env::var("MLT_DEBUG").is_ok() {
            for (i, s) in structures.iter().enumerate() {
                eprint!("[{i}: {s:?} cells {}..] ", i * REGIONS * REGIONS);
            }
            eprintln!();
        }
        let walls = walls()
            .iter()
            .map(|(_, r)| (vertex_at(scene, r.uniform(Vec2::splat(0.5)), r.n), *r))
            .collect();
        let (light, light_rect, first_region) = match light_rect {
            Some(r) => (
                light_vertex_at(scene, r.uniform(Vec2::splat(0.5))),
                r,
                LIGHT_REGION,
            ),
            None => (medium_vertex(Vec3::ZERO), big_light_rect(), MEDIUM_REGION),
        };
        BidirCells {
            x,
            structures,
            weights,
            walls,
            light,
            light_rect,
            first_region,
            lens_cells: if scene.camera.as_ref().unwrap().is_pinhole() {
                1
            } else {
                4
            },
            scene,
        }
    }

    fn cells(&self) -> usize {
        self.structures.len() * REGIONS * REGIONS * self.lens_cells
    }

    /// True for a thin lens whose point y moved: the decomposition's m is then k (the deleted
    /// section reached the camera and took its lens point along).
    fn new_lens_point(&self, y: &[Vertex]) -> bool {
        let (a, b) = (self.x.last().unwrap(), y.last().unwrap());
        self.lens_cells > 1 && b.kind == VertexKind::Camera && a.p != b.p
    }

    fn region_of(&self, v: &Vertex, first: bool) -> Option<usize> {
        match v.kind {
            VertexKind::Light { .. } if first && self.light_rect.contains(v.p) => {
                Some(LIGHT_REGION)
            }
            VertexKind::Medium { .. } if in_box(v.p) => Some(MEDIUM_REGION),
            VertexKind::Surface { .. } => self
                .walls
                .iter()
                .position(|(t, r)| t.kind == v.kind && r.contains(v.p))
                .map(|i| i + 1),
            _ => None,
        }
    }

    /// The decomposition of y against x as the mutation defines it (kept prefix x_0 .. x_l,
    /// kept suffix x_m .. x_k) and the regions of the new vertices.
    fn cell_of(&self, y: &[Vertex]) -> Option<usize> {
        let x = &self.x;
        let (nx, ny) = (x.len(), y.len());
        let new_lens = self.new_lens_point(y);
        let cs = if new_lens {
            1
        } else {
            x.iter()
                .rev()
                .zip(y.iter().rev())
                .take_while(|(a, b)| same_vertex(a, b))
                .count()
        };
        if cs == 0 {
            return None;
        }
        let cp = x
            .iter()
            .zip(y)
            .take_while(|(a, b)| same_vertex(a, b))
            .count()
            .min(nx - cs)
            .min(ny - cs);
        let l = cp as i64 - 1;
        let kd = nx - cs - cp + 1;
        let ka = (ny - cs + 1).checked_sub(cp)?;
        let st = self.structures.iter().position(|&s| s == (l, kd, ka))?;
        let mut cell = [0usize; MAX_NEW];
        for (j, v) in y[cp..cp + ka - 1].iter().enumerate() {
            cell[j] = self.region_of(v, cp + j == 0)?;
        }
        // a thin lens: the quadrant of y's lens point where the mutation drew one (m = k)
        let lens = if self.lens_cells > 1 && cs == 1 {
            lens_quadrant(self.scene, &y[ny - 1])
        } else {
            0
        };
        Some(((st * REGIONS + cell[0]) * REGIONS + cell[1]) * self.lens_cells + lens)
    }

    /// A vertex in `region`: uniform there with probability 1/2, else near one of `anchors`;
    /// with the mixture's density at the point.
    fn place(&self, region: usize, anchors: &[Vec3], s: &mut Sampler) -> Option<(Vertex, f64)> {
        let pick = s.next_f64();
        let u = s.next_2d();
        let w = s.next_f32();
        let na = anchors.len() as f64;
        let which = ((pick - 0.5) * 2.0 * na) as usize;
        if region == MEDIUM_REGION {
            let p = if pick < 0.5 {
                BOX_MIN + (BOX_MAX - BOX_MIN) * Vec3::new(u.x, u.y, w)
            } else {
                medium_near(anchors[which.min(anchors.len() - 1)], u, w)?
            };
            let q = 0.5 / box_volume()
                + anchors
                    .iter()
                    .map(|&a| 0.5 / na * medium_near_pdf(a, p))
                    .sum::<f64>();
            return Some((medium_vertex(p), q));
        }
        let (template, rect) = if region == LIGHT_REGION {
            (self.light, self.light_rect)
        } else {
            self.walls[region - 1]
        };
        let p = if pick < 0.5 {
            rect.uniform(u)
        } else {
            rect.near(anchors[which.min(anchors.len() - 1)], u)?
        };
        let q = 0.5 / rect.area()
            + anchors
                .iter()
                .map(|&a| 0.5 / na * rect.near_pdf(a, p))
                .sum::<f64>();
        let mut v = template;
        v.p = p;
        Some((v, q))
    }

    fn draw(&self, s: &mut Sampler) -> Option<(Vec<Vertex>, f64)> {
        let u = s.next_f64();
        let mut acc = 0.0;
        let mut st = self.structures.len() - 1;
        for (i, w) in self.weights.iter().enumerate() {
            acc += w;
            if u < acc {
                st = i;
                break;
            }
        }
        let (l, kd, ka) = self.structures[st];
        let x = &self.x;
        let m = (l + kd as i64) as usize;
        let mut y: Vec<Vertex> = x[..(l + 1) as usize].to_vec();
        let mut q = self.weights[st];
        for _ in 0..ka - 1 {
            let first = y.is_empty();
            let region = if first {
                self.first_region
            } else {
                1 + s.next_index(REGIONS - 1)
            };
            if !first {
                q /= (REGIONS - 1) as f64;
            }
            let mut anchors = vec![x[m].p];
            if let Some(prev) = y.last() {
                anchors.push(prev.p);
            }
            let (v, qv) = self.place(region, &anchors, s)?;
            q *= qv;
            y.push(v);
        }
        y.extend_from_slice(&x[m..]);
        if self.lens_cells > 1 && m + 1 == x.len() {
            // m = k: a thin lens's new point
            let (v, pdf) = lens_vertex(self.scene, s);
            y.last_mut().unwrap().p = v.p;
            q *= pdf;
        }
        Some((y, 1.0 / q))
    }
}

/// Pre-pass paths of the box (depth limit 4), drawn by contribution: for each k = 1 ..= 5
/// edges the first whose inner vertices lie below `REGION_TOP`.
fn paths_by_length(scene: &Scene, mlt: &Mlt) -> Vec<Vec<Vertex>> {
    let boot = Bootstrap::run(scene, &mlt.bdpt, 20_000, 51);
    let mut s = Sampler::new(51, 1, 0);
    let mut out: Vec<Option<Vec<Vertex>>> = vec![None; 5];
    for _ in 0..20_000 {
        let Some(c) = boot.select(s.next_f64()) else {
            break;
        };
        let Some(x) = Bootstrap::path_of(scene, &mlt.bdpt, 51, c) else {
            continue;
        };
        let k = x.len() - 1;
        if (1..=5).contains(&k)
            && out[k - 1].is_none()
            && image_contribution(scene, &x).is_some()
            && x[1..k].iter().all(|v| v.p.y < REGION_TOP)
        {
            out[k - 1] = Some(x);
        }
        if out.iter().all(Option::is_some) {
            break;
        }
    }
    out.into_iter()
        .map(|p| p.expect("a pre-pass path of every length"))
        .collect()
}

#[test]
fn bidirectional_proposals_follow_t_at_depths_one_to_five() {
    let mut fam = Family::new("mlt_mutations: bidirectional proposals");
    let scene = big_light_box(16);
    let mlt = engine(&scene, [1.0; 5], Some(4), 51);
    let b: &Bidirectional = &mlt.mutations.bidirectional;
    for x in paths_by_length(&scene, &mlt) {
        let k = x.len() - 1;
        let kinds: String = x[1..k]
            .iter()
            .map(|v| if v.is_medium() { 'V' } else { 'D' })
            .collect();
        let cells = BidirCells::new(&scene, &mlt, x.clone(), big_light_rect());
        proposals_follow_t(
            &mut fam,
            &format!("k = {k} (L{kinds}E)"),
            &scene,
            b,
            &x,
            cells.cells(),
            &|y| cells.cell_of(y),
            150_000,
            2_000_000,
            &|s| cells.draw(s),
            52 + k as u64,
        );
    }
    fam.finish();
}

/// The same through a thin lens: where the deleted section reaches the camera (m = k) the
/// proposal's lens point is new, binned by the lens's quadrant, and T carries its density
/// 1 / (pi r^2) (the test's draws place it uniformly on the disk by their own map).
#[test]
fn bidirectional_proposals_through_a_thin_lens_follow_t_at_depths_one_to_four() {
    let mut fam = Family::new("mlt_mutations: bidirectional proposals through a thin lens");
    let scene = lens_scene("big-light-box (thin lens)", &big_light_box_text(16));
    let mlt = engine(&scene, [1.0; 5], Some(4), 57);
    let b: &Bidirectional = &mlt.mutations.bidirectional;
    for x in paths_by_length(&scene, &mlt).into_iter().take(4) {
        let k = x.len() - 1;
        assert_ne!(
            x[k].p,
            scene.camera.as_ref().unwrap().eye,
            "a lens point off the centre"
        );
        let cells = BidirCells::new(&scene, &mlt, x.clone(), big_light_rect());
        proposals_follow_t(
            &mut fam,
            &format!("k = {k} through the lens"),
            &scene,
            b,
            &x,
            cells.cells(),
            &|y| cells.cell_of(y),
            150_000,
            2_000_000,
            &|s| cells.draw(s),
            72 + k as u64,
        );
    }
    fam.finish();
}

// ------------------------------------------------------------------------------------------
// (b) stationarity: chains against f/b on the 4 x 4 boxes

const RES: u32 = 4;

/// The class of a path for the stationarity cells: the light seen directly, or the kind of
/// x_{k-1} (which wall, the mirror, the fog near or far from the pinhole) for k = 2 and k >= 3,
/// times the half of the light x_0 lies in (the multi-chain and light perturbations move it).
const CLASSES: usize = 2 * (2 + 2 * 8);

fn class_of(scene: &Scene, x: &[Vertex]) -> usize {
    let k = x.len() - 1;
    let half = usize::from(x[0].p.x < 0.0);
    if k == 1 {
        // the glow seen directly: x_0 in the fog's nearer or farther half from the pinhole
        // (the propagation perturbation moves it along the ray)
        let far = x[0].is_medium() && (x[0].p - x[1].p).length() > 3.9;
        return 2 * usize::from(far) + half;
    }
    let v = &x[k - 1];
    let eye = x[k].p;
    let kind = match v.kind {
        VertexKind::Medium { .. } => {
            if (v.p - eye).length() < 3.9 {
                6
            } else {
                7
            }
        }
        _ if is_specular(scene, v) => 5,
        _ => match v.n {
            n if n.y > 0.5 => 0,
            n if n.y < -0.5 => 1,
            n if n.z > 0.5 => 2,
            n if n.x > 0.5 => 3,
            n if n.x < -0.5 => 4,
            _ => 5,
        },
    };
    2 * (2 + 8 * (k.min(3) - 2) + kind) + half
}

fn stationary_cell(scene: &Scene, x: &[Vertex], raster: Vec2) -> usize {
    let px = (raster.y.min(RES as f32 - 1e-3) as usize) * RES as usize
        + raster.x.min(RES as f32 - 1e-3) as usize;
    px * CLASSES + class_of(scene, x)
}

const CELLS: usize = (RES * RES) as usize * CLASSES;

/// Per-cell shares of b and the variance of each share, from `n` independent eye walks
/// (chunks of 8192 on streams of `seed`): `walk` traces one walk and adds each path it scores
/// to its cell (the normalization's own noise neglected: b is estimated to a fraction of the
/// cells' errors).
fn cell_shares(
    n: u64,
    seed: u64,
    walk: impl Fn(&mut Sampler, &mut dyn FnMut(usize, f64)) + Sync,
) -> (Vec<f64>, Vec<f64>) {
    const CHUNK: u64 = 8192;
    let sums = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut acc = vec![(0.0f64, 0.0f64); CELLS];
            let mut one = vec![0.0f64; CELLS];
            let mut touched = Vec::new();
            let mut s = Sampler::new(seed, c, 7);
            for _ in c * CHUNK..((c + 1) * CHUNK).min(n) {
                touched.clear();
                walk(&mut s, &mut |cell, v| {
                    one[cell] += v;
                    touched.push(cell);
                });
                touched.sort_unstable();
                touched.dedup();
                for &cell in &touched {
                    acc[cell].0 += one[cell];
                    acc[cell].1 += one[cell] * one[cell];
                    one[cell] = 0.0;
                }
            }
            acc
        })
        .reduce(
            || vec![(0.0, 0.0); CELLS],
            |a, b| {
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| (x.0 + y.0, x.1 + y.1))
                    .collect()
            },
        );
    let nf = n as f64;
    let b: f64 = sums.iter().map(|s| s.0).sum::<f64>() / nf;
    let share = sums.iter().map(|s| s.0 / nf / b).collect();
    let var = sums
        .iter()
        .map(|s| ((s.1 / nf - (s.0 / nf).powi(2)) / nf).max(0.0) / (b * b))
        .collect();
    (share, var)
}

/// f/b per cell by an independent estimator: a path tracer from the pinhole (or from a lens
/// point the test draws, [`lens_vertex`], its density divided out) that at each eye vertex either connects to a light vertex (s = 1, for paths whose x_1 is not specular)
/// or, having hit the light, keeps the path (s = 0, for the light seen directly and for paths
/// whose x_1 is specular): each path has exactly one of the two strategies, so the sum is
/// unbiased for f* over each cell without weights. Returns the per-cell share of b and the
/// variance of that estimate (the normalization's own noise neglected: b is estimated to a
/// fraction of the cells' errors).
fn truth(scene: &Scene, max_depth: usize, n: u64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    cell_shares(
        n,
        seed,
        |s: &mut Sampler, add: &mut dyn FnMut(usize, f64)| {
            // through a thin lens each walk starts at its own lens point
            let (eye, p_lens) = lens_vertex(scene, s);
            let mut add = |cell: usize, v: f64| add(cell, v / p_lens);
            let mut sub = vec![eye];
            for _ in 0..=max_depth {
                let len = sub.len();
                let prev = len.checked_sub(2).map(|i| sub[i]);
                let cur = sub[len - 1];
                let Some(d) = sample_direction(
                    scene,
                    &pathspace::path::PLAIN,
                    prev.as_ref(),
                    &cur,
                    TransportMode::Radiance,
                    s,
                ) else {
                    break;
                };
                // (the environment's vertex where the walk escapes, if the scene has one)
                let Some(v) = extend_or_escape(scene, &cur, d, s) else {
                    break;
                };
                sub.push(v);
                let vertices = sub.len() - 1; // scattering vertices and the new one
                if v.is_infinite_light() {
                    // s = 0 at the environment: the sky seen directly or through a mirror
                    let mut path: Vec<Vertex> = sub.iter().rev().copied().collect();
                    anchor_infinite(scene, &mut path);
                    if path.len() == 2 || is_specular(scene, &path[1]) {
                        if let Some((f, r)) = image_contribution(scene, &path) {
                            let dens = singular_densities(scene, &pathspace::path::PLAIN, &path);
                            let p: f64 = dens.eye[..path.len() - 1]
                                .iter()
                                .map(|&p| p as f64)
                                .product();
                            if p > 0.0 {
                                let cell = stationary_cell(scene, &path, r);
                                add(cell, scalar_contribution(f) as f64 / p);
                            }
                        }
                    }
                    break;
                }
                // s = 0: the new vertex on the light
                if let VertexKind::Surface { prim } = v.kind {
                    let shape = &scene.shapes[scene.prim_shape[prim as usize] as usize];
                    if let Some(light) = shape.light {
                        let mut path: Vec<Vertex> = sub.iter().rev().copied().collect();
                        path[0].kind = VertexKind::Light {
                            light,
                            prim: Some(prim),
                        };
                        if path.len() == 2 || is_specular(scene, &path[1]) {
                            if let Some((f, r)) = image_contribution(scene, &path) {
                                let dens =
                                    singular_densities(scene, &pathspace::path::PLAIN, &path);
                                let p: f64 = dens.eye[..path.len() - 1]
                                    .iter()
                                    .map(|&p| p as f64)
                                    .product();
                                if p > 0.0 {
                                    let cell = stationary_cell(scene, &path, r);
                                    add(cell, scalar_contribution(f) as f64 / p);
                                }
                            }
                        }
                        break;
                    }
                }
                if vertices > max_depth {
                    break;
                }
                // s = 1: a light vertex connected to the new one
                if is_specular(scene, &v) {
                    continue;
                }
                let Some(l) = sample_light_vertex(scene, &pathspace::path::PLAIN, s) else {
                    continue;
                };
                let mut path = vec![l];
                path.extend(sub.iter().rev().copied());
                // a light at infinity: its direction, seen from x_1
                anchor_infinite(scene, &mut path);
                if let Some((f, r)) = image_contribution(scene, &path) {
                    let dens = singular_densities(scene, &pathspace::path::PLAIN, &path);
                    let p: f64 = dens.light[0] as f64
                        * dens.eye[1..path.len() - 1]
                            .iter()
                            .map(|&p| p as f64)
                            .product::<f64>();
                    if p > 0.0 {
                        let cell = stationary_cell(scene, &path, r);
                        add(cell, scalar_contribution(f) as f64 / p);
                    }
                }
            }
        },
    )
}

/// The fog box's f/b per cell at depth limit 2 (shared by the tests that use it).
fn fog_truth() -> &'static (Vec<f64>, Vec<f64>) {
    static T: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    T.get_or_init(|| truth(&fog_box(RES), 2, 1_500_000, 61))
}

/// Test (b): `chains` independent chains of the mutations `weights`, each seeded from the
/// pre-pass (so close to f/b from the start) and run `steps` mutations; the last states'
/// cells against f/b.
#[allow(clippy::too_many_arguments)]
fn chains_follow_f_over_b(
    fam: &mut Family,
    what: &str,
    scene: &Scene,
    mlt: &Mlt,
    truth: &(Vec<f64>, Vec<f64>),
    chains: u64,
    steps: usize,
    seed: u64,
) {
    let boot = Bootstrap::run(scene, &mlt.bdpt, 40_000, seed);
    let counts = (0..chains)
        .into_par_iter()
        .map(|c| {
            let mut s = Sampler::new(seed, c, 3);
            let chain = loop {
                let cand = boot.select(s.next_f64()).expect("the pre-pass found paths");
                let Some(x) = Bootstrap::path_of(scene, &mlt.bdpt, seed, cand) else {
                    continue;
                };
                if let Some(ch) = Chain::new(scene, Sampler::new(seed, c, 4), x) {
                    break ch;
                }
            };
            let mut chain = chain;
            let mut splats = Vec::new();
            let mut stats = Default::default();
            for _ in 0..steps {
                splats.clear();
                mlt.step(scene, &mut chain, &mut splats, &mut stats);
            }
            stationary_cell(scene, &chain.x, chain.raster)
        })
        .fold(
            || vec![0u64; CELLS],
            |mut acc, cell| {
                acc[cell] += 1;
                acc
            },
        )
        .reduce(
            || vec![0u64; CELLS],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    cells_agree(fam, what, &counts, chains, &truth.0, &truth.1);
}

/// Mutation weights: the bidirectional mutation and `kind` at 1 : 4, so that the chain's
/// moves are mostly `kind`'s.
fn with_bidirectional(index: usize) -> [f64; 5] {
    let mut w = [0.0; 5];
    w[0] = 1.0;
    w[index] += 4.0;
    w
}

#[test]
fn bidirectional_chains_follow_f_over_b() {
    let mut fam = Family::new("mlt_mutations: bidirectional chains");
    let scene = fog_box(RES);
    let mlt = engine(&scene, with_bidirectional(0), Some(2), 62);
    chains_follow_f_over_b(
        &mut fam,
        "fog box",
        &scene,
        &mlt,
        fog_truth(),
        30_000,
        20,
        62,
    );
    fam.finish();
}

#[test]
fn sensor_perturbation_chains_follow_f_over_b() {
    let mut fam = Family::new("mlt_mutations: sensor chains");
    let scene = fog_box(RES);
    let mut mlt = engine(&scene, with_bidirectional(1), Some(2), 63);
    // offsets within the 4 x 4 film
    mlt.mutations.sensor.offset = InverseDistance::new(0.05, 2.0).unwrap();
    chains_follow_f_over_b(
        &mut fam,
        "fog box",
        &scene,
        &mlt,
        fog_truth(),
        30_000,
        30,
        63,
    );
    fam.finish();
}

#[test]
fn light_perturbation_chains_follow_f_over_b() {
    let mut fam = Family::new("mlt_mutations: light chains");
    let scene = fog_box(RES);
    let mut mlt = engine(&scene, with_bidirectional(2), Some(2), 64);
    mlt.mutations.light.angle = InverseDistance::new(1e-3, 0.3).unwrap();
    chains_follow_f_over_b(
        &mut fam,
        "fog box",
        &scene,
        &mlt,
        fog_truth(),
        30_000,
        30,
        64,
    );
    fam.finish();
}

#[test]
fn propagation_perturbation_chains_follow_f_over_b() {
    let mut fam = Family::new("mlt_mutations: propagation chains");
    let scene = fog_box(RES);
    let mut mlt = engine(&scene, with_bidirectional(3), Some(2), 65);
    mlt.mutations.propagation = PropagationPerturbation {
        distance: InverseDistance::new(0.01, 1.0).unwrap(),
    };
    chains_follow_f_over_b(
        &mut fam,
        "fog box",
        &scene,
        &mlt,
        fog_truth(),
        30_000,
        30,
        65,
    );
    fam.finish();
}

#[test]
fn multichain_perturbation_chains_follow_f_over_b() {
    let mut fam = Family::new("mlt_mutations: multi-chain chains");
    let scene = mirror_box(RES);
    let truth = truth(&scene, 3, 1_500_000, 66);
    let mut mlt = engine(&scene, with_bidirectional(4), Some(3), 66);
    mlt.mutations.multichain = MultiChainPerturbation {
        offset: InverseDistance::new(0.05, 2.0).unwrap(),
        angle: InverseDistance::new(1e-3, 0.3).unwrap(),
    };
    chains_follow_f_over_b(&mut fam, "mirror box", &scene, &mlt, &truth, 30_000, 30, 66);
    fam.finish();
}

// ------------------------------------------------------------------------------------------
// (b) with lights at infinity: the directional measure

/// The fog box (with the floor mirror of [`mirror_box`] if `mirror`) without its ceiling and
/// its ceiling light, lit from above by `light` (a `[[lights]]` table): the fog's null box stays,
/// so the light crosses its top face into the fog, reaches the walls, the floor and the mirror,
/// and the film's corners see past the box.
fn open_box(w: u32, light: &str, mirror: bool) -> Scene {
    let text = if mirror {
        mirror_box_text(w)
    } else {
        pathspace::scene::FOG_BOX.replace(
            "resolution = [256, 256]",
            &format!("resolution = [{w}, {w}]"),
        ) + "\n"
    };
    let ceiling = "# ceiling y = +1\n[[shapes]]\ntype = \"quad\"\norigin = [-1.0, 1.0, -1.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 0.0, 2.0]\nmaterial = \"white\"\n";
    assert!(text.contains(ceiling), "ceiling found");
    let at = text.find("# ceiling light").expect("ceiling light found");
    let end = text[at..].find("\n\n").map_or(text.len(), |e| at + e);
    let text = format!("{}{}\n{light}\n", &text[..at], &text[end..]).replace(ceiling, "");
    assert!(!text.contains("emission"), "the area light removed");
    Scene::load(&SceneSource::embedded("open-box", &text)).expect("valid open box")
}

/// The sun: a directional light from above, tilted so that it reaches the back wall too.
const SUN: &str =
    "[[lights]]\ntype = \"directional\"\ndirection = [0.3, -1.0, -0.4]\nirradiance = 2.0\n";

/// A sky: a constant environment.
const SKY: &str = "[[lights]]\ntype = \"environment\"\nradiance = 1.0\n";

/// Test (b) for the first `kinds` mutations (each with the bidirectional one, as above) on
/// `scene` (lit from infinity, or seen through a thin lens): the chains' last states against
/// f/b of the path tracer, whose strategies reach a light at infinity as they reach an area
/// light (s = 1 by the light's own sampling, s = 0 where a walk escapes to the sky).
fn chains_of_each_kind_follow_f_over_b(family: &str, scene: &Scene, kinds: usize, seed: u64) {
    let mut fam = Family::new(family);
    let truth = truth(scene, 3, 1_500_000, seed);
    for (i, name) in [
        "bidirectional",
        "sensor",
        "light",
        "propagation",
        "multichain",
    ]
    .into_iter()
    .enumerate()
    .take(kinds)
    {
        let mut mlt = engine(scene, with_bidirectional(i), Some(3), seed + i as u64);
        mlt.mutations.sensor.offset = InverseDistance::new(0.05, 2.0).unwrap();
        mlt.mutations.light.angle = InverseDistance::new(1e-3, 0.3).unwrap();
        mlt.mutations.propagation = PropagationPerturbation {
            distance: InverseDistance::new(0.01, 1.0).unwrap(),
        };
        mlt.mutations.multichain = MultiChainPerturbation {
            offset: InverseDistance::new(0.05, 2.0).unwrap(),
            angle: InverseDistance::new(1e-3, 0.3).unwrap(),
        };
        chains_follow_f_over_b(
            &mut fam,
            name,
            scene,
            &mlt,
            &truth,
            30_000,
            30,
            seed + i as u64,
        );
    }
    fam.finish();
}

/// Under the sun, without the mirror: a path tracer never reaches the sun through a mirror (its
/// one direction), so the truth has no strategy for L S D E; and the multi-chain perturbation
/// leaves every chain that ends on a directional light to the others.
#[test]
fn chains_under_a_directional_light_follow_f_over_b() {
    let scene = open_box(RES, SUN, false);
    chains_of_each_kind_follow_f_over_b("mlt_mutations: chains under the sun", &scene, 4, 70);
}

/// Under a sky, with the mirror: the multi-chain perturbation retraces L S D E chains to a new
/// direction of the sky.
#[test]
fn chains_under_an_environment_follow_f_over_b() {
    let scene = open_box(RES, SKY, true);
    chains_of_each_kind_follow_f_over_b("mlt_mutations: chains under a sky", &scene, 5, 80);
}

/// Through a thin lens, in the fog box: the bidirectional mutation redraws the lens point
/// (m = k), the perturbations keep it (the sensor perturbation moves the film point about it,
/// the light and propagation perturbations reconnect to it); the truth's walks start at lens
/// points of their own. (The multi-chain perturbation's lens chain is the sensor
/// perturbation's; its proposals through the lens are test (a)'s. In the mirror box the
/// caustics seen in the mirror, L S D S E, are too heavy-tailed for this test's variances: a
/// few seed paths carry a cell, through the pinhole as well.)
#[test]
fn chains_through_a_thin_lens_follow_f_over_b() {
    let scene = lens_scene("fog box (thin lens)", &fog_box_text(RES));
    chains_of_each_kind_follow_f_over_b("mlt_mutations: chains through a thin lens", &scene, 4, 90);
}

// ------------------------------------------------------------------------------------------
// (b) stationarity with a glowing medium as the only light: every path starts at a volume
// vertex x0 (Pauly et al. eq. 5), which the bidirectional mutation regenerates (by emitted
// power, or as the eye side's collision), the propagation perturbation slides along the
// pinhole's ray (the glow seen directly) and the multi-chain perturbation moves at its old
// distance (a chain through the mirror ending at x0); the sensor and light perturbations keep
// it. f carries L_e,V0(x0).

/// `text` (the fog box's) with the fog glowing (L_e,V0 = 0.5 per unit length) and the
/// ceiling light and everything after it gone.
fn glowing(text: &str) -> String {
    let cut = text.find("# ceiling light").expect("the fog box's light");
    let out = text[..cut].replacen(
        "sigma_s = 0.4\n",
        "sigma_s = 0.4\nemission = [0.5, 0.5, 0.5]\n",
        1,
    );
    assert!(out.contains("emission = [0.5"), "the fog glows");
    out
}

/// The fog box at `w` x `w` pixels lit by its glowing fog alone.
fn glowing_fog_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{w}, {w}]"),
    );
    Scene::load(&SceneSource::embedded("glowing-fog-box", &glowing(&text))).expect("valid box")
}

/// [`mirror_box`] lit by its glowing fog alone: paths V0 S D S E through the mirror, whose
/// last chain (for the multi-chain perturbation) ends at the volume x0.
fn glowing_mirror_box(w: u32) -> Scene {
    let text = pathspace::scene::FOG_BOX
        .replace(
            "resolution = [256, 256]",
            &format!("resolution = [{w}, {w}]"),
        )
        .replace(
            "[materials.white]",
            "[materials.chrome]\ntype = \"mirror\"\n\n[materials.white]",
        );
    let text = glowing(&text)
        + &format!(
            "\n[[shapes]]\ntype = \"quad\"\norigin = [-0.6, {MIRROR_Y}, -0.9]\nu = [0.0, 0.0, 1.7]\nv = [1.2, 0.0, 0.0]\nmaterial = \"chrome\"\n"
        );
    Scene::load(&SceneSource::embedded("glowing-mirror-box", &text)).expect("valid box")
}

/// f/b per cell for a scene lit only by glowing media, by an estimator independent of MLT: a
/// walk from the pinhole whose every collision in a glowing medium ends one path there (x0 =
/// the collision, BDPT's s = 0), weighed by f over the walk's density. Every path of the
/// scene has exactly this one strategy, so the sum is unbiased for f* over each cell.
fn glow_truth_of(scene: &Scene, max_depth: usize, n: u64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let eye = eye_vertex(scene);
    cell_shares(
        n,
        seed,
        |s: &mut Sampler, add: &mut dyn FnMut(usize, f64)| {
            let mut sub = vec![eye];
            for _ in 0..=max_depth {
                let len = sub.len();
                let prev = len.checked_sub(2).map(|i| sub[i]);
                let cur = sub[len - 1];
                let Some(d) = sample_direction(
                    scene,
                    &pathspace::path::PLAIN,
                    prev.as_ref(),
                    &cur,
                    TransportMode::Radiance,
                    s,
                ) else {
                    break;
                };
                let Some(v) = extend(scene, &cur, d, s) else {
                    break;
                };
                sub.push(v);
                if !v.is_medium() {
                    continue;
                }
                let path: Vec<Vertex> = sub.iter().rev().copied().collect();
                let Some((f, r)) = image_contribution(scene, &path) else {
                    continue;
                };
                let dens = singular_densities(scene, &pathspace::path::PLAIN, &path);
                let p: f64 = dens.eye[..path.len() - 1]
                    .iter()
                    .map(|&p| p as f64)
                    .product();
                if p > 0.0 {
                    let cell = stationary_cell(scene, &path, r);
                    add(cell, scalar_contribution(f) as f64 / p);
                }
            }
        },
    )
}

/// The glowing fog box's f/b per cell at depth limit 2.
fn glow_truth() -> &'static (Vec<f64>, Vec<f64>) {
    static T: OnceLock<(Vec<f64>, Vec<f64>)> = OnceLock::new();
    T.get_or_init(|| glow_truth_of(&glowing_fog_box(RES), 2, 1_500_000, 71))
}

/// The chains of `weights` (with `tune` applied to the engine) on the glowing fog box.
fn glowing_chains(name: &str, weights: [f64; 5], seed: u64, tune: impl Fn(&mut Mlt)) {
    let mut fam = Family::new(&format!("mlt_mutations: {name} chains, glowing fog"));
    let scene = glowing_fog_box(RES);
    let mut mlt = engine(&scene, weights, Some(2), seed);
    tune(&mut mlt);
    chains_follow_f_over_b(
        &mut fam,
        "glowing fog box",
        &scene,
        &mlt,
        glow_truth(),
        30_000,
        100,
        seed,
    );
    fam.finish();
}

#[test]
fn bidirectional_chains_follow_f_over_b_with_a_glowing_medium() {
    glowing_chains("bidirectional", with_bidirectional(0), 72, |_| {});
}

#[test]
fn sensor_perturbation_chains_follow_f_over_b_with_a_glowing_medium() {
    glowing_chains("sensor", with_bidirectional(1), 73, |mlt| {
        mlt.mutations.sensor.offset = InverseDistance::new(0.05, 2.0).unwrap();
    });
}

#[test]
fn light_perturbation_chains_follow_f_over_b_with_a_glowing_medium() {
    glowing_chains("light", with_bidirectional(2), 74, |mlt| {
        mlt.mutations.light.angle = InverseDistance::new(1e-3, 0.3).unwrap();
    });
}

#[test]
fn propagation_perturbation_chains_follow_f_over_b_with_a_glowing_medium() {
    glowing_chains("propagation", with_bidirectional(3), 75, |mlt| {
        mlt.mutations.propagation = PropagationPerturbation {
            distance: InverseDistance::new(0.01, 1.0).unwrap(),
        };
    });
}

#[test]
fn multichain_perturbation_chains_follow_f_over_b_with_a_glowing_medium() {
    let mut fam = Family::new("mlt_mutations: multi-chain chains, glowing mirror box");
    let scene = glowing_mirror_box(RES);
    let truth = glow_truth_of(&scene, 3, 1_500_000, 76);
    let mut mlt = engine(&scene, with_bidirectional(4), Some(3), 76);
    mlt.mutations.multichain = MultiChainPerturbation {
        offset: InverseDistance::new(0.05, 2.0).unwrap(),
        angle: InverseDistance::new(1e-3, 0.3).unwrap(),
    };
    chains_follow_f_over_b(
        &mut fam,
        "glowing mirror box",
        &scene,
        &mlt,
        &truth,
        30_000,
        100,
        76,
    );
    fam.finish();
}

/// The bidirectional mutation's proposals against T at k = 1 ..= 5 edges when the only light
/// is the glowing fog: a deleted x_0 comes back as a volume vertex, by emitted power (then a
/// direction uniform on the sphere) or as the eye side's collision (s' = 0), both in T.
#[test]
fn bidirectional_proposals_follow_t_with_a_glowing_medium() {
    let mut fam = Family::new("mlt_mutations: bidirectional proposals, glowing fog");
    let scene = glowing_fog_box(16);
    let mlt = engine(&scene, [1.0; 5], Some(4), 53);
    let b: &Bidirectional = &mlt.mutations.bidirectional;
    for x in paths_by_length(&scene, &mlt) {
        let k = x.len() - 1;
        assert!(x[0].is_medium(), "x_0 in the glowing fog");
        let kinds: String = x[1..k]
            .iter()
            .map(|v| if v.is_medium() { 'V' } else { 'D' })
            .collect();
        let cells = BidirCells::with_first(&scene, &mlt, x.clone(), None);
        proposals_follow_t(
            &mut fam,
            &format!("k = {k} (V0{kinds}E)"),
            &scene,
            b,
            &x,
            cells.cells(),
            &|y| cells.cell_of(y),
            150_000,
            2_000_000,
            &|s| cells.draw(s),
            54 + k as u64,
        );
    }
    fam.finish();
}

/// With `hide_emitters`, emitting surfaces are transparent to the camera's rays up to the
/// first scattering vertex (Mitsuba 3's `skip_area_emitters`): a hidden panel between the
/// pinhole and the back wall must not stop the sensor perturbation's new rays, so the
/// proposals reach the wall behind it as T says.
#[test]
fn sensor_perturbation_proposals_see_through_a_hidden_panel() {
    let mut fam = Family::new("mlt_mutations: sensor perturbation through a hidden panel");
    let text = format!(
        "hide_emitters = true\n{}\n[[shapes]]\ntype = \"quad\"\norigin = [-0.25, -0.1, -0.3]\nu = [0.4, 0.0, 0.0]\nv = [0.0, 0.35, 0.0]\nemission = 1.0\n",
        fog_box_text(64)
    );
    let scene = Scene::load(&SceneSource::embedded("hidden panel", &text)).expect("valid scene");
    let m = SensorPerturbation {
        offset: InverseDistance::new(0.1, 4.0).unwrap(),
    };
    // the pinhole sees this wall point through the panel
    let x = floor_wall_path(&scene, Vec3::new(-0.05, 0.1, -1.0));
    let rebuild = moving_vertex(&x, 2);
    let mv = back_wall_move(x[2].p, (3e-3, 0.4), 2, &rebuild);
    proposals_follow_t(
        &mut fam,
        "back wall behind the panel",
        &scene,
        &m,
        &x,
        mv.cells(),
        &|y| mv.cell_of(y),
        100_000,
        200_000,
        &|s| mv.draw(s),
        14,
    );
    fam.finish();
}
