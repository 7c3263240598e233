//! Mitsuba 3's `checkerboard` texture (Mitsuba 3 documentation, plugin `checkerboard`):
//! `color0` where the fractional parts of u and v are both above 1/2 or both at most 1/2,
//! `color1` elsewhere; defaults 0.4 and 0.2.

use glam::Vec2;

use super::UvTransform;
use crate::spectrum::Rgb;

/// Mitsuba 3's default `color0`.
pub const COLOR0: f32 = 0.4;
/// Mitsuba 3's default `color1`.
pub const COLOR1: f32 = 0.2;

#[derive(Clone, Debug, PartialEq)]
pub struct Checkerboard {
    pub color0: Rgb,
    pub color1: Rgb,
    pub to_uv: UvTransform,
}

impl Checkerboard {
    /// Mitsuba's test: `uv - floor(uv) > 0.5` per axis, `color0` when the two agree.
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Rgb {
        let uv = self.to_uv.apply(uv);
        let high = |x: f32| x - x.floor() > 0.5;
        if high(uv.x) == high(uv.y) {
            self.color0
        } else {
            self.color1
        }
    }

    /// The one-channel lookup as Mitsuba 3 (3.9) makes it: its `eval_1` takes `color1` where
    /// `eval` takes `color0` and back (recorded by `scripts/make_texture_fixtures.py`), so a
    /// textured roughness reads the swapped pattern in both renderers.
    #[inline]
    pub fn eval_1_colour(&self, uv: Vec2) -> Rgb {
        let c = self.eval(uv);
        if c == self.color0 {
            self.color1
        } else {
            self.color0
        }
    }
}
