//! Particles: weighted rays that represent the incident radiance L_i (photons) or the incident
//! importance W_i (importons) (Kristensen 2010, sec. 5.2.2).
//!
//! A set of weighted rays (r_i, alpha_i) represents L_i without bias when, for every sensor
//! responsivity W_e, E[sum_i alpha_i W_e(r_i)] = <W_e, L_i> (Kristensen 2010, eq. (5.8)); for
//! importons, E[sum_i beta_i L_e(r_i)] = <L_e, W_i> (eq. (5.9)). The inner product is over the
//! measure of the vertices (area on surfaces, volume in the medium) times solid angle, and on
//! surfaces it carries the cosine at the receiver: summed photon weights over a surface patch
//! estimate int L_i |cos| dw dA (the patch's incident flux), not int L_i dw dA.
//!
//! Two samplers are implemented:
//! - the classical tracer (eq. (5.11)-(5.12)): random walks from the lights (photons) or the
//!   sensor (importons); the particle at y_{i+1} carries the walk's throughput up to y_{i+1},
//!   which is exactly the [`Vertex::beta`] of BDPT's subpaths (emission, geometry factors,
//!   BSDF or phase function times sigma_s, propagation tau / p and Russian roulette included);
//! - the bidirectional particle sampler ([`bidirectional`]): one full path per sample, of
//!   length k with probability 2^-k, split at s uniform in 0..=k+1, with power-heuristic
//!   weights over the splits (the thesis gives it only by two worked examples).
//!
//! Every weight is already divided by the number of paths traced, so sums over particles are
//! estimates, not means. Streams are `Sampler::new(seed, chunk, pass)` per chunk of
//! [`PARTICLE_CHUNK`] paths and chunks are concatenated in order: the particle list is the same
//! whatever the thread count.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::bidir::{Bdpt, Scratch, Strategies, WalkLimits};
use crate::math::Sampler;
use crate::path::{LocalSampling, Vertex, VertexKind};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// A weighted ray: a photon (a sample of L_i) or an importon (a sample of W_i).
// ANCHOR: particle
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    /// Where the particle sits: a surface point or a collision point in a medium.
    pub position: Vec3,
    /// The surface normal at a surface particle (this project has geometric normals only, see
    /// ARCHITECTURE.md; not flipped towards the incident side); `None` in a medium.
    pub normal: Option<Vec3>,
    /// The cell of a volume particle: the index of the medium it collided in (a cell is one
    /// connected region of one medium in the shipped scenes); `None` on surfaces.
    pub medium: Option<u32>,
    /// Unit incident direction, pointing from the particle back towards where it came from
    /// (towards the light for photons, towards the sensor for importons): the direction
    /// argument of L_i(x, w) and W_i(x, w).
    pub direction: Vec3,
    /// alpha_i (photons) or beta_i (importons), divided by the number of paths traced.
    pub weight: Rgb,
    /// Index of the vertex in its path counted from the source (1 = first vertex after the
    /// light or sensor vertex).
    pub depth: u32,
}
// ANCHOR_END: particle

/// Which adjoint quantity a particle set represents.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Quantity {
    /// Incident radiance L_i: photons, traced from the lights.
    Radiance,
    /// Incident importance W_i: importons, traced from the sensor.
    Importance,
}

/// Where importons start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportonSource {
    /// The camera, raster positions uniform over the whole film: the importons represent the
    /// importance of the mean pixel, (1 / N_pixels) sum_j W_e^(j).
    Camera,
    /// Irradiance meter `m` (W_e = 1 / A on its front side).
    Meter(u32),
}

impl ImportonSource {
    /// The camera if the scene has one, else its first meter.
    pub fn default_for(scene: &Scene) -> Option<Self> {
        if scene.camera.is_some() {
            Some(ImportonSource::Camera)
        } else if !scene.sensors.is_empty() {
            Some(ImportonSource::Meter(0))
        } else {
            None
        }
    }
}

/// Paths per parallel work item (and per random stream).
pub const PARTICLE_CHUNK: u64 = 4096;
/// Stream salts that keep the particle samplers apart from each other and from the renderers.
const PHOTON_SALT: u64 = 0x7068_6f74_6f6e_0000;
const IMPORTON_SALT: u64 = 0x696d_706f_7274_0000;

