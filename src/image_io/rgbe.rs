//! The Radiance RGBE (`.hdr`) reader for environment maps, as Mitsuba 3 reads these files
//! (`Bitmap::read_rgbe`, after Bruce Walter's `rgbe.c`): a text header starting with `#?`
//! (`#?RADIANCE`, `#?RGBE`), `FORMAT=32-bit_rle_rgbe`, an empty line, the resolution line
//! `-Y height +X width` (top row first, left to right; the other seven orientations are refused),
//! then the scanlines, each either run-length encoded per channel (the marker 2, 2, width) or flat
//! (4 bytes a pixel; a flat scanline makes the rest of the image flat, and widths outside
//! [8, 32767] are always flat). A pixel (r, g, b, e) is (r, g, b) 2^(e - 136), and 0 for e = 0;
//! `EXPOSURE` and the other header variables are ignored, as Mitsuba ignores them. Sizes are
//! checked against the limits before anything is allocated, and every defect is an error naming
//! the file, never a panic. Tests: `tests/spec/scene/envmap.rs`.

use std::path::Path;

use super::{io_err, Image, ImageError};
use crate::spectrum::Rgb;

/// The longest header read, in bytes (real headers hold a few lines).
pub const MAX_HEADER_BYTES: usize = 1 << 16;

/// True if the file at `path` is read as RGBE: its name ends in `.hdr`, `.pic` or `.rgbe`, or its
/// first bytes are `#?` (Mitsuba decides by these bytes; a file named `.hdr` that lacks them
/// then gets the RGBE reader's error rather than the EXR reader's).
pub fn is_rgbe(path: &Path) -> bool {
    let by_name = path.extension().is_some_and(|e| {
        let e = e.to_string_lossy().to_ascii_lowercase();
        matches!(e.as_str(), "hdr" | "pic" | "rgbe")
    });
    by_name || {
        use std::io::Read;
        let mut start = [0u8; 2];
        std::fs::File::open(path)
            .and_then(|mut f| f.read_exact(&mut start))
            .is_ok_and(|_| &start == b"#?")
    }
}

/// Reads the RGBE file at `path` (at most `max_bytes`, at most `max_pixels` pixels) with the
/// FNV-1a hash of its bytes.
pub fn read_rgbe_input_hashed(
    path: &Path,
    max_bytes: u64,
    max_pixels: usize,
) -> Result<(Image, u64), ImageError> {
    let bytes = crate::conventions::read_at_most(path, max_bytes).map_err(|e| io_err(path, e))?;
    let image = decode(&bytes, max_pixels).map_err(|e| io_err(path, e))?;
    Ok((image, crate::conventions::fnv1a(&bytes)))
}

/// Decodes the bytes of an RGBE file; the error says what is wrong and where.
pub fn decode(bytes: &[u8], max_pixels: usize) -> Result<Image, String> {
    let (width, height, start) = header(bytes, max_pixels)?;
    let mut pixels = Vec::with_capacity(width * height);
    let mut at = start;
    let flat = |at: usize, pixels: &mut Vec<Rgb>| -> Result<(), String> {
        let need = (width * height - pixels.len()) * 4;
        let data = bytes.get(at..at + need).ok_or_else(|| {
            format!(
                "the pixel data ends early: {} flat pixels need {need} bytes from byte {at}, \
                 the file has {}",
                need / 4,
                bytes.len()
            )
        })?;
        pixels.extend(data.chunks_exact(4).map(to_rgb));
        Ok(())
    };
    if !(8..=0x7fff).contains(&width) {
        flat(at, &mut pixels)?;
        return Ok(image(width, height, pixels));
    }
    let mut line = vec![0u8; 4 * width];
    for y in 0..height {
        let marker = bytes
            .get(at..at + 4)
            .ok_or_else(|| format!("the pixel data ends early (scanline {y} of {height})"))?;
        if marker[0] != 2 || marker[1] != 2 || marker[2] & 0x80 != 0 {
            flat(at, &mut pixels)?;
            return Ok(image(width, height, pixels));
        }
        let n = (marker[2] as usize) << 8 | marker[3] as usize;
        if n != width {
            return Err(format!(
                "scanline {y} is encoded {n} pixels wide, the image {width}"
            ));
        }
        at = scanline(bytes, at + 4, &mut line, y)?;
        let channel = |c: usize, x: usize| line[c * width + x];
        pixels.extend((0..width).map(|x| to_rgb(&[0, 1, 2, 3].map(|c| channel(c, x)))));
    }
    Ok(image(width, height, pixels))
}

