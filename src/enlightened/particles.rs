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

use crate::integrator::bdpt::Bdpt;
use crate::math::Sampler;
use crate::path::{Vertex, VertexKind};
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
    let (normal, medium) = match v.kind {
        VertexKind::Surface { .. } => (Some(v.n), None),
        VertexKind::Medium { medium } => (None, Some(medium)),
        _ => return None,
    };
    let direction = (path[i - 1].p - v.p).normalize_or_zero();
    let weight = v.beta * scale;
    if direction == Vec3::ZERO || !weight.is_finite() || weight == Rgb::ZERO {
        return None;
    }
    Some(Particle {
        position: v.p,
        normal,
        medium,
        direction,
        weight,
        depth: i as u32,
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
        bdpt.light_subpath(scene, sampler, path);
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
                bdpt.camera_subpath(scene, raster, sampler, path);
            }
            ImportonSource::Meter(m) => bdpt.meter_subpath(scene, m, sampler, path),
        }
        out.extend((1..path.len()).filter_map(|i| particle_at(path, i, scale)));
    })
}
// ANCHOR_END: trace_importons

/// The classical tracer for either quantity with BDPT's default walks (Russian roulette, no
/// depth limit); importons start at [`ImportonSource::default_for`] the scene.
pub fn trace_classical(scene: &Scene, quantity: Quantity, paths: u64, seed: u64) -> Vec<Particle> {
    let bdpt = Bdpt::new(scene, None, crate::integrator::bdpt::Strategies::All);
    match quantity {
        Quantity::Radiance => trace_photons(scene, &bdpt, paths, seed),
        Quantity::Importance => match ImportonSource::default_for(scene) {
            Some(src) => trace_importons(scene, &bdpt, src, paths, seed),
            None => Vec::new(),
        },
    }
}
