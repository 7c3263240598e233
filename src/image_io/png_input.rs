//! The PNG reader for textures, as Mitsuba 3 reads these files (`Bitmap::read_png` over libpng):
//! palettes expanded to RGB, transparency to alpha, 1-, 2- and 4-bit grey to 8 bits; alpha is
//! dropped and grey copied to the three channels. Only 8-bit images are read (Mitsuba stores a
//! 16-bit one in half floats, a rounding this reader does not copy). Values are the bytes over
//! 255, still sRGB-encoded (Mitsuba takes every PNG as sRGB; the texture decodes them unless
//! `raw`). The header's size is checked against the limits before any pixel is decoded, and
//! every defect is an error naming the file, never a panic. Tests: `tests/spec/texture.rs`,
//! fuzzed by `scripts/fuzz.py`.

use std::path::Path;

use super::{io_err, Image, ImageError};
use crate::spectrum::Rgb;

/// Reads the 8-bit PNG at `path` of at most `max_bytes` bytes and `max_pixels` pixels, with the
/// FNV-1a hash of its bytes (a render's identity).
pub fn read_png8_input_hashed(
    path: &Path,
    max_bytes: u64,
    max_pixels: usize,
) -> Result<(Image, u64), ImageError> {
    let bytes = crate::conventions::read_at_most(path, max_bytes).map_err(|e| io_err(path, e))?;
    let image = decode_png8(&bytes, max_pixels).map_err(|e| io_err(path, e))?;
    Ok((image, crate::conventions::fnv1a(&bytes)))
}

/// [`read_png8_input_hashed`]'s decoding of the bytes of a file.
pub fn decode_png8(bytes: &[u8], max_pixels: usize) -> Result<Image, String> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let (w, h) = (reader.info().width, reader.info().height);
    if (w as usize)
        .checked_mul(h as usize)
        .is_none_or(|n| n > max_pixels || n == 0)
    {
        return Err(format!(
            "the image has {w} x {h} pixels; at least 1 and at most {max_pixels} are read"
        ));
    }
    let mut buf = vec![0u8; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    if frame.bit_depth != png::BitDepth::Eight {
        return Err(format!(
            "a {:?}-bit PNG: only 8-bit PNGs are read (Mitsuba rounds 16-bit ones to half floats)",
            frame.bit_depth as u8
        ));
    }
    let channels = match frame.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err("an indexed PNG was not expanded".into()),
    };
    let (w, h) = (frame.width as usize, frame.height as usize);
    let line = frame.line_size;
    if line < w * channels || buf.len() < line * h {
        return Err("the decoded image is shorter than its header says".into());
    }
    let mut pixels = Vec::with_capacity(w * h);
    for y in 0..h {
        let row = &buf[y * line..y * line + w * channels];
        for px in row.chunks_exact(channels) {
            let v = |i: usize| px[i] as f32 / 255.0;
            pixels.push(if channels < 3 {
                Rgb::splat(v(0))
            } else {
                Rgb::new(v(0), v(1), v(2))
            });
        }
    }
    Ok(Image {
        width: w as u32,
        height: h as u32,
        pixels,
    })
}
