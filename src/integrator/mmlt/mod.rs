//! Multiplexed Metropolis light transport (Hachisuka, Kaplanyan, Dachsbacher 2014): the
//! chains of primary-sample-space MLT (`integrator::pssmlt`) over *one* BDPT strategy per state.
//! A state's first numbers choose the path's depth d (scattering vertices) and its strategy
//! (s, t) with s + t = d + 2; the walks are drawn with exactly s and t vertices and joined by that
//! strategy alone, weighted by its MIS weight w_{s,t} (`bidir::MisHeuristic`) among the d + 2
//! strategies of the path and divided by the probability of the choice:
//!
//! C(u) = (d + 2) / p(d) w_{s,t}(x) f(x) / p_{s,t}(x).
//!
//! Summed over s the weights are 1, so E_u[C] is BDPT's image, and the chain's target
//! f*(u) = lum(C(u)) makes it spend its steps on the strategies that sample a path well: a
//! small step that changes s switches strategy, and its acceptance compares the two
//! strategies' MIS-weighted contributions. The depth is part of the state too (a choice of this
//! implementation; Hachisuka et al. run chains per depth): uniform over 0..=D with a depth limit
//! D, and p(d) = 1 / ((d + 1)(d + 2)) without one.
//!
//! Bootstrap, normalization, large and small steps, determinism: PSSMLT's, with its options
//! (`[render.pssmlt]`, `--pssmlt-*`).
//! Book: "Primary-sample-space and multiplexed MLT", section "Multiplexed MLT".

use glam::Vec2;

use super::pssmlt::kernel::{Deposit, Target};
use super::pssmlt::sample::{STREAM_CONNECT, STREAM_EYE, STREAM_FILM, STREAM_LIGHT};
use super::pssmlt::{check_scene, Pssmlt, PssmltFacts};
use crate::bidir::{Bdpt, WalkLimits, MAX_SUBPATH_VERTICES};
use crate::math::Sampler;
use crate::scene::Scene;
use crate::spectrum::{luminance, Rgb};

/// One strategy of a BDPT sample as the target of a primary-sample chain.
pub struct MultiplexedTarget<'a> {
    pub scene: &'a Scene,
    pub bdpt: &'a Bdpt<'a>,
    pub walks: crate::bidir::Scratch,
    /// The film's size W x H in pixels.
    pub film: Vec2,
}

/// The depth d and its probability: uniform over 0..=D under a depth limit D, else
/// p(d) = 1 / ((d + 1)(d + 2)) (inverse CDF: P(d' <= d) = 1 - 1 / (d + 2)).
// ANCHOR: depth
pub fn sample_depth(u: f64, max_depth: u32) -> (usize, f64) {
    if max_depth < u32::MAX {
        let n = max_depth as usize + 1;
        (((u * n as f64) as usize).min(n - 1), 1.0 / n as f64)
    } else {
        let d = ((1.0 / (1.0 - u)).floor() as usize).saturating_sub(1);
        let d = d.min(2 * MAX_SUBPATH_VERTICES);
        (d, 1.0 / ((d as f64 + 1.0) * (d as f64 + 2.0)))
    }
}
// ANCHOR_END: depth

impl<'a> MultiplexedTarget<'a> {
    pub fn new(scene: &'a Scene, bdpt: &'a Bdpt<'a>) -> Self {
        let film = scene
            .camera
            .as_ref()
            .map_or(Vec2::ZERO, |c| Vec2::new(c.width as f32, c.height as f32));
        MultiplexedTarget {
            scene,
            bdpt,
            walks: Default::default(),
            film,
        }
    }

