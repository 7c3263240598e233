//! Textures: a reflectance that varies over a surface, looked up at the hit's (u, v) (Mitsuba 3
//! documentation, "Textures"). Two plugins, as Mitsuba 3 defines them: `bitmap` (an image with
//! bilinear or nearest lookup and a wrap mode) and `checkerboard` (two colours alternating on
//! the unit square). Both take an affine `to_uv` applied to (u, v) before the lookup.
//!
//! A texture only answers "which value at (u, v)"; where (u, v) comes from is the shape's
//! (`geometry::shape::Primitive::uv`, and `scene::UvMap` for the cube), and which parameter it
//! replaces is the material's (`scene::ShapeTexture`).
//! Book: "Scenes and geometry" (textures); spec: `tests/spec/texture.rs`.

pub mod bitmap;
pub mod checkerboard;

pub use bitmap::{srgb_to_linear, Bitmap, FilterType, WrapMode};
pub use checkerboard::Checkerboard;

use glam::Vec2;

use crate::spectrum::Rgb;

/// Mitsuba 3's `to_uv`: the affine map `uv' = [m0 m1] uv + m2` (the top two rows of its 3x3
/// matrix, columns here), identity by default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// Rows `[a, b, c]`, `[d, e, f]`: u' = a u + b v + c, v' = d u + e v + f.
    pub rows: [[f32; 3]; 2],
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform {
            rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        }
    }
}

impl UvTransform {
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let [a, d] = self.rows;
        Vec2::new(
            a[0] * uv.x + a[1] * uv.y + a[2],
            d[0] * uv.x + d[1] * uv.y + d[2],
        )
    }
}

/// Mitsuba 3's luminance weights of linear sRGB (`luminance` in its `spectrum.h`), not the
/// rounded Rec. 709 ones of [`crate::spectrum::LUMINANCE`]: a textured roughness must be
/// the value Mitsuba reads.
pub const MITSUBA_LUMINANCE: Rgb = glam::Vec3::new(0.212671, 0.715160, 0.072169);

/// The closed set of textures.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    Bitmap(Bitmap),
    Checkerboard(Checkerboard),
}

impl Texture {
    /// The value at surface coordinates `uv` (before `to_uv`).
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Rgb {
        match self {
            Texture::Bitmap(b) => b.eval(uv),
            Texture::Checkerboard(c) => c.eval(uv),
        }
    }

    /// The one-channel value at `uv`: the luminance of [`Texture::eval`] with Mitsuba 3's
    /// weights (`Texture::eval_1` of its RGB `bitmap`, `luminance` in
    /// `include/mitsuba/core/spectrum.h`), where a scalar parameter such as a roughness is
    /// textured; a checkerboard's with its two colours swapped, as Mitsuba's `eval_1`
    /// ([`Checkerboard::eval_1_colour`]).
    #[inline]
    pub fn eval_1(&self, uv: Vec2) -> f32 {
        match self {
            Texture::Bitmap(b) => b.eval(uv).dot(MITSUBA_LUMINANCE),
            Texture::Checkerboard(c) => c.eval_1_colour(uv).dot(MITSUBA_LUMINANCE),
        }
    }

    /// The least and largest one-channel value anywhere ([`Texture::eval_1`] is linear in the
    /// texels, so bilinear lookups stay between them).
    pub fn range_1(&self) -> (f32, f32) {
        let l = |c: Rgb| c.dot(MITSUBA_LUMINANCE);
        let values: Vec<f32> = match self {
            Texture::Bitmap(b) => b.texels().iter().map(|&t| l(t)).collect(),
            Texture::Checkerboard(c) => vec![l(c.color0), l(c.color1)],
        };
        values
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    }

    /// The least value of each channel anywhere (bilinear lookups stay above it), where a
    /// conductor's `eta` and `k` must not both reach 0.
    pub fn least(&self) -> Rgb {
        match self {
            Texture::Bitmap(b) => b.texels().iter().fold(Rgb::INFINITY, |m, &t| m.min(t)),
            Texture::Checkerboard(c) => c.color0.min(c.color1),
        }
    }

    /// The largest value of any channel anywhere (a reflectance must stay at most 1).
    pub fn max_value(&self) -> f32 {
        match self {
            Texture::Bitmap(b) => b
                .texels()
                .iter()
                .fold(0.0f32, |m, t| m.max(t.max_element())),
            Texture::Checkerboard(c) => c.color0.max_element().max(c.color1.max_element()),
        }
    }

    /// What `pathspace info` says of it.
    pub fn describe(&self) -> String {
        match self {
            Texture::Bitmap(b) => format!("bitmap {} x {}", b.width(), b.height()),
            Texture::Checkerboard(c) => format!(
                "checkerboard {} / {}",
                crate::spectrum::show(c.color0),
                crate::spectrum::show(c.color1)
            ),
        }
    }
}