/// The particle a subpath vertex represents, or `None` for vertices that are no particle (the
/// source vertex itself, an escaped infinite-light vertex).
pub fn particle_at(path: &[Vertex], i: usize, scale: f32) -> Option<Particle> {
    if i == 0 || i >= path.len() {
        return None;
    }
    let v = &path[i];
    let direction = (path[i - 1].p - v.p).normalize_or_zero();
    particle_with(v, direction, v.beta * scale, i)
}

/// The particle at vertex `v` with incident direction `direction` and `weight` (`None` for
/// vertices that are no particle or a zero, non-finite weight).
fn particle_with(v: &Vertex, direction: Vec3, weight: Rgb, depth: usize) -> Option<Particle> {
    let (normal, medium) = match v.kind {
        VertexKind::Surface { .. } => (Some(v.n), None),
        VertexKind::Medium { medium } => (None, Some(medium)),
        _ => return None,
    };
    if direction == Vec3::ZERO || !weight.is_finite() || weight == Rgb::ZERO {
        return None;
    }
    Some(Particle {
        position: v.p,
        normal,
        medium,
        direction,
        weight,
        depth: depth as u32,
    })
}

/// Runs `per_path` for `paths` paths in chunks of [`PARTICLE_CHUNK`] (one stream each) in
/// parallel and concatenates the chunks' particles in chunk order.
fn in_chunks<F>(paths: u64, seed: u64, salt: u64, per_path: F) -> Vec<Particle>
where
    F: Fn(&mut Sampler, &mut Vec<Vertex>, &mut Vec<Particle>) + Sync,
{
    let chunks = paths.div_ceil(PARTICLE_CHUNK);
    let parts: Vec<Vec<Particle>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut sampler = Sampler::new(seed, c ^ salt, 0);
            let mut path = Vec::new();
            let mut out = Vec::new();
            let n = PARTICLE_CHUNK.min(paths - c * PARTICLE_CHUNK);
            for _ in 0..n {
                per_path(&mut sampler, &mut path, &mut out);
            }
            out
        })
        .collect();
    parts.concat()
}

/// Classical photon tracing (Kristensen 2010, eq. (5.11)): `paths` light subpaths started as
/// BDPT starts them (with the scene's light-start density, the adjoint image included when one
/// is installed); every vertex after the light vertex is a photon with weight
/// alpha = L_e^(0)/p_0 prod f*_k G / p, i.e. the subpath throughput `beta`, divided by `paths`.
// ANCHOR: trace_photons
pub fn trace_photons(scene: &Scene, bdpt: &Bdpt, paths: u64, seed: u64) -> Vec<Particle> {
    if paths == 0 {
        return Vec::new();
    }
    let scale = 1.0 / paths as f32;
    in_chunks(paths, seed, PHOTON_SALT, |sampler, path, out| {
        bdpt.light_subpath(scene, WalkLimits::BDPT, sampler, path);
        out.extend((1..path.len()).filter_map(|i| particle_at(path, i, scale)));
    })
}
// ANCHOR_END: trace_photons

/// Classical importon tracing (Kristensen 2010, eq. (5.12) with W_e^(0), W_e^(1) and the
/// BSDF f_k): eye subpaths from `source`; every vertex after the sensor vertex is an importon
/// with weight beta = W_e^(0)/p_0 prod f_k G / p, divided by `paths`.
// ANCHOR: trace_importons
pub fn trace_importons(
    scene: &Scene,
    bdpt: &Bdpt,
    source: ImportonSource,
    paths: u64,
    seed: u64,
) -> Vec<Particle> {
    if paths == 0 {
        return Vec::new();
    }
    match source {
        ImportonSource::Camera if scene.camera.is_none() => return Vec::new(),
        ImportonSource::Meter(m) if m as usize >= scene.sensors.len() => return Vec::new(),
        _ => {}
    }
    let scale = 1.0 / paths as f32;
    in_chunks(paths, seed, IMPORTON_SALT, |sampler, path, out| {
        match source {
            ImportonSource::Camera => {
                let Some(cam) = scene.camera.as_ref() else {
                    return;
                };
                let film = Vec2::new(cam.width as f32, cam.height as f32);
                let raster = sampler.next_2d() * film;
                bdpt.camera_subpath(scene, raster, WalkLimits::BDPT, sampler, path);
            }
            ImportonSource::Meter(m) => {
                bdpt.meter_subpath(scene, m, WalkLimits::BDPT, sampler, path)
            }
        }
        out.extend((1..path.len()).filter_map(|i| particle_at(path, i, scale)));
    })
}
// ANCHOR_END: trace_importons

