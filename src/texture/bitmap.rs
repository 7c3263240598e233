//! Mitsuba 3's `bitmap` texture (Mitsuba 3 documentation and `src/textures/bitmap.cpp`, plugin
//! `bitmap`, over Dr.Jit's `Texture`): texel (i, j) has its centre at uv = ((i + 1/2) / w,
//! (j + 1/2) / h), row j = 0 is the image's first (top) row at v = 0. `bilinear` (the default)
//! blends the four texels around `uv * size - 1/2`, `nearest` takes the texel `floor(uv *
//! size)`; texel indices outside the image are wrapped by `repeat` (the default), `mirror` or
//! `clamp` before the fetch. 8-bit sRGB texels are decoded to linear per texel before they are
//! blended (Dr.Jit's `srgb` flag), as here, where the texels are stored decoded.

use glam::{IVec2, Vec2};

use super::UvTransform;
use crate::spectrum::Rgb;

/// Mitsuba 3's `filter_type`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FilterType {
    #[default]
    Bilinear,
    Nearest,
}

/// Mitsuba 3's `wrap_mode` (Dr.Jit's `WrapMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WrapMode {
    #[default]
    Repeat,
    /// The image reflected at each edge, edge texels repeated: ..., 1, 0 | 0, 1, ...
    Mirror,
    /// The edge texels extended.
    Clamp,
}

impl WrapMode {
    /// The texel index in [0, n) that index `i` reads (Dr.Jit's `Texture::wrap`).
    #[inline]
    pub fn wrap(self, i: i32, n: i32) -> i32 {
        match self {
            WrapMode::Clamp => i.clamp(0, n - 1),
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::Mirror => {
                let period = i.div_euclid(n);
                let m = i.rem_euclid(n);
                if period % 2 == 0 {
                    m
                } else {
                    n - 1 - m
                }
            }
        }
    }
}

/// The sRGB decoding of an encoded value in [0, 1] (IEC 61966-2-1), as Mitsuba applies to 8-bit
/// images unless `raw`.
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// An image of linear texels, row 0 first, at least 2 x 2 (Mitsuba pads smaller images).
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    width: usize,
    height: usize,
    texels: Vec<Rgb>,
    pub filter: FilterType,
    pub wrap: WrapMode,
    pub to_uv: UvTransform,
}

impl Bitmap {
    /// A bitmap of `width * height` linear texels, row by row from the top; `None` unless both
    /// sides are at least 2 and the count matches.
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        filter: FilterType,
        wrap: WrapMode,
        to_uv: UvTransform,
    ) -> Option<Self> {
        (width >= 2 && height >= 2 && width.checked_mul(height) == Some(texels.len())).then_some(
            Bitmap {
                width,
                height,
                texels,
                filter,
                wrap,
                to_uv,
            },
        )
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn texels(&self) -> &[Rgb] {
        &self.texels
    }

    /// The texel at index `i` (any integers: wrapped first).
    #[inline]
    fn fetch(&self, i: IVec2) -> Rgb {
        let x = self.wrap.wrap(i.x, self.width as i32) as usize;
        let y = self.wrap.wrap(i.y, self.height as i32) as usize;
        self.texels[y * self.width + x]
    }

    /// The value at `uv` (before `to_uv`).
    pub fn eval(&self, uv: Vec2) -> Rgb {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let p = self.to_uv.apply(uv) * size;
        if !p.is_finite() {
            return Rgb::ZERO;
        }
        // far outside the image the texel index would overflow i32; the wrap makes every
        // period alike, and no real uv goes there
        let p = p.clamp(Vec2::splat(-1.0e8), Vec2::splat(1.0e8));
        match self.filter {
            FilterType::Nearest => self.fetch(p.floor().as_ivec2()),
            FilterType::Bilinear => {
                let p = p - 0.5;
                let i = p.floor();
                let (w1, i) = (p - i, i.as_ivec2());
                let w0 = Vec2::ONE - w1;
                let c0 = self.fetch(i) * w0.x + self.fetch(i + IVec2::X) * w1.x;
                let c1 = self.fetch(i + IVec2::Y) * w0.x + self.fetch(i + IVec2::ONE) * w1.x;
                c0 * w0.y + c1 * w1.y
            }
        }
    }
}
