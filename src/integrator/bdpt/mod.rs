//! The `light` and `bdpt` integrators: the bidirectional engine of [`crate::bidir`] (Veach
//! 1997 ch. 10) as the render loop sees it, light tracing being its t = 1 strategies alone. One
//! sample traces a camera (or meter) subpath and a light subpath, and [`Bdpt::combine`] adds
//! every strategy of it into the sample's own pixel (or meter) and the film's splats; the
//! per-strategy images of `--strategy-images` are in [`strategy_images`].
//! Book: "Bidirectional path tracing".

mod combine;
mod strategy_images;

pub use crate::bidir::{
    mis_weight_of_path, Bdpt, MisHeuristic, Scratch, Strategies, MAX_SUBPATH_VERTICES,
};
pub use combine::Splat;
pub use strategy_images::strategy_images;

use super::{Integrator, IntegratorError, Setup};
use crate::bidir::SensorStart;
use crate::math::Sampler;
use crate::scene::{Camera, Scene};
use crate::spectrum::Rgb;

/// Splats a light or BDPT sample deposits on average (a light subpath's vertices seen by the
/// camera; about 3 measured on the fog box), for the memory estimate.
const SPLATS_PER_SAMPLE: u64 = 4;

/// The facts of `light` and `bdpt` (which differ in their strategies): tile results and
/// splats, light start points, split by passes.
pub struct BdptFacts(pub Strategies);

impl super::Facts for BdptFacts {
    fn prepare<'t>(
        &self,
        setup: &Setup<'_, 't>,
    ) -> Result<Box<dyn Integrator + 't>, IntegratorError> {
        prepare(setup, self.0)
    }

    fn samples_light_starts(&self) -> bool {
        true
    }

    /// Light subpaths start at volume vertices x0 of the glowing media too (eq. 5), the eye
    /// subpath's collisions collect L_e,V0 (s = 0) and next-event estimation samples x0 (s = 1).
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        None
    }

    /// Light tracing joins the sensor only from a non-specular vertex; BDPT's other
    /// strategies reach those paths.
    fn unreachable(&self) -> super::reach::Unreachable {
        match self.0 {
            Strategies::LightTracing => super::reach::Unreachable::SpecularSeenBySensor,
            _ => super::reach::Unreachable::Nothing,
        }
    }

    fn pass_footprint(&self, _: &super::Case) -> super::PassFootprint {
        super::PassFootprint {
            tiles: true,
            bytes_per_sample: SPLATS_PER_SAMPLE * super::SPLAT_BYTES,
        }
    }

    /// Light tracing's t = 1 strategies add to other pixels as splats, which a pixel's own
    /// samples do not see: the film's per-pixel variance would leave them out.
    fn pixel_variance(&self) -> bool {
        false
    }

    /// BDPT's (s, t) strategies one by one (light tracing's are all t = 1).
    fn takes(&self, option: super::OwnOption) -> bool {
        use super::OwnOption::*;
        matches!(option, StrategyImages | PixelSamples | MisHeuristic) && self.0 == Strategies::All
    }
}

/// The bidirectional engine with `strategies` (all for `bdpt`, t = 1 for `light`).
pub fn prepare<'t>(
    setup: &Setup<'_, 't>,
    strategies: Strategies,
) -> Result<Box<dyn Integrator + 't>, IntegratorError> {
    let bdpt = Bdpt::new(setup.technique, setup.max_depth, strategies);
    Ok(Box::new(bdpt.with_heuristic(setup.settings.mis_heuristic)))
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
        scratch: &mut super::Scratch,
    ) -> Rgb {
        let walks = scratch.own.get::<Scratch>();
        self.sample(scene, SensorStart::Camera(raster), sampler, walks);
        self.combine(scene, walks, sampler, &mut scratch.splats)
    }

    fn meter_sample(
        &self,
        scene: &Scene,
        meter: u32,
        sampler: &mut Sampler,
        scratch: &mut super::Scratch,
    ) -> Rgb {
        let walks = scratch.own.get::<Scratch>();
        self.sample(scene, SensorStart::Meter(meter), sampler, walks);
        self.combine(scene, walks, sampler, &mut scratch.splats)
    }

    fn technique_images(
        &self,
        scene: &crate::scene::Scene,
        seed: u64,
        pass: u64,
        spp: u32,
        max_depth_shown: u32,
    ) -> Option<std::collections::BTreeMap<(usize, usize), crate::film::Film>> {
        Some(strategy_images(
            scene,
            self,
            seed,
            pass,
            spp,
            max_depth_shown,
        ))
    }
}