    /// The state's contribution C(u) and where it lands (`None`: nothing).
    // ANCHOR: contribution
    fn contribution(&mut self, sampler: &mut Sampler) -> Option<(Vec2, Rgb)> {
        let (scene, bdpt) = (self.scene, self.bdpt);
        sampler.set_stream(STREAM_FILM);
        let raster = sampler.next_2d() * self.film;
        let (d, p_d) = sample_depth(sampler.next_f64(), bdpt.max_depth);
        if d < scene.min_depth() as usize {
            // paths of d scattering vertices are not measured (`hide_emitters`)
            return None;
        }
        let strategies = d + 2;
        let s = sampler.next_index(strategies);
        let t = strategies - s;
        sampler.set_stream(STREAM_EYE);
        let eye = &mut self.walks.eye;
        bdpt.camera_subpath(scene, raster, WalkLimits::at_most(t), sampler, eye);
        self.walks.light.clear();
        if s > 0 {
            sampler.set_stream(STREAM_LIGHT);
            let light = &mut self.walks.light;
            bdpt.light_subpath(scene, WalkLimits::at_most(s), sampler, light);
        }
        // a walk that ended early cannot be joined by strategy (s, t); s = 1 samples its own
        // light vertex (next-event estimation); a glowing medium is a light too (its volume
        // vertices x0 start light subpaths, s = 0 collects L_e,V0 at the eye walk's collisions)
        let (light, eye) = (&self.walks.light, &self.walks.eye);
        let unlit = scene.lights.is_empty() && scene.emitters.is_empty();
        if eye.len() != t || (s > 1 && light.len() != s) || unlit {
            return None;
        }
        sampler.set_stream(STREAM_CONNECT);
        let joined = bdpt.connect_in(scene, light.as_slice(), eye.as_slice(), s, t, sampler);
        let (l, splat, _) = joined?;
        let l = l * (strategies as f64 / p_d) as f32;
        Some(match splat {
            Some(r) => (r, l),
            // the image-plane term, as PSSMLT's
            None => (raster, l * (self.film.x * self.film.y)),
        })
    }
    // ANCHOR_END: contribution
}

impl Target for MultiplexedTarget<'_> {
    fn evaluate(&mut self, sampler: &mut Sampler, out: &mut Vec<Deposit>) -> f64 {
        out.clear();
        let Some((r, l)) = self.contribution(sampler) else {
            return 0.0;
        };
        let f = luminance(l).max(0.0) as f64;
        if f.is_finite() && f > 0.0 {
            out.push((r, l));
            f
        } else {
            0.0
        }
    }

    fn storage(&mut self) -> crate::bidir::Scratch {
        std::mem::take(&mut self.walks)
    }
}

/// MMLT's target.
pub fn multiplexed_target<'a>(
    scene: &'a Scene,
    bdpt: &'a Bdpt<'a>,
    walks: crate::bidir::Scratch,
) -> Box<dyn Target + 'a> {
    Box::new(MultiplexedTarget {
        walks,
        ..MultiplexedTarget::new(scene, bdpt)
    })
}

/// MMLT's facts: PSSMLT's, with its own target and name.
pub struct MmltFacts;

impl super::Facts for MmltFacts {
    fn prepare<'t>(
        &self,
        setup: &super::Setup<'_, 't>,
    ) -> Result<Box<dyn super::Integrator + 't>, super::IntegratorError> {
        let mut p = Pssmlt::with_target(
            setup.scene,
            setup.technique,
            setup.settings.pssmlt.clone(),
            setup.seed,
            setup.max_depth,
            ("mmlt", multiplexed_target),
        )?;
        p.bdpt.heuristic = setup.settings.mis_heuristic;
        Ok(Box::new(p))
    }

    /// Each strategy's sample carries its weight among the path's strategies.
    fn takes(&self, option: super::OwnOption) -> bool {
        option == super::OwnOption::MisHeuristic
    }

    fn samples_light_starts(&self) -> bool {
        true
    }

    /// A strategy (s, t) of BDPT's: light subpaths from volume vertices x0 (s >= 2),
    /// next-event estimation of the glowing media (s = 1) and the emission the eye walk's
    /// collisions collect (s = 0), each with its MIS weight among the path's strategies.
    fn emitting_media_refusal(&self) -> Option<&'static str> {
        None
    }

    fn check(&self, case: &super::Case) -> Result<(), super::IntegratorError> {
        check_scene(case.scene, "mmlt").map_err(super::IntegratorError::from)
    }

    fn pass_footprint(&self, case: &super::Case) -> super::PassFootprint {
        PssmltFacts.pass_footprint(case)
    }

    fn memory_parts(&self, case: &super::Case) -> Vec<(&'static str, u64)> {
        PssmltFacts.memory_parts(case)
    }

    fn shard_split(&self) -> super::ShardSplit {
        super::ShardSplit::IndependentChains
    }

    fn chains(&self) -> Option<super::ChainCount> {
        PssmltFacts.chains()
    }

    fn statistics_key(&self) -> Option<&'static str> {
        Some("mmlt")
    }

    fn pixel_variance(&self) -> bool {
        PssmltFacts.pixel_variance()
    }
}
