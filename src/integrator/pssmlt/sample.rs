//! A BDPT sample as a function of primary samples: the film point, the eye and light walks and
//! the connections each read their own coordinate stream (`math::primary_sample`), so a small
//! step that lengthens one walk leaves the other walks' numbers in place.

use glam::Vec2;

use super::kernel::{Deposit, Target};
use crate::bidir::{Bdpt, Scratch, WalkLimits};
use crate::math::Sampler;
use crate::scene::Scene;
use crate::spectrum::{luminance, Rgb};

/// The coordinate streams of a sample: the film point, the eye walk, the light walk, the
/// connections (the shadow rays of heterogeneous media and next-event estimation's light points).
pub const STREAM_FILM: usize = 0;
pub const STREAM_EYE: usize = 1;
pub const STREAM_LIGHT: usize = 2;
pub const STREAM_CONNECT: usize = 3;

/// BDPT with every strategy, MIS-weighted, as the target of a primary-sample chain.
///
/// The film point is uniform over the whole film (u_0 W, u_1 H): its density on the image plane
/// is 1 / (W H), where a BDPT pixel sample has density 1 over its pixel, so the sample's own
/// contribution is deposited at its film point times the film's area W H (the image-plane
/// term); the light-tracing strategies (t = 1) deposit at their own film points as BDPT splats
/// them. Then E_u[deposits in pixel j] is pixel j's value, and f*(u) is the deposits' summed
/// luminance.
pub struct BdptTarget<'a> {
    pub scene: &'a Scene,
    pub bdpt: &'a Bdpt<'a>,
    pub walks: Scratch,
    /// The film's size W x H in pixels.
    pub film: Vec2,
}

impl<'a> BdptTarget<'a> {
    pub fn new(scene: &'a Scene, bdpt: &'a Bdpt<'a>) -> Self {
        let film = scene
            .camera
            .as_ref()
            .map_or(Vec2::ZERO, |c| Vec2::new(c.width as f32, c.height as f32));
        BdptTarget {
            scene,
            bdpt,
            walks: Scratch::default(),
            film,
        }
    }
}

impl Target for BdptTarget<'_> {
    // ANCHOR: evaluate
    fn evaluate(&mut self, sampler: &mut Sampler, out: &mut Vec<Deposit>) -> f64 {
        out.clear();
        let (scene, bdpt) = (self.scene, self.bdpt);
        sampler.set_stream(STREAM_FILM);
        let raster = sampler.next_2d() * self.film;
        sampler.set_stream(STREAM_EYE);
        let eye = &mut self.walks.eye;
        bdpt.camera_subpath(scene, raster, WalkLimits::BDPT, sampler, eye);
        sampler.set_stream(STREAM_LIGHT);
        let light = &mut self.walks.light;
        bdpt.light_subpath(scene, WalkLimits::BDPT, sampler, light);
        sampler.set_stream(STREAM_CONNECT);
        let own = bdpt.combine(scene, &mut self.walks, sampler, out);
        // the image-plane term: the film point's density is 1 / (W H)
        if own != Rgb::ZERO {
            out.push((raster, own * (self.film.x * self.film.y)));
        }
        let f: f64 = out.iter().map(|(_, v)| luminance(*v).max(0.0) as f64).sum();
        if f.is_finite() && f > 0.0 {
            f
        } else {
            out.clear();
            0.0
        }
    }
    // ANCHOR_END: evaluate

    fn storage(&mut self) -> Scratch {
        std::mem::take(&mut self.walks)
    }
}