/// The classical tracer for either quantity with BDPT's default walks (Russian roulette, no
/// depth limit); importons start at [`ImportonSource::default_for`] the scene.
pub fn trace_classical(
    scene: &Scene,
    tech: &dyn LocalSampling,
    quantity: Quantity,
    paths: u64,
    seed: u64,
) -> Vec<Particle> {
    let bdpt = Bdpt::new(tech, None, Strategies::All);
    match quantity {
        Quantity::Radiance => trace_photons(scene, &bdpt, paths, seed),
        Quantity::Importance => match ImportonSource::default_for(scene) {
            Some(src) => trace_importons(scene, &bdpt, src, paths, seed),
            None => Vec::new(),
        },
    }
}

/// Longest path the bidirectional particle sampler draws (edges): p_k = 2^-k is truncated
/// here and renormalized, which changes p_k by 2^-24.
pub const BIDIRECTIONAL_MAX_LENGTH: usize = 24;
const BIDIRECTIONAL_SALT: u64 = 0x6269_6469_7200_0000;

/// p_k of the truncated length distribution, k in 1..=[`BIDIRECTIONAL_MAX_LENGTH`].
fn length_pmf(k: usize) -> f64 {
    let z = 1.0 - 0.5f64.powi(BIDIRECTIONAL_MAX_LENGTH as i32);
    if (1..=BIDIRECTIONAL_MAX_LENGTH).contains(&k) {
        0.5f64.powi(k as i32) / z
    } else {
        0.0
    }
}

/// P(K >= n): the probability that the drawn length can hold a particle n edges from its
/// source with at least one more edge behind it (q of Kristensen 2010, sec. 5.2.2).
fn length_at_least(n: usize) -> f64 {
    (n..=BIDIRECTIONAL_MAX_LENGTH).map(length_pmf).sum()
}

fn sample_length(u: f64) -> usize {
    let mut acc = 0.0;
    for k in 1..=BIDIRECTIONAL_MAX_LENGTH {
        acc += length_pmf(k);
        if u < acc {
            return k;
        }
    }
    BIDIRECTIONAL_MAX_LENGTH
}

/// Photons and importons from one sampler.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleSets {
    pub photons: Vec<Particle>,
    pub importons: Vec<Particle>,
}

impl ParticleSets {
    pub fn clear(&mut self) {
        self.photons.clear();
        self.importons.clear();
    }

    /// Moves `other`'s particles to the end of these.
    pub fn append(&mut self, other: &mut ParticleSets) {
        self.photons.append(&mut other.photons);
        self.importons.append(&mut other.importons);
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty() && self.importons.is_empty()
    }

    /// Multiplies every weight by `f`.
    pub(crate) fn scale(&mut self, f: f32) {
        for p in self.photons.iter_mut().chain(self.importons.iter_mut()) {
            p.weight *= f;
        }
    }
}

