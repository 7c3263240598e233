//! BDPT's strategies one by one (`--strategy-images`): each (s, t) of the render loop's
//! samples into a film of its own, unweighted by the others (`Bdpt::connect`).

use std::collections::BTreeMap;

use glam::Vec2;
use rayon::prelude::*;

use super::{Bdpt, Scratch};
use crate::bidir::SensorStart;
use crate::film::Film;
use crate::math::Sampler;
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// One strategy's contribution: (s, t), the raster position it splats to (`None`: the
/// sample's own pixel), the pixel index and the value.
type Contribution = (usize, usize, Option<Vec2>, usize, Rgb);

/// Which samples: pass `pass` of `spp` per pixel of the render with `seed`, strategies of
/// paths up to `max_depth_shown` edges.
#[derive(Clone, Copy)]
struct Samples {
    seed: u64,
    pass: u64,
    spp: u32,
    max_depth_shown: u32,
}

/// BDPT's strategies one by one (see [`crate::integrator::Renderer::strategy_images`]): pass
/// `pass` of `spp` samples per pixel with the streams of the render loop.
pub fn strategy_images(
    scene: &Scene,
    b: &Bdpt,
    seed: u64,
    pass: u64,
    spp: u32,
    max_depth_shown: u32,
) -> BTreeMap<(usize, usize), Film> {
    let mut films = BTreeMap::new();
    let Some(cam) = scene.camera.as_ref() else {
        return films;
    };
    let (w, h) = (cam.width, cam.height);
    let samples = Samples {
        seed,
        pass,
        spp,
        max_depth_shown,
    };
    let rows: Vec<Vec<Contribution>> = (0..h)
        .into_par_iter()
        .map(|y| row(scene, b, samples, y, w))
        .collect();
    for row in rows {
        for (s, t, r, index, l) in row {
            let film = films.entry((s, t)).or_insert_with(|| {
                let mut f = Film::new(w, h);
                f.spp = spp as u64;
                f.splat_count = (w * h) as u64 * spp as u64;
                f
            });
            match r {
                Some(r) => film.add_splat(r, l),
                None => film.add_pixel(index, [l.x as f64, l.y as f64, l.z as f64], [0.0; 3]),
            }
        }
    }
    films
}

/// Every finite contribution of every strategy of the samples of row `y` (`w` pixels), in
/// the render loop's order of random numbers.
fn row(scene: &Scene, b: &Bdpt, samples: Samples, y: u32, w: u32) -> Vec<Contribution> {
    let mut out = Vec::new();
    let mut scratch = Scratch::default();
    for x in 0..w {
        let index = (y * w + x) as usize;
        let mut sampler = Sampler::new(samples.seed, index as u64, samples.pass);
        for _ in 0..samples.spp {
            let raster = Vec2::new(x as f32, y as f32) + sampler.next_2d();
            b.sample(
                scene,
                SensorStart::Camera(raster),
                &mut sampler,
                &mut scratch,
            );
            for t in 1..=scratch.eye.len() {
                for s in 0..=Bdpt::max_light_vertices(scene, &scratch.light) {
                    let depth = s + t;
                    if depth < 2 + scene.min_depth() as usize
                        || depth - 2 > samples.max_depth_shown as usize
                        || depth - 2 > b.max_depth as usize
                    {
                        continue;
                    }
                    if let Some((l, r)) =
                        b.connect(scene, &scratch.light, &scratch.eye, s, t, &mut sampler)
                    {
                        if l.is_finite() {
                            out.push((s, t, r, index, l));
                        }
                    }
                }
            }
        }
    }
    out
}
