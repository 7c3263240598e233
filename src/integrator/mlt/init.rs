//! Initialization (Pauly, Kollig, Keller 2000 sec. 5.1; Veach 1997 sec. 11.3.1): a BDPT
//! pre-pass of n samples estimates b = integral of f* over path space, and every chain's seed
//! path is drawn from the pre-pass paths with probability proportional to its (MIS-weighted)
//! contribution. Each pre-pass sample traces a camera subpath through a uniform point of the
//! whole film and a light subpath, and every strategy (s, t) yields one weighted path
//! w_{s,t} f / p_{s,t}; their luminances are the resampling weights, and b_n is their sum over
//! n. Then E[b_n g(x_seed)] = integral of f* g for any g, so the image is unbiased whatever n
//! (averaged over runs, initialization included); n only sets the start-up error of one run.

use glam::Vec2;
use rayon::prelude::*;

use crate::bidir::{Bdpt, Scratch};
use crate::math::Sampler;
use crate::path::{Vertex, VertexKind};
use crate::scene::Scene;
use crate::spectrum::{luminance, Rgb};

/// Salt that keeps the pre-pass streams apart from chains and pixels.
const BOOTSTRAP_STREAM_SALT: u64 = 0x626f_6f74_0000_0000;
/// Pre-pass samples per parallel work item.
const BOOTSTRAP_CHUNK: u64 = 1024;

/// One weighted pre-pass path, named by how to regenerate it.
#[derive(Clone, Copy, Debug)]
pub struct Candidate {
    pub sample: u64,
    pub s: usize,
    pub t: usize,
    /// Luminance of the strategy's contribution to the film sum.
    pub weight: f64,
}

/// The pre-pass: b_n and the candidates with their cumulative weights.
#[derive(Clone, Debug, Default)]
pub struct Bootstrap {
    pub b: f64,
    pub samples: u64,
    pub candidates: Vec<Candidate>,
    cdf: Vec<f64>,
}

/// Runs one pre-pass sample and calls `visit(s, t, contribution, raster, joined path)` for each
/// strategy with a non-zero contribution, in the order BDPT's `combine` uses. The subpaths are
/// traced into `walks` (the caller's, reused from one sample to the next).
fn run_sample(
    scene: &Scene,
    bdpt: &Bdpt,
    seed: u64,
    sample: u64,
    want_path: Option<(usize, usize)>,
    walks: &mut Scratch,
    visit: &mut dyn FnMut(usize, usize, Rgb, bool, Option<Vec<Vertex>>) -> bool,
) {
    let Some(cam) = scene.camera.as_ref() else {
        return;
    };
    let mut sampler = Sampler::new(seed, BOOTSTRAP_STREAM_SALT ^ sample, 0);
    let u = sampler.next_2d();
    let raster = Vec2::new(u.x * cam.width as f32, u.y * cam.height as f32);
    let start = crate::bidir::SensorStart::Camera(raster);
    bdpt.sample(scene, start, &mut sampler, walks);
    let (light, eye) = (&walks.light, &walks.eye);
    bdpt.for_each_strategy(
        scene,
        light,
        eye,
        &mut sampler,
        &mut |s, t, l, splat, sampled| {
            let path =
                (want_path == Some((s, t))).then(|| joined_path(scene, light, eye, s, t, sampled));
            visit(s, t, l, splat.is_some(), path)
        },
    );
}

/// The path x_0 (light) ... x_k (camera; a thin lens's point as BDPT sampled it) of strategy
/// (s, t): `light[..s]`, then `eye[..t]` reversed, with the endpoint the connection sampled
/// (s = 1: the light vertex; t = 1: the sensor, a lens point of its own). For s = 0 the eye
/// subpath's emitter vertex becomes the light vertex.
pub fn joined_path(
    scene: &Scene,
    light: &[Vertex],
    eye: &[Vertex],
    s: usize,
    t: usize,
    sampled: Option<Vertex>,
) -> Vec<Vertex> {
    // s = 1 samples its light vertex itself, whatever the light subpath holds
    let mut v: Vec<Vertex> = match (s, sampled) {
        (1, Some(q)) => vec![q],
        _ => light[..s].to_vec(),
    };
    let start = v.len();
    v.extend(eye[..t].iter().rev().copied());
    if t == 1 && s != 1 {
        if let Some(q) = sampled {
            v[start] = q;
        }
    }
    if s == 0 {
        if let VertexKind::Surface { prim } = v[0].kind {
            if let Some(l) = scene.shapes[scene.prim_shape[prim as usize] as usize].light {
                v[0].kind = VertexKind::Light {
                    light: l,
                    prim: Some(prim),
                };
            }
        }
    }
    v
}