/// The bidirectional particle sampler (Kristensen 2010, sec. 5.2.2), made unbiased.
///
/// One sample is one path x_0 (light) ... x_k (sensor): the length k with p_k = 2^-k, the split
/// s uniform in 0..=k+1, a light walk of s vertices and an eye walk of t = k + 1 - s vertices
/// (no Russian roulette: k is the roulette). A photon at x_i (1 <= i <= k - 1) represents the
/// light subpath x_0 ... x_i; an importon at x_i the eye subpath x_i ... x_k.
///
/// What the thesis prints, alpha = (k+2) p_{s,t}^2 / sum p^2 f_L / (p_{s,t} q_i), is unbiased
/// only with three precisions, derived here (book, "Bidirectional particles"):
/// 1. Which splits compete. For the photon at x_i the eye-sampled vertices' densities depend on
///    x_{i+1}, x_{i+2} (the "tail" the eye walk drew first). A power-heuristic weight that
///    depends on the tail sums to one over the splits that see the same tail distribution:
///    s' = 0 ..= i (x_i eye-sampled, the tail is the eye walk's first k - i vertices) and
///    s' = i + 1 (x_0 ... x_i light-sampled, the tail an independent eye walk of k - i
///    vertices). Splits s' > i + 1 draw the tail's first vertices from the light side, so the
///    photons of a light walk count at its last vertex only.
/// 2. Walks that stop early. When the eye walk of s = i + 1 ends before its tail is complete, no
///    other split could have produced x_i with it: the weight is 1.
/// 3. q. Combining the lengths k >= i + 1 (the sensor vertex x_k carries no scene particle)
///    gives q = P(K >= i + 1) = 2^-i for a photon i edges from the light: the thesis's "q_1 for
///    direct light, q_{n+1} for the n-th bounce".
///
/// Importons mirror this with j = k - i edges from the sensor: splits s' = i ..= k compete, and
/// q = P(K >= j + 1). The camera's importons carry the mean pixel's importance (as
/// [`ImportonSource::Camera`]).
///
/// Limitation: f-hat of a Dirac lobe is not evaluated, so subpaths through a mirror or glass
/// vertex carry no particle (the classical tracer has them). Infinite lights are not handled
/// (their vertices lie outside the scene): the sets are empty.
// ANCHOR: trace_bidirectional
pub fn trace_bidirectional(
    scene: &Scene,
    tech: &dyn LocalSampling,
    source: ImportonSource,
    paths: u64,
    seed: u64,
) -> ParticleSets {
    trace_bidirectional_where(scene, tech, source, paths, seed, |_| true)
}
// ANCHOR_END: trace_bidirectional

/// [`trace_bidirectional`] keeping only the particles of the samples whose full-path
/// contribution I(u) passes `keep` (`|i| i > 0`: the part of the particle set the Metropolis
/// sampler without its defensive floor represents).
pub fn trace_bidirectional_where(
    scene: &Scene,
    tech: &dyn LocalSampling,
    source: ImportonSource,
    paths: u64,
    seed: u64,
    keep: impl Fn(f64) -> bool + Sync,
) -> ParticleSets {
    if paths == 0 || !can_trace(scene, source) {
        return ParticleSets::default();
    }
    let bdpt = particle_bdpt(tech);
    let scale = 1.0 / paths as f64;
    let chunks = paths.div_ceil(PARTICLE_CHUNK);
    let parts: Vec<ParticleSets> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let mut sampler = Sampler::new(seed, c ^ BIDIRECTIONAL_SALT, 0);
            let mut walks = Scratch::default();
            let mut out = ParticleSets::default();
            let mut one = ParticleSets::default();
            for _ in 0..PARTICLE_CHUNK.min(paths - c * PARTICLE_CHUNK) {
                one.clear();
                let i = bidirectional_sample(
                    scene,
                    &bdpt,
                    source,
                    scale,
                    &mut sampler,
                    &mut walks,
                    &mut one,
                );
                if keep(i) {
                    out.append(&mut one);
                }
            }
            out
        })
        .collect();
    let mut all = ParticleSets::default();
    for p in parts {
        all.photons.extend(p.photons);
        all.importons.extend(p.importons);
    }
    all
}

/// The engine of the bidirectional particle samplers: no depth limit (the path length is drawn,
/// and each walk is limited to its part of it by [`WalkLimits::at_most`], without Russian
/// roulette).
pub(crate) fn particle_bdpt(tech: &dyn LocalSampling) -> Bdpt<'_> {
    Bdpt::new(tech, None, Strategies::All)
}

/// Whether `source` can start importons in `scene` (and the scene's lights can be handled).
pub(crate) fn can_trace(scene: &Scene, source: ImportonSource) -> bool {
    if scene.lights.is_empty() || scene.lights.iter().any(|l| l.is_infinite()) {
        return false;
    }
    match source {
        ImportonSource::Camera => scene.camera.is_some(),
        ImportonSource::Meter(m) => (m as usize) < scene.sensors.len(),
    }
}

