//! Textured reflectances (`albedo = { texture = "bitmap", file = "wood.png" }`): the texture
//! of a material key, its image read within limits, every texel a reflectance in [0, 1], or,
//! for a conductor's `eta` and `k`, any finite value >= 0 ([`Texels::Index`]).

use std::path::Path;

use glam::Vec3;

use super::values::{albedo, non_negative};
use crate::image_io::{png_input, read_exr_input_hashed, Image};
use crate::scene::file::{FilterTypeDesc, KeyPath, ReflectanceValue, TextureDesc, WrapModeDesc};
use crate::scene::{SceneError, SceneSource};
use crate::texture::{
    srgb_to_linear, Bitmap, Checkerboard, FilterType, Texture, UvTransform, WrapMode,
};

/// The largest texture file read, in bytes.
pub const MAX_TEXTURE_BYTES: u64 = 1 << 28;
/// The most texels a texture may have (an 8k x 8k image).
pub const MAX_TEXELS: usize = 1 << 26;

/// What a texture's values are, and so which values it may hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Texels {
    /// A reflectance: finite, in [0, 1].
    Reflectance,
    /// A conductor's `eta` or `k` (Mitsuba 3 documentation, plugin `conductor`): finite and
    /// >= 0, unbounded above (an EXR may carry eta = 2.5); never clamped. Named in messages.
    Index(&'static str),
    /// An emitted radiance (Mitsuba 3 documentation, plugin `area`): finite and >= 0,
    /// unbounded above, never clamped (Mitsuba's RGB variants read an emitter's bitmap as is).
    Emission,
}

/// A reflectance at `key`: its constant value, or the texture (whose mean stands in for the
/// constant where no point is known, as in `pathspace info`).
pub(super) fn reflectance(
    src: &SceneSource,
    key: &KeyPath,
    v: &ReflectanceValue,
) -> Result<(Vec3, Option<Texture>), SceneError> {
    colour(src, key, v, Texels::Reflectance)
}

/// A colour at `key` holding `texels`: its constant value, or the texture with its mean.
pub(super) fn colour(
    src: &SceneSource,
    key: &KeyPath,
    v: &ReflectanceValue,
    texels: Texels,
) -> Result<(Vec3, Option<Texture>), SceneError> {
    match v {
        ReflectanceValue::Value(c) => Ok((value(src, key, *c, texels)?, None)),
        ReflectanceValue::Texture(t) => {
            let t = texture_of(src, key, t, texels)?;
            Ok((mean(&t), Some(t)))
        }
    }
}

/// A constant colour holding `texels`, checked as such.
fn value(
    src: &SceneSource,
    key: &KeyPath,
    c: crate::scene::file::RgbValue,
    texels: Texels,
) -> Result<Vec3, SceneError> {
    match texels {
        Texels::Reflectance => albedo(src, key, c),
        Texels::Index(what) => non_negative(src, key, c, what),
        Texels::Emission => non_negative(src, key, c, "emission"),
    }
}

/// A texture's mean value over the unit square of (u, v) (of its texels; a checkerboard's
/// two colours cover it equally).
pub(super) fn mean(t: &Texture) -> Vec3 {
    match t {
        Texture::Bitmap(b) => b.texels().iter().sum::<Vec3>() / b.texels().len() as f32,
        Texture::Checkerboard(c) => 0.5 * (c.color0 + c.color1),
    }
}

/// The reflectance texture `t` at `key`.
pub(super) fn texture(
    src: &SceneSource,
    key: &KeyPath,
    t: &TextureDesc,
) -> Result<Texture, SceneError> {
    texture_of(src, key, t, Texels::Reflectance)
}