fn image(width: usize, height: usize, pixels: Vec<Rgb>) -> Image {
    Image {
        width: width as u32,
        height: height as u32,
        pixels,
    }
}

/// (r, g, b) 2^(e - 136), as Mitsuba's `rgbe_to_float` (no half-step offset).
fn to_rgb(p: &[u8]) -> Rgb {
    if p[3] == 0 {
        return Rgb::ZERO;
    }
    // 2^(e - 136) exactly (in f32 a power of 2 down to 2^-149 is exact; f32's own powi would
    // form 2^136, beyond its range)
    let f = 2f64.powi(p[3] as i32 - 136) as f32;
    Rgb::new(p[0] as f32 * f, p[1] as f32 * f, p[2] as f32 * f)
}

/// Decodes one run-length encoded scanline (its four channels one after the other) from
/// `bytes[at..]` into `line`; returns where the next scanline starts.
fn scanline(bytes: &[u8], mut at: usize, line: &mut [u8], y: usize) -> Result<usize, String> {
    let width = line.len() / 4;
    let mut next = |n: usize| {
        let s = bytes
            .get(at..at + n)
            .ok_or_else(|| format!("the pixel data ends early (scanline {y})"));
        at += n;
        s
    };
    for c in 0..4 {
        let mut x = 0;
        while x < width {
            let code = next(1)?[0] as usize;
            let (count, run) = if code > 128 {
                (code - 128, true)
            } else {
                (code, false)
            };
            if count == 0 || count > width - x {
                return Err(format!(
                    "scanline {y}, channel {c}: a run of {count} at pixel {x} of {width}"
                ));
            }
            let dst = &mut line[c * width + x..c * width + x + count];
            if run {
                dst.fill(next(1)?[0]);
            } else {
                dst.copy_from_slice(next(count)?);
            }
            x += count;
        }
    }
    Ok(at)
}

/// Parses the header: returns the width, the height and where the pixels start.
fn header(bytes: &[u8], max_pixels: usize) -> Result<(usize, usize, usize), String> {
    let text = &bytes[..bytes.len().min(MAX_HEADER_BYTES)];
    let mut lines = text.split(|&b| b == b'\n');
    let mut at = 0;
    let mut take = |lines: &mut std::slice::Split<'_, u8, _>| {
        let line = lines.next()?;
        at += line.len() + 1;
        Some(
            String::from_utf8_lossy(line)
                .trim_end_matches('\r')
                .to_string(),
        )
    };
    let first = take(&mut lines).unwrap_or_default();
    if !first.starts_with("#?") {
        return Err(
            "not a Radiance RGBE file: it does not start with `#?` (as `#?RADIANCE`)".into(),
        );
    }
    let mut format = None;
    loop {
        let Some(line) = take(&mut lines) else {
            return Err(format!(
                "the header has no empty line ending it within its first {MAX_HEADER_BYTES} bytes"
            ));
        };
        if line.is_empty() {
            break;
        }
        if let Some(f) = line.strip_prefix("FORMAT=") {
            format = Some(f.trim().to_string());
        }
    }
    match format.as_deref() {
        Some("32-bit_rle_rgbe") => {}
        Some(f) => {
            return Err(format!(
                "FORMAT={f}: only 32-bit_rle_rgbe is read (not XYZE or others)"
            ))
        }
        None => return Err("the header has no FORMAT=32-bit_rle_rgbe line".into()),
    }
    let Some(size) = take(&mut lines) else {
        return Err("the resolution line is missing".into());
    };
    let words: Vec<&str> = size.split_whitespace().collect();
    let (height, width) = match words.as_slice() {
        ["-Y", h, "+X", w] => (dimension(h, &size)?, dimension(w, &size)?),
        _ => {
            return Err(format!(
                "the resolution line `{}` is not `-Y height +X width` (other orientations are \
                 not read)",
                size.escape_debug()
            ))
        }
    };
    if width.checked_mul(height).is_none_or(|n| n > max_pixels) {
        return Err(format!(
            "the image has {width} x {height} pixels, more than the limit of {max_pixels}"
        ));
    }
    if at > text.len() {
        return Err(format!(
            "the resolution line does not end with a newline within the first \
             {MAX_HEADER_BYTES} bytes"
        ));
    }
    Ok((width, height, at))
}

/// A side of the resolution line: a positive integer.
fn dimension(word: &str, line: &str) -> Result<usize, String> {
    match word.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!(
            "the resolution line `{}` has the side `{}`, not a positive integer",
            line.escape_debug(),
            word.escape_debug()
        )),
    }
}