/// The power-heuristic weight of split `s` among `candidates` (densities; zero ones cannot
/// produce the subpath and are left out).
fn power_weight(s: usize, densities: &[(usize, f64)]) -> f64 {
    let own = densities.iter().find(|(i, _)| *i == s).map_or(0.0, |d| d.1);
    let sum: f64 = densities
        .iter()
        .filter(|(_, p)| *p > 0.0 && p.is_finite())
        .map(|(_, p)| p * p)
        .sum();
    if own > 0.0 && sum > 0.0 {
        own * own / sum
    } else {
        0.0
    }
}

/// Primary-sample streams of one bidirectional particle sample: the length and split, the light
/// walk, the eye walk, the evaluation (transmittance estimates of the densities and edges).
const STREAM_CHOICE: usize = 0;
const STREAM_LIGHT: usize = 1;
const STREAM_EYE: usize = 2;
const STREAM_EVAL: usize = 3;

/// One sample of the bidirectional particle sampler: pushes its particles (weights times
/// `scale`) into `out` and returns I(u), the luminance of the full path's own contribution to
/// the measurement (the target of the Metropolis particle sampler, Kristensen 2010, eq. (5.15)):
/// (k + 2) / p_k * w_s f(x) / p_s(x), with the power heuristic over the splits s' = 0 ..= k that
/// reach the sensor. Zero when a walk ended early or the full path carries no light.
// ANCHOR: bidirectional_sample
pub(crate) fn bidirectional_sample(
    scene: &Scene,
    bdpt: &Bdpt,
    source: ImportonSource,
    scale: f64,
    sampler: &mut Sampler,
    walks: &mut Scratch,
    out: &mut ParticleSets,
) -> f64 {
    let Some(split) = draw_walks(scene, bdpt, source, sampler, walks) else {
        return 0.0;
    };
    let Split { k, s, t, n_pix } = split;
    sampler.set_stream(STREAM_EVAL);
    if t == 0 {
        return 0.0;
    }
    let (light, eye) = (&walks.light, &walks.eye);
    if !(light.len() == s && eye.len() == t) {
        early_particles(&split, scale, walks, out);
        return 0.0;
    }
    let Some(path) = full_path(scene, light, eye, s, k) else {
        return 0.0;
    };
    let full = FullPath::new(scene, bdpt, &path, n_pix, sampler);
    let contribution = full.contribution(s);
    full.photons(s, scale, out);
    full.importons(s, scale, out);
    contribution
}
// ANCHOR_END: bidirectional_sample

/// The length k, the split s and t = k + 1 - s of one bidirectional particle sample, and the
/// number of pixels its importance is shared by (1 for a meter).
struct Split {
    k: usize,
    s: usize,
    t: usize,
    n_pix: f64,
}

/// Draws the length and split (stream [`STREAM_CHOICE`]), the light walk of s vertices
/// ([`STREAM_LIGHT`]) and the eye walk of t ([`STREAM_EYE`]) into `walks`; `None` without the
/// camera the importons come from.
fn draw_walks(
    scene: &Scene,
    bdpt: &Bdpt,
    source: ImportonSource,
    sampler: &mut Sampler,
    walks: &mut Scratch,
) -> Option<Split> {
    sampler.set_stream(STREAM_CHOICE);
    let k = sample_length(sampler.next_f64());
    let s = sampler.next_index(k + 2);
    let t = k + 1 - s; // t = 0: the light walk would have to hit the sensor
    walks.light.clear();
    if s > 0 {
        sampler.set_stream(STREAM_LIGHT);
        bdpt.light_subpath(scene, WalkLimits::at_most(s), sampler, &mut walks.light);
    }
    sampler.set_stream(STREAM_EYE);
    let eye_limits = WalkLimits::at_most(t.max(1));
    let n_pix = match source {
        ImportonSource::Camera => {
            let cam = scene.camera.as_ref()?;
            let film = Vec2::new(cam.width as f32, cam.height as f32);
            let raster = sampler.next_2d() * film;
            bdpt.camera_subpath(scene, raster, eye_limits, sampler, &mut walks.eye);
            (cam.width as f64) * (cam.height as f64)
        }
        ImportonSource::Meter(m) => {
            bdpt.meter_subpath(scene, m, eye_limits, sampler, &mut walks.eye);
            1.0
        }
    };
    Some(Split { k, s, t, n_pix })
}