/// The texture `t` at `key`, its values checked as `texels`.
fn texture_of(
    src: &SceneSource,
    key: &KeyPath,
    t: &TextureDesc,
    texels: Texels,
) -> Result<Texture, SceneError> {
    match t {
        TextureDesc::Checkerboard {
            color0,
            color1,
            to_uv,
        } => Ok(Texture::Checkerboard(Checkerboard {
            color0: value(src, &key.clone().key("color0"), *color0, texels)?,
            color1: value(src, &key.clone().key("color1"), *color1, texels)?,
            to_uv: uv_transform(src, key, to_uv)?,
        })),
        TextureDesc::Bitmap {
            file,
            filter_type,
            wrap_mode,
            raw,
            to_uv,
        } => {
            let file_key = key.clone().key("file");
            let (image, srgb) = read_image(src, &file_key, file, *raw)?;
            let values: Vec<Vec3> = image
                .pixels
                .iter()
                .map(|c| if srgb { c.map(srgb_to_linear) } else { *c })
                .collect();
            let (max, what) = match texels {
                Texels::Reflectance => (1.0, "a reflectance must be finite and in [0, 1]"),
                Texels::Index(_) => (f32::INFINITY, "an index must be finite and >= 0"),
                Texels::Emission => (f32::INFINITY, "an emission must be finite and >= 0"),
            };
            if let Some(k) = values.iter().position(|c| {
                !c.to_array()
                    .iter()
                    .all(|x| x.is_finite() && (0.0..=max).contains(x))
            }) {
                let w = image.width as usize;
                return Err(src.error(
                    &file_key,
                    format!(
                        "{file}: texel ({}, {}) is {}: {what}",
                        k % w,
                        k / w,
                        values[k]
                    ),
                ));
            }
            let texels = values;
            let filter = match filter_type {
                FilterTypeDesc::Bilinear => FilterType::Bilinear,
                FilterTypeDesc::Nearest => FilterType::Nearest,
            };
            let wrap = match wrap_mode {
                WrapModeDesc::Repeat => WrapMode::Repeat,
                WrapModeDesc::Mirror => WrapMode::Mirror,
                WrapModeDesc::Clamp => WrapMode::Clamp,
            };
            let to_uv = uv_transform(src, key, to_uv)?;
            let (w, h) = (image.width as usize, image.height as usize);
            Bitmap::new(w, h, texels, filter, wrap, to_uv)
                .map(Texture::Bitmap)
                .ok_or_else(|| {
                    src.error(
                        &file_key,
                        format!(
                            "{file}: a {w} x {h} image; each side must be at least 2 (Mitsuba pads smaller ones)"
                        ),
                    )
                })
        }
    }
}

/// The image `file` (relative to the scene file): a PNG (8-bit, sRGB unless `raw`) or an EXR
/// (linear), by its first bytes; with whether it is to be sRGB-decoded.
fn read_image(
    src: &SceneSource,
    key: &KeyPath,
    file: &str,
    raw: bool,
) -> Result<(Image, bool), SceneError> {
    let path = src.base_dir.join(file);
    let (image, hash, srgb) = if is_png(&path) {
        png_input::read_png8_input_hashed(&path, MAX_TEXTURE_BYTES, MAX_TEXELS)
            .map(|(i, h)| (i, h, !raw))
    } else {
        read_exr_input_hashed(&path, MAX_TEXTURE_BYTES, MAX_TEXELS).map(|(i, h)| (i, h, false))
    }
    .map_err(|e| src.error(key, e.to_string()))?;
    src.record_input(file, hash);
    Ok((image, srgb))
}

/// True when the file starts with PNG's signature.
fn is_png(path: &Path) -> bool {
    use std::io::Read;
    let mut start = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut start))
        .is_ok_and(|_| start == *b"\x89PNG\r\n\x1a\n")
}

/// `to_uv` at `key`: finite rows, identity when absent.
fn uv_transform(
    src: &SceneSource,
    key: &KeyPath,
    rows: &Option<[[f32; 3]; 2]>,
) -> Result<UvTransform, SceneError> {
    match rows {
        None => Ok(UvTransform::default()),
        Some(r) if r.iter().flatten().all(|x| x.is_finite()) => Ok(UvTransform { rows: *r }),
        Some(r) => Err(src.error(&key.clone().key("to_uv"), format!("{r:?} is not finite"))),
    }
}
