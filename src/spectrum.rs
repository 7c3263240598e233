//! RGB radiometric quantities.
//!
//! The papers work per wavelength; pathspace carries three channels (linear sRGB primaries) in a
//! `glam::Vec3`, the simplest representation that shows chromatic media (a per-channel `sigma_t`).
//! Book: "Conventions of the code".

pub mod cie;

use glam::Vec3;

/// A per-channel radiometric quantity (radiance, throughput, sigma, albedo).
pub type Rgb = Vec3;

/// A colour or coefficient for a reader, to three decimals: `[0.725, 0.725, 0.725]`, or `0.5`
/// when all three components are equal.
pub fn show(v: Rgb) -> String {
    if v.x == v.y && v.y == v.z {
        format!("{}", round3(v.x))
    } else {
        format!("[{}, {}, {}]", round3(v.x), round3(v.y), round3(v.z))
    }
}

/// `x` rounded to three decimals (for a reader).
pub fn round3(x: f32) -> f32 {
    (x * 1000.0).round() / 1000.0
}

/// Rec. 709 luminance weights, used wherever a scalar must stand for a colour (Russian roulette,
/// MLT's scalar image contribution, SMC's channel average is the plain mean instead).
pub const LUMINANCE: Rgb = Vec3::new(0.2126, 0.7152, 0.0722);

/// Luminance of a linear RGB value.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    c.dot(LUMINANCE)
}

/// Mean of the three channels (the pdf of a channel picked uniformly, averaged).
#[inline]
pub fn average(c: Rgb) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

/// True when every channel is finite.
#[inline]
pub fn is_finite(c: Rgb) -> bool {
    c.is_finite()
}

/// True when every channel is exactly zero.
#[inline]
pub fn is_black(c: Rgb) -> bool {
    c == Vec3::ZERO
}

/// Channel `i` (0, 1, 2) of `c`.
#[inline]
pub fn channel(c: Rgb, i: usize) -> f32 {
    c[i]
}