/// A walk ended early (precision 2.): the last vertex of the complete light walk is a photon
/// with weight 1 among the splits (no tail for the others); the last vertex of a complete eye
/// walk an importon likewise.
fn early_particles(split: &Split, scale: f64, walks: &Scratch, out: &mut ParticleSets) {
    let Split { k, s, t, .. } = *split;
    let (light, eye) = (&walks.light, &walks.eye);
    if light.len() == s && s >= 2 && s - 1 < k {
        let i = s - 1;
        let f = (k + 2) as f64 / length_at_least(i + 1) * scale;
        if let Some(p) = particle_at(light, i, f as f32) {
            out.photons.push(p);
        }
    }
    if eye.len() == t && t >= 2 && s >= 1 {
        // the importon at x_s, j = k - s edges from the sensor
        let j = t - 1;
        let f = (k + 2) as f64 / length_at_least(j + 1) * scale;
        if let Some(p) = particle_at(eye, t - 1, f as f32) {
            out.importons.push(p);
        }
    }
}

/// The full path x_0 ... x_k of complete walks; for s = 0 the eye walk's emitter made the light
/// vertex (`None` when it did not end on one).
fn full_path(
    scene: &Scene,
    light: &[Vertex],
    eye: &[Vertex],
    s: usize,
    k: usize,
) -> Option<crate::path::Path> {
    let mut x: Vec<Vertex> = Vec::with_capacity(k + 1);
    x.extend_from_slice(light);
    x.extend(eye.iter().rev().copied());
    // the two walks' last vertices are joined by the connection, not by whatever lobe their
    // own walks took there (a plastic vertex may have taken its Dirac coat)
    for j in [s.saturating_sub(1), s.min(k)] {
        x[j].delta = false;
    }
    if s == 0 {
        // the eye walk must have found an emitter: make it the light vertex
        let VertexKind::Surface { prim } = x[0].kind else {
            return None;
        };
        let l = scene.shapes[scene.prim_shape[prim as usize] as usize].light?;
        x[0].kind = VertexKind::Light {
            light: l,
            prim: Some(prim),
        };
    }
    Some(crate::path::Path { vertices: x })
}

/// A complete sample's full path with what its particles' weights are made of: the densities of
/// every vertex from both ends, G T of every edge, L_e and W_e (physical light flow, x_0 -> x_k).
struct FullPath<'a> {
    scene: &'a Scene,
    x: &'a [Vertex],
    k: usize,
    d: crate::path::pdf::Densities,
    gt: Vec<Rgb>,
    le: Rgb,
    we: Rgb,
}

impl<'a> FullPath<'a> {
    fn new(
        scene: &'a Scene,
        bdpt: &Bdpt,
        path: &'a crate::path::Path,
        n_pix: f64,
        sampler: &mut Sampler,
    ) -> Self {
        use crate::path::geometry_term::geometry_term_unoccluded;
        let x = &path.vertices[..];
        let k = x.len() - 1;
        let d = crate::path::pdf::densities(scene, bdpt.tech, path, sampler);
        // G T of every edge and f-hat of every inner vertex (physical light flow, x_0 -> x_k)
        let mut gt = vec![Rgb::ZERO; k];
        for m in 0..k {
            let e = scene.edge(
                x[m].edge_end(x[m + 1].p),
                x[m + 1].edge_end(x[m].p),
                sampler,
            );
            gt[m] = e.transmittance * geometry_term_unoccluded(&x[m], &x[m + 1]);
        }
        let le = x[0].emitted(scene, x[1].p);
        let we = match x[k].kind {
            VertexKind::Camera => x[k].importance(scene, x[k - 1].p) / n_pix as f32,
            _ => x[k].importance(scene, x[k - 1].p),
        };
        FullPath {
            scene,
            x,
            k,
            d,
            gt,
            le,
            we,
        }
    }