/// The resampling weight of one strategy's contribution: its luminance as an estimate of the
/// film sum (a contribution to the sample's own pixel estimates that pixel, so times the pixel
/// count; a splat already estimates the film).
fn film_weight(l: Rgb, splat: bool, npix: f64) -> f64 {
    luminance(l) as f64 * if splat { 1.0 } else { npix }
}

// ANCHOR: film_weights
/// Traces pre-pass samples `samples` (reusing one pair of subpath buffers) and calls
/// `f(sample, s, t, weight)` for every strategy whose film weight is positive and finite: what
/// both the bootstrap and the refinement of b add up.
fn film_weights(
    scene: &Scene,
    bdpt: &Bdpt,
    seed: u64,
    samples: std::ops::Range<u64>,
    npix: f64,
    mut f: impl FnMut(u64, usize, usize, f64),
) {
    let mut walks = Scratch::default();
    for sample in samples {
        run_sample(
            scene,
            bdpt,
            seed,
            sample,
            None,
            &mut walks,
            &mut |s, t, l, splat, _| {
                let w = film_weight(l, splat, npix);
                if w > 0.0 && w.is_finite() {
                    f(sample, s, t, w);
                }
                true
            },
        );
    }
}

// ANCHOR_END: film_weights

fn pixel_count(scene: &Scene) -> f64 {
    scene
        .camera
        .as_ref()
        .map_or(1.0, |c| (c.width * c.height) as f64)
}

impl Bootstrap {
    /// The pre-pass of `n` samples (parallel, deterministic for `seed`).
    // ANCHOR: bootstrap
    pub fn run(scene: &Scene, bdpt: &Bdpt, n: u64, seed: u64) -> Bootstrap {
        let npix = pixel_count(scene);
        let chunks = n.div_ceil(BOOTSTRAP_CHUNK);
        let parts: Vec<Vec<Candidate>> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut out = Vec::new();
                let chunk = c * BOOTSTRAP_CHUNK..((c + 1) * BOOTSTRAP_CHUNK).min(n);
                film_weights(scene, bdpt, seed, chunk, npix, |sample, s, t, weight| {
                    out.push(Candidate {
                        sample,
                        s,
                        t,
                        weight,
                    })
                });
                out
            })
            .collect();
        let candidates: Vec<Candidate> = parts.into_iter().flatten().collect();
        let mut cdf = Vec::with_capacity(candidates.len());
        let mut acc = 0.0;
        for c in &candidates {
            acc += c.weight;
            cdf.push(acc);
        }
        Bootstrap {
            b: acc / n.max(1) as f64,
            samples: n,
            candidates,
            cdf,
        }
    }
    // ANCHOR_END: bootstrap

    /// The sum of the film weights of pre-pass samples `start..end` (the same samples `run`
    /// would draw with those indices): more samples for the estimate of b, without keeping
    /// candidates. Summed per chunk in index order, so the result is independent of threads.
    // ANCHOR: refine
    pub fn weight_sum(scene: &Scene, bdpt: &Bdpt, seed: u64, start: u64, end: u64) -> f64 {
        let npix = pixel_count(scene);
        let first = start / BOOTSTRAP_CHUNK;
        let last = end.div_ceil(BOOTSTRAP_CHUNK);
        let parts: Vec<f64> = (first..last)
            .into_par_iter()
            .map(|c| {
                let mut acc = 0.0;
                let lo = (c * BOOTSTRAP_CHUNK).max(start);
                let hi = ((c + 1) * BOOTSTRAP_CHUNK).min(end);
                film_weights(scene, bdpt, seed, lo..hi, npix, |_, _, _, w| acc += w);
                acc
            })
            .collect();
        parts.iter().sum()
    }
    // ANCHOR_END: refine

    /// The candidate a uniform `u` in [0, 1) selects, with probability proportional to weight.
    pub fn select(&self, u: f64) -> Option<&Candidate> {
        let total = *self.cdf.last()?;
        let i = self.cdf.partition_point(|&c| c <= u * total);
        self.candidates.get(i.min(self.candidates.len() - 1))
    }

    /// Regenerates a candidate's path (the same random stream, replayed).
    pub fn path_of(scene: &Scene, bdpt: &Bdpt, seed: u64, c: &Candidate) -> Option<Vec<Vertex>> {
        let mut found = None;
        run_sample(
            scene,
            bdpt,
            seed,
            c.sample,
            Some((c.s, c.t)),
            &mut Scratch::default(),
            &mut |s, t, _, _, p| {
                if (s, t) == (c.s, c.t) {
                    found = p;
                    return false;
                }
                true
            },
        );
        // a light at infinity on its first edge (BDPT places it beyond the disk it started on)
        if let Some(path) = found.as_mut() {
            super::contribution::anchor_infinite(scene, path);
        }
        found
    }
}
