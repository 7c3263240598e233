//! The `light` and `bdpt` integrators: the bidirectional engine of [`super::bdpt`] (Veach 1997
//! ch. 10) as the render loop sees it, light tracing being its t = 1 strategies alone. One
//! sample traces a camera (or meter) subpath and a light subpath and combines them; splats go
//! to the film. Also the per-strategy images of `--strategy-images`.
//! Book: "Bidirectional path tracing".

use rayon::prelude::*;

use super::bdpt::{Bdpt, Strategies};
use super::{Integrator, IntegratorError, Scratch, Setup};
use crate::film::Film;
use crate::math::Sampler;
use crate::path::bidirectional::SensorStart;
use crate::scene::{Camera, Scene};
use crate::spectrum::Rgb;

/// The bidirectional engine with `strategies` (all for `bdpt`, t = 1 for `light`).
pub fn prepare<'t>(
    setup: &Setup<'_, 't>,
    strategies: Strategies,
) -> Result<Box<dyn Integrator + 't>, IntegratorError> {
    Ok(Box::new(Bdpt::new(
        setup.scene,
        setup.technique,
        setup.max_depth,
        strategies,
    )))
}

impl Integrator for Bdpt<'_> {
    fn label(&self) -> String {
        match self.strategies {
            Strategies::LightTracing => "light",
            _ => "bdpt",
        }
        .to_string()
    }

    fn camera_sample(
        &self,
        scene: &Scene,
        _cam: &Camera,
        raster: glam::Vec2,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        self.sample(
            scene,
            SensorStart::Camera(raster),
            sampler,
            &mut scratch.bdpt,
        );
        self.combine(scene, &mut scratch.bdpt, sampler, &mut scratch.splats)
    }

    fn meter_sample(
        &self,
        scene: &Scene,
        meter: u32,
        sampler: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        self.sample(scene, SensorStart::Meter(meter), sampler, &mut scratch.bdpt);
        self.combine(scene, &mut scratch.bdpt, sampler, &mut scratch.splats)
    }

    fn bdpt(&self) -> Option<&Bdpt<'_>> {
        Some(self)
    }
}

/// BDPT's strategies one by one (see [`super::Renderer::strategy_images`]): pass `pass` of
/// `spp` samples per pixel with the streams of the render loop.
pub fn strategy_images(
    scene: &Scene,
    b: &Bdpt,
    seed: u64,
    pass: u64,
    spp: u32,
    max_depth_shown: u32,
) -> std::collections::BTreeMap<(usize, usize), Film> {
    let mut films = std::collections::BTreeMap::new();
    let Some(cam) = scene.camera.as_ref() else {
        return films;
    };
    let (w, h) = (cam.width, cam.height);
    type Row = Vec<(usize, usize, Option<glam::Vec2>, usize, Rgb)>;
    let rows: Vec<Row> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut out = Vec::new();
            let mut scratch = super::bdpt::Scratch::default();
            for x in 0..w {
                let index = (y * w + x) as usize;
                let mut sampler = Sampler::new(seed, index as u64, pass);
                for _ in 0..spp {
                    let raster = glam::Vec2::new(x as f32, y as f32) + sampler.next_2d();
                    b.sample(
                        scene,
                        SensorStart::Camera(raster),
                        &mut sampler,
                        &mut scratch,
                    );
                    for t in 1..=scratch.eye.len() {
                        for s in 0..=Bdpt::max_light_vertices(scene, &scratch.light) {
                            let depth = s + t;
                            if depth < 2
                                || depth - 2 > max_depth_shown as usize
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
        })
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