    /// f-hat at inner vertex m: zero at a Dirac vertex (its f-hat is not evaluated, see the
    /// limitation above; plastic's regular lobe must not stand in for its coat).
    fn f_inner(&self, m: usize) -> Rgb {
        let x = self.x;
        if x[m].delta {
            return Rgb::ZERO;
        }
        x[m].f_hat(self.scene, x[m - 1].p, x[m + 1].p)
    }

    fn light_d(&self, a: usize, b: usize) -> f64 {
        (a..b).map(|m| self.d.light[m] as f64).product()
    }

    fn eye_d(&self, a: usize, b: usize) -> f64 {
        (a..b).map(|m| self.d.eye[m] as f64).product()
    }

    /// I(u): the full path's contribution, power heuristic over the splits that reach the
    /// sensor.
    fn contribution(&self, s: usize) -> f64 {
        let k = self.k;
        let split_pdf = |sp: usize| self.light_d(0, sp) * self.eye_d(sp, k + 1);
        let cands: Vec<(usize, f64)> = (0..=k).map(|sp| (sp, split_pdf(sp))).collect();
        let w = power_weight(s, &cands);
        let p = split_pdf(s);
        let mut f = self.le * self.we;
        for (m, g) in self.gt.iter().enumerate() {
            f *= *g;
            if m >= 1 {
                f *= self.f_inner(m);
            }
        }
        let c = crate::spectrum::luminance(f) as f64 * w / p * (k + 2) as f64 / length_pmf(k);
        if w > 0.0 && p > 0.0 && c.is_finite() && c > 0.0 {
            c
        } else {
            0.0
        }
    }

    /// Photons at x_i, 1 <= i <= k - 1, from splits s <= i + 1.
    fn photons(&self, s: usize, scale: f64, out: &mut ParticleSets) {
        let (k, x) = (self.k, self.x);
        for i in s.saturating_sub(1).max(1)..k {
            let split_pdf = |sp: usize| self.light_d(0, sp) * self.eye_d(sp, i + 1);
            let cands: Vec<(usize, f64)> = (0..=i + 1).map(|sp| (sp, split_pdf(sp))).collect();
            let w = power_weight(s, &cands);
            let p = split_pdf(s);
            if w <= 0.0 || p <= 0.0 {
                continue;
            }
            // f_L(x_0 ... x_i) = L_e prod G T prod f-hat (x_i's own scattering not included)
            let mut f = self.le;
            for (m, g) in self.gt.iter().enumerate().take(i) {
                f *= *g;
                if m >= 1 {
                    f *= self.f_inner(m);
                }
            }
            if f == Rgb::ZERO {
                continue;
            }
            let a = (k + 2) as f64 / length_at_least(i + 1) * w / p * scale;
            let towards = (x[i - 1].p - x[i].p).normalize_or_zero();
            if let Some(ph) = particle_with(&x[i], towards, f * a as f32, i) {
                out.photons.push(ph);
            }
        }
    }

    /// Importons at x_i, 1 <= i <= k - 1, from splits s >= i (x_i ... x_k), j = k - i.
    fn importons(&self, s: usize, scale: f64, out: &mut ParticleSets) {
        let (k, x) = (self.k, self.x);
        for i in 1..=s.min(k - 1) {
            let split_pdf = |sp: usize| self.light_d(i, sp) * self.eye_d(sp, k + 1);
            let cands: Vec<(usize, f64)> = (i..=k).map(|sp| (sp, split_pdf(sp))).collect();
            let w = power_weight(s, &cands);
            let p = split_pdf(s);
            if w <= 0.0 || p <= 0.0 {
                continue;
            }
            // f_E(x_i ... x_k) = W_e prod G T prod f-hat (x_i's own scattering not included)
            let mut f = self.we;
            for (m, g) in self.gt.iter().enumerate().skip(i) {
                f *= *g;
                if m > i {
                    f *= self.f_inner(m);
                }
            }
            if f == Rgb::ZERO {
                continue;
            }
            let j = k - i;
            let a = (k + 2) as f64 / length_at_least(j + 1) * w / p * scale;
            // the importon's direction points towards the sensor: from x_i to x_{i+1}
            let towards = (x[i + 1].p - x[i].p).normalize_or_zero();
            if let Some(im) = particle_with(&x[i], towards, f * a as f32, j) {
                out.importons.push(im);
            }
        }
    }
}
