//! One sample's strategies combined: every (s, t) within the depth limit connected by the
//! engine ([`crate::bidir::connect`]), MIS-weighted as the strategies ask, into the sample's
//! own pixel (or meter) and the film's splats.

use crate::bidir::{Bdpt, Scratch, Strategies};
use crate::math::Sampler;
use crate::path::subpath::{self, Cached};
use crate::path::VertexKind;
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// One contribution for the film: to the sample's own pixel (`None`) or splatted.
pub use crate::integrator::Splat;

impl Bdpt<'_> {
    /// All strategies for one sensor sample whose eye subpath is `scratch.eye`: returns the
    /// contribution to the sample's own pixel (or meter) and pushes splats for t = 1.
    pub fn combine(
        &self,
        scene: &Scene,
        scratch: &mut Scratch,
        sampler: &mut Sampler,
        splats: &mut Vec<Splat>,
    ) -> Rgb {
        // the values every connection through a vertex reads, once per sample
        subpath::fill(&scratch.light, &mut scratch.light_cache);
        subpath::fill(&scratch.eye, &mut scratch.eye_cache);
        let light = Cached {
            path: &scratch.light,
            cache: &scratch.light_cache,
        };
        let eye = Cached {
            path: &scratch.eye,
            cache: &scratch.eye_cache,
        };
        let mut own = Rgb::ZERO;
        let meter = matches!(
            eye.path.first().map(|v| v.kind),
            Some(VertexKind::Meter { .. })
        );
        for t in 1..=eye.path.len() {
            for s in 0..=Bdpt::max_light_vertices(scene, light.path) {
                let depth = s as i64 + t as i64 - 2;
                if depth < scene.min_depth() as i64 || depth as u64 > self.max_depth as u64 {
                    continue;
                }
                match self.strategies {
                    Strategies::LightTracing if t != 1 => continue,
                    Strategies::Only(a, b) if (a, b) != (s, t) => continue,
                    _ => {}
                }
                if let Some((l, raster, _)) = self.connect_in(scene, &light, &eye, s, t, sampler) {
                    match raster {
                        Some(r) if !meter => splats.push((r, l)),
                        _ => own += l,
                    }
                }
            }
        }
        own
    }
}
