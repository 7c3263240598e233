//! The enlightened local-sampling technique (Kristensen 2010, sec. 5.3): light starts from the
//! adjoint image, emission and scattering directions from the guided mixtures, the guided lobe
//! choice at glass and guided roulette, each with its exact density, behind the one interface
//! every walk and density uses ([`LocalSampling`]). Built once, as a preprocessing stage, from
//! the scene and its settings; where a part is absent the plain technique's choice is made
//! with the same random numbers.
//! Book: "Enlightened local path sampling".

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::adjoint::{AdjointError, AdjointImage, AdjointSettings, AdjointStats};
use super::guide::{self, Guide, GuideKind, GuideSettings, GuideStats};
use crate::bsdf::TransportMode;
use crate::math::Sampler;
use crate::path::technique::{LobeChoice, LocalSampling, ScatterSample, StartDraw, PLAIN};
use crate::path::Vertex;
use crate::scene::light::emission_pdf_dir;
use crate::scene::{Light, Scene};

/// Guided mixtures and the adjoint image, each optional: the technique of Kristensen 2010's
/// enlightened samplers. `Enlightened::default()` has neither and samples as [`PLAIN`] does.
#[derive(Clone, Debug, Default)]
pub struct Enlightened {
    /// The guided mixtures (sec. 5.3), when built.
    pub guide: Option<Arc<Guide>>,
    /// The adjoint image (sec. 5.3.1), when estimated: area-light starts are drawn from it.
    pub adjoint: Option<AdjointImage>,
}

/// Why the guide (`guide`) or the adjoint image (`adjoint`) cannot be built for `scene`, naming
/// its first emitting medium; `None` when neither is asked for or no medium glows. Both are
/// built from light starts on the scene's lights (photons traced from them, a map of the unit
/// square onto the area lights), so a light path whose x0 is a volume vertex (eq. 5) would be
/// missing from the guided mixtures' L_i and would have no density under the adjoint image.
pub fn emitting_media_refusal(scene: &Scene, guide: bool, adjoint: bool) -> Option<String> {
    let i = scene.media.iter().position(crate::medium::Medium::emits)?;
    let what = match (guide, adjoint) {
        (false, false) => return None,
        (true, false) => "the guide (--guide, [render.guide] vertices)",
        (false, true) => "the adjoint image (--adjoint-image, [render] adjoint_image)",
        (true, true) => "the guide and the adjoint image",
    };
    Some(format!(
        "{what} cannot be built with the emitting medium `{}`: it is built from light starts on \
         the scene's lights (photons, a map onto the area lights), and light paths that start in \
         the glowing medium (x0 a volume vertex, eq. 5) would be missing; render without it",
        scene.medium_names[i]
    ))
}

impl Enlightened {
    /// Estimates the adjoint image with this technique's classical light starts (any image
    /// already held is dropped first) and keeps it; returns the pre-pass statistics.
    pub fn install_adjoint(
        &mut self,
        scene: &Scene,
        settings: &AdjointSettings,
        seed: u64,
        max_depth: Option<u32>,
    ) -> Result<AdjointStats, AdjointError> {
        self.adjoint = None;
        let image = AdjointImage::render(scene, &*self, settings, seed, max_depth)?;
        let stats = image.stats;
        self.adjoint = Some(image);
        Ok(stats)
    }

    /// Builds the guide `settings` ask for (with `seed` for particles
    /// and clustering) and keeps it; `None` when guiding is off. Any guide already held is
    /// dropped first, so the particles are traced with the unguided walks (and the adjoint
    /// image's light starts, when one is held).
    pub fn install_guide(
        &mut self,
        scene: &Scene,
        settings: &GuideSettings,
        seed: u64,
    ) -> Option<GuideStats> {
        self.guide = None;
        let mut settings = *settings;
        if settings.kind == GuideKind::Off {
            return None;
        }
        settings.seed = seed;
        settings.regions.seed = crate::math::sampler::mix64(seed ^ 0x5245_4749_4f4e);
        let built = guide::build_guide(scene, &*self, settings);
        let stats = built.stats.clone();
        self.guide = Some(Arc::new(built));
        Some(stats)
    }
}

impl LocalSampling for Enlightened {
    fn sample_light_start(
        &self,
        scene: &Scene,
        light: usize,
        u_pos: Vec2,
        sampler: &mut Sampler,
    ) -> StartDraw {
        match (&self.adjoint, &scene.lights[light]) {
            (Some(a), Light::Area { .. }) => match a.sample(scene, u_pos, sampler.next_2d()) {
                Some(st) => StartDraw::Drawn(st),
                None => StartDraw::Failed,
            },
            _ => StartDraw::ByPower,
        }
    }

    // ANCHOR: area_light_start_pdf
    #[inline]
    fn area_light_start_pdf(&self, scene: &Scene, light: u32, prim: u32, p: Vec3) -> f32 {
        match &self.adjoint {
            Some(a) => a.pdf(scene, light, prim, p),
            None => PLAIN.area_light_start_pdf(scene, light, prim, p),
        }
    }
    // ANCHOR_END: area_light_start_pdf

    fn guides_emission(&self, light: &Light) -> bool {
        matches!(light, Light::Area { .. }) && self.guide.is_some()
    }

    fn sample_emission(
        &self,
        scene: &Scene,
        light: &Light,
        (p, n): (Vec3, Vec3),
        d_le: Vec3,
        u: Vec2,
        sampler: &mut Sampler,
    ) -> Option<(Vec3, f32)> {
        match self.guide.as_deref() {
            Some(g) if self.guides_emission(light) => guide::sample_emission(
                g,
                (p, n),
                d_le,
                u,
                |w| emission_pdf_dir(light, n, w),
                sampler,
            ),
            _ => PLAIN.sample_emission(scene, light, (p, n), d_le, u, sampler),
        }
    }

    fn emission_pdf(&self, _: &Scene, light: &Light, p: Vec3, n: Vec3, w: Vec3) -> f32 {
        let p_le = emission_pdf_dir(light, n, w);
        match (light, self.guide.as_deref()) {
            (Light::Area { .. }, Some(g)) => guide::emission_pdf(g, p, n, w, p_le),
            _ => p_le,
        }
    }

    fn sample_scatter_with(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        mode: TransportMode,
        u: Vec2,
        sampler: &mut Sampler,
    ) -> Option<ScatterSample> {
        match self.guide.as_deref() {
            Some(g) => guide::sample_scatter_with(g, scene, v, wo, mode, u, sampler),
            None => PLAIN.sample_scatter_with(scene, v, wo, mode, u, sampler),
        }
    }

    fn scatter_pdf(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        wi: Vec3,
        mode: TransportMode,
    ) -> f32 {
        match self.guide.as_deref() {
            Some(g) => guide::scatter_pdf(g, scene, v, wo, wi, mode),
            None => PLAIN.scatter_pdf(scene, v, wo, wi, mode),
        }
    }

    fn lobe_choice(
        &self,
        scene: &Scene,
        v: &Vertex,
        wo: Vec3,
        mode: TransportMode,
    ) -> Option<LobeChoice> {
        guide::guided_fresnel(self.guide.as_deref()?, scene, v, wo, mode)
    }

    fn roulette_survival(
        &self,
        lhat: Option<f32>,
        throughput_ratio: f32,
        q_max: f32,
    ) -> Option<f32> {
        guide::roulette_survival(self.guide.as_deref()?, lhat, throughput_ratio, q_max)
    }

    fn guides_scattering(&self) -> bool {
        self.guide
            .as_deref()
            .is_some_and(|g| g.settings.kind != GuideKind::Off)
    }
}
