//! Images in memory and on disk: OpenEXR (linear, with the render's metadata as attributes) and
//! PNG previews (exposure 0, sRGB transfer, clamped).

pub mod png_input;
pub mod rgbe;

use std::collections::BTreeMap;
use std::path::Path;

use crate::spectrum::Rgb;

/// A linear RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image {
            width,
            height,
            pixels: vec![Rgb::ZERO; (width * height) as usize],
        }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Rgb {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean over pixels, per channel.
    pub fn mean(&self) -> Rgb {
        let mut s = [0.0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
        }
        let n = self.pixels.len().max(1) as f64;
        Rgb::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }
}

/// What a render records about itself in its EXR file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImageMeta {
    /// Free-form key/value attributes (integrator, spp, seed, seconds, scene_hash, ...).
    pub attributes: BTreeMap<String, String>,
}

impl ImageMeta {
    pub fn set(&mut self, key: &str, value: impl ToString) -> &mut Self {
        self.attributes.insert(key.to_string(), value.to_string());
        self
    }

    pub fn get(&self, key: &str) -> Option<&str> {
        self.attributes.get(key).map(String::as_str)
    }
}

/// How pathspace stores a numeric attribute in an EXR header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Numeric {
    /// OpenEXR's `int` (32-bit).
    Int,
    /// OpenEXR's `double`.
    Double,
}

/// The attributes pathspace writes as numbers, so that a tool reading the header (OpenEXR's
/// `exrheader`, Python's `OpenEXR`) gets counts and times as numbers; every other attribute is a
/// string. A value that does not fit its type (a count beyond `i32`) stays a string, and `seed`
/// is a string because a merged image lists its runs' seeds.
pub const NUMERIC_ATTRIBUTES: [(&str, Numeric); 7] = [
    ("spp", Numeric::Int),
    ("spp_target", Numeric::Int),
    ("nan_count", Numeric::Int),
    ("negative_pixels", Numeric::Int),
    ("seconds", Numeric::Double),
    ("guide_seconds", Numeric::Double),
    ("estimated_relmse", Numeric::Double),
];

/// The header value of attribute `key` with text `value`.
fn attribute_value(key: &str, value: &str) -> exr::meta::attribute::AttributeValue {
    use exr::meta::attribute::{AttributeValue, Text};
    let kind = NUMERIC_ATTRIBUTES.iter().find(|(k, _)| *k == key);
    match kind.map(|(_, t)| t) {
        Some(Numeric::Int) => value.parse().ok().map(AttributeValue::I32),
        Some(Numeric::Double) => value
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(AttributeValue::F64),
        None => None,
    }
    .unwrap_or_else(|| AttributeValue::Text(Text::from(value)))
}

/// The text of a header value that pathspace reads: strings and numbers (other renderers may
/// store a number as `float`).
fn attribute_text(v: &exr::meta::attribute::AttributeValue) -> Option<String> {
    use exr::meta::attribute::AttributeValue;
    match v {
        AttributeValue::Text(t) => Some(t.to_string()),
        AttributeValue::I32(i) => Some(i.to_string()),
        AttributeValue::F32(f) => Some(f.to_string()),
        AttributeValue::F64(f) => Some(f.to_string()),
        _ => None,
    }
}

/// Failure to read or write an image.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {message}")]
    Io { path: String, message: String },
}

/// The error of an image file at `path` (also used by the files written beside images).
pub fn io_err(path: &Path, e: impl std::fmt::Display) -> ImageError {
    ImageError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Writes a linear RGB float EXR with `meta` as attributes ([`NUMERIC_ATTRIBUTES`] as numbers,
/// the others as strings).
pub fn write_exr(path: &Path, image: &Image, meta: &ImageMeta) -> Result<(), ImageError> {
    write_exr_channels(path, image, &[], meta)
}

/// A channel of an EXR beside R, G and B (a feature or variance layer of `--aovs`): its
/// name (`Albedo.R`, `Z`) and one value per pixel, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub name: String,
    pub values: Vec<f32>,
}

/// [`write_exr`] with `extra` channels in the same layer (all 32-bit floats, in the order of
/// their names, as OpenEXR stores channels). Without extra channels the file is exactly
/// [`write_exr`]'s RGB file.
pub fn write_exr_channels(
    path: &Path,
    image: &Image,
    extra: &[Channel],
    meta: &ImageMeta,
) -> Result<(), ImageError> {
    use exr::prelude::*;
    let (w, h) = (image.width as usize, image.height as usize);
    let mut layer_attributes = LayerAttributes::named("pathspace");
    let mut texts = BTreeMap::new();
    for (k, v) in meta.attributes.iter().filter(|(k, _)| !is_checksum(k)) {
        let value = attribute_value(k, v);
        // the record as a reader will see it (a number read back prints as it was parsed)
        texts.insert(k.clone(), attribute_text(&value).unwrap_or_default());
        layer_attributes.other.insert(Text::from(k.as_str()), value);
    }
    let mut sums = vec![(CHECKSUM, rgb_checksum(&texts, image))];
    if !extra.is_empty() {
        sums.push((CHECKSUM_LAYERS, layers_checksum(extra)));
    }
    for (k, v) in sums {
        layer_attributes
            .other
            .insert(Text::from(k), AttributeValue::Text(Text::from(v.as_str())));
    }
    let mut bytes = Vec::new();
    let sink = std::io::Cursor::new(&mut bytes);
    let written = if extra.is_empty() {
        let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
            let p = image.pixels[pos.y() * w + pos.x()];
            (p.x, p.y, p.z)
        });
        let layer = Layer::new((w, h), layer_attributes, Encoding::SMALL_LOSSLESS, channels);
        exr::image::Image::from_layer(layer)
            .write()
            .to_buffered(sink)
    } else {
        let rgb = ["R", "G", "B"].iter().enumerate().map(|(c, name)| {
            let values = image.pixels.iter().map(|p| p[c]).collect();
            AnyChannel::new(*name, FlatSamples::F32(values))
        });
        let others = extra.iter().map(|ch| {
            if ch.values.len() != w * h {
                return Err(io_err(
                    path,
                    format!(
                        "channel {} has {} values for {w} x {h} pixels",
                        ch.name,
                        ch.values.len()
                    ),
                ));
            }
            Ok(AnyChannel::new(
                ch.name.as_str(),
                FlatSamples::F32(ch.values.clone()),
            ))
        });
        let list: Vec<_> = rgb
            .map(Ok)
            .chain(others)
            .collect::<std::result::Result<_, ImageError>>()?;
        let channels = AnyChannels::sort(SmallVec::from_vec(list));
        let layer = Layer::new((w, h), layer_attributes, Encoding::SMALL_LOSSLESS, channels);
        exr::image::Image::from_layer(layer)
            .write()
            .to_buffered(sink)
    };
    written.map_err(|e| io_err(path, e))?;
    sort_header(&mut bytes).ok_or_else(|| io_err(path, "the EXR header could not be ordered"))?;
    write_replacing(path, |tmp| {
        std::fs::write(tmp, &bytes).map_err(|e| io_err(path, e))
    })
}

/// The attribute holding the FNV-1a hash of an image's record (its other attributes, as text)
/// and its RGB pixels, written with every EXR and checked by every read: a byte of the file
/// changed since (a damaged disk or copy) is found even where it gives a finite, plausible value.
pub const CHECKSUM: &str = "checksum";

/// The attribute holding the FNV-1a hash of the layers beside R, G and B (`--aovs`).
pub const CHECKSUM_LAYERS: &str = "checksum_layers";

fn is_checksum(key: &str) -> bool {
    key == CHECKSUM || key == CHECKSUM_LAYERS
}

/// [`CHECKSUM`]'s value: every attribute but the checksums (key and text, in key order), then
/// the pixels' R, G, B as little-endian `f32`, row by row.
fn rgb_checksum(texts: &BTreeMap<String, String>, image: &Image) -> String {
    use crate::conventions::{fnv1a_continue, FNV1A_START};
    let mut h = FNV1A_START;
    for (k, v) in texts.iter().filter(|(k, _)| !is_checksum(k)) {
        for part in [k.as_bytes(), &[0], v.as_bytes(), &[0]] {
            h = fnv1a_continue(h, part);
        }
    }
    for p in &image.pixels {
        for c in 0..3 {
            h = fnv1a_continue(h, &p[c].to_le_bytes());
        }
    }
    format!("{h:016x}")
}

/// [`CHECKSUM_LAYERS`]'s value: each layer's name and values, in the order of the names.
fn layers_checksum(channels: &[Channel]) -> String {
    use crate::conventions::{fnv1a_continue, FNV1A_START};
    let mut sorted: Vec<&Channel> = channels.iter().collect();
    sorted.sort_by(|a, b| a.name.cmp(&b.name));
    let mut h = FNV1A_START;
    for ch in sorted {
        h = fnv1a_continue(fnv1a_continue(h, ch.name.as_bytes()), &[0]);
        for v in &ch.values {
            h = fnv1a_continue(h, &v.to_le_bytes());
        }
    }
    format!("{h:016x}")
}

/// Checks a checksum attribute against what was read: a file without it (written by another
/// program, or by an older pathspace) passes.
fn verify(path: &Path, key: &str, recorded: Option<&str>, found: &str) -> Result<(), ImageError> {
    match recorded {
        Some(r) if r != found => Err(io_err(
            path,
            format!(
                "the file is damaged: its {} do not match the `{key}` written with them \
                 (if it was changed on purpose, remove that attribute)",
                if key == CHECKSUM {
                    "pixels or record"
                } else {
                    "layers"
                }
            ),
        )),
        _ => Ok(()),
    }
}

/// The channels of an EXR's first valid layer other than R, G, B and A (the layers
/// [`write_exr_channels`] adds), in the order of their names, as 32-bit floats; checked
/// against [`CHECKSUM_LAYERS`] where the file has it.
pub fn read_exr_channels(path: &Path) -> Result<Vec<Channel>, ImageError> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| io_err(path, e))?;
    let channels: Vec<Channel> = img
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|ch| Channel {
            name: ch.name.to_string(),
            values: ch.sample_data.values_as_f32().collect(),
        })
        .filter(|ch| !matches!(ch.name.as_str(), "R" | "G" | "B" | "A"))
        .collect();
    let recorded = img
        .layer_data
        .attributes
        .other
        .get(&Text::from(CHECKSUM_LAYERS))
        .and_then(attribute_text);
    verify(
        path,
        CHECKSUM_LAYERS,
        recorded.as_deref(),
        &layers_checksum(&channels),
    )?;
    Ok(channels)
}

/// Puts the header attributes of a single-part EXR in the order of their names, as OpenEXR's
/// own library writes them, because the exr crate writes its custom attributes in the order of
/// a `HashMap`, which changes from run to run, and the same render must give the same bytes.
/// The header keeps its length, so the chunk offsets after it stay right.
// ANCHOR: sort_header
pub fn sort_header(bytes: &mut [u8]) -> Option<()> {
    const MULTIPART: u32 = 0x1000;
    let version = u32::from_le_bytes(bytes.get(4..8)?.try_into().ok()?);
    if version & MULTIPART != 0 {
        return None;
    }
    let nul = |from: usize| Some(from + bytes.get(from..)?.iter().position(|&b| b == 0)?);
    let (start, mut at) = (8, 8);
    // (start, end of the name, end) of each attribute: name\0 type\0 size (i32) value
    let mut attributes = Vec::new();
    loop {
        let name_end = nul(at)?;
        if name_end == at {
            break; // the empty name ends the header
        }
        let type_end = nul(name_end + 1)?;
        let size = i32::from_le_bytes(bytes.get(type_end + 1..type_end + 5)?.try_into().ok()?);
        let end = type_end + 5 + usize::try_from(size).ok()?;
        if end > bytes.len() {
            return None;
        }
        attributes.push((at, name_end, end));
        at = end;
    }
    attributes.sort_by(|a, b| bytes[a.0..a.1].cmp(&bytes[b.0..b.1]));
    let sorted: Vec<u8> = attributes
        .iter()
        .flat_map(|&(s, _, e)| bytes[s..e].iter().copied())
        .collect();
    bytes[start..at].copy_from_slice(&sorted);
    Some(())
}
// ANCHOR_END: sort_header

/// Writes `path` through `write` into a temporary file beside it, renamed over `path` only once
/// it is complete, so that a failed write leaves an earlier file at `path` as it was. A target
/// that exists and is no regular file (a device such as `/dev/null`) is written in place.
pub fn write_replacing(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), ImageError>,
) -> Result<(), ImageError> {
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return write(path);
    }
    let name = path
        .file_name()
        .ok_or_else(|| io_err(path, "is not a file name"))?;
    // unique per process and per write: two renders given the same -o never share a
    // temporary file (the last rename wins, and each file is whole)
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = path.with_file_name(format!(
        ".{}.{}-{n}.partial",
        name.to_string_lossy(),
        std::process::id()
    ));
    let written =
        write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| io_err(path, e)));
    if written.is_err() {
        // the write's own error is the one to report; a temporary file that cannot be removed
        // (or was never created) changes nothing at `path`
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// Reads an RGB(A) EXR written by pathspace or any other renderer, with its string and number
/// attributes as text; a file whose [`CHECKSUM`] does not match is refused as damaged (and the
/// checksums are not among the attributes returned).
pub fn read_exr(path: &Path) -> Result<(Image, ImageMeta), ImageError> {
    let file = std::fs::File::open(path).map_err(|e| io_err(path, e))?;
    let (pixels, attributes) = decode_rgb(path, std::io::BufReader::new(file))?;
    let mut meta = ImageMeta::default();
    for (k, v) in &attributes {
        if let Some(t) = attribute_text(v) {
            meta.attributes.insert(k.to_string(), t);
        }
    }
    let found = rgb_checksum(&meta.attributes, &pixels);
    verify(path, CHECKSUM, meta.get(CHECKSUM), &found)?;
    // checked, they have said what they had to: the record is what the render wrote
    meta.attributes.retain(|k, _| !is_checksum(k));
    Ok((pixels, meta))
}

/// Reads the RGB channels of an EXR input image (an environment map) of at most `max_bytes`
/// bytes and `max_pixels` pixels: the sizes in the header are checked before any pixel is
/// decoded, so a small file declaring a huge image is refused, not allocated.
/// With the image, the FNV-1a hash of the bytes it decoded (a render's identity).
pub fn read_exr_input_hashed(
    path: &Path,
    max_bytes: u64,
    max_pixels: usize,
) -> Result<(Image, u64), ImageError> {
    let bytes = crate::conventions::read_at_most(path, max_bytes).map_err(|e| io_err(path, e))?;
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
        .map_err(|e| io_err(path, e))?;
    for h in &meta.headers {
        let (w, hgt) = (h.layer_size.width(), h.layer_size.height());
        if w.checked_mul(hgt).is_none_or(|n| n > max_pixels) {
            return Err(io_err(
                path,
                format!("the image has {w} x {hgt} pixels, more than the limit of {max_pixels}"),
            ));
        }
    }
    let hash = crate::conventions::fnv1a(&bytes);
    Ok((decode_rgb(path, std::io::Cursor::new(bytes))?.0, hash))
}

/// A layer's attributes other than the standard ones, as the exr crate keeps them.
type ExrAttributes =
    std::collections::HashMap<exr::meta::attribute::Text, exr::meta::attribute::AttributeValue>;

/// The RGB pixels of the first valid layer of an EXR (alpha dropped) and the layer's other
/// attributes; errors name `path`.
fn decode_rgb(
    path: &Path,
    source: impl std::io::Read + std::io::Seek + Send,
) -> Result<(Image, ExrAttributes), ImageError> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| {
                crate::image_io::Image::new(resolution.width() as u32, resolution.height() as u32)
            },
            |image: &mut crate::image_io::Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = image.width as usize;
                image.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(source)
        .map_err(|e| io_err(path, e))?;
    Ok((
        img.layer_data.channel_data.pixels,
        img.layer_data.attributes.other,
    ))
}

/// The sRGB transfer function of a linear value, clamped to [0, 1].
#[inline]
pub fn srgb_encode(v: f32) -> f32 {
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes an 8-bit sRGB PNG preview (exposure 0, clamped).
pub fn write_png(path: &Path, image: &Image) -> Result<(), ImageError> {
    let data: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.to_array().map(|c| (srgb_encode(c) * 255.0 + 0.5) as u8))
        .collect();
    write_png_rgb8(path, image.width, image.height, &data)
}

/// Writes raw 8-bit RGB data as a PNG. The file is encoded in memory and written at once, so
/// that every error of the write (a full disk included) is reported.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, data: &[u8]) -> Result<(), ImageError> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(|e| io_err(path, e))?;
        writer.write_image_data(data).map_err(|e| io_err(path, e))?;
        writer.finish().map_err(|e| io_err(path, e))?;
    }
    write_file_replacing(path, &bytes)
}

/// Checks, before any work, that an image can be written at `path`: its directory exists and
/// its name ends in `extension` (the format written). What only the write can tell (a full
/// disk) is still reported by the write.
pub fn check_output(path: &Path, extension: &str) -> Result<(), ImageError> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if !ext.eq_ignore_ascii_case(extension) && std::fs::metadata(path).map_or(true, |m| m.is_file())
    {
        let m = format!(
            "is written as {}: name it *.{extension}",
            extension.to_uppercase()
        );
        return Err(io_err(path, m));
    }
    check_output_file(path)
}

/// Checks, before any work, that a file of any kind can be written at `path`: its directory
/// exists and can be written (a probe file: a read-only file system is found here), and `path`
/// is no directory and no device but `/dev/null`. [`check_output`] adds the extension rule of
/// images; the other outputs (scene files, CSV, charts, heatmaps) are checked here.
pub fn check_output_file(path: &Path) -> Result<(), ImageError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(io_err(
            path,
            format!("directory {} does not exist", dir.display()),
        ));
    }
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => return Err(io_err(path, "is a directory")),
        Ok(m) if !m.is_file() && path != Path::new("/dev/null") => {
            return Err(io_err(
                path,
                "is no regular file (a device such as /dev/full cannot hold an output; \
                 /dev/null discards it)",
            ))
        }
        _ => {}
    }
    probe_writable(dir).map_err(|e| io_err(path, format!("cannot write in {}: {e}", dir.display())))
}

/// Checks, before any work, that files can be written into the directory `dir`, creating it
/// (and its parents) when missing: a file of that name, or a directory that cannot be written,
/// is refused. The files the command writes there are checked by [`check_output_file`].
pub fn check_output_dir(dir: &Path) -> Result<(), ImageError> {
    if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
        return Err(io_err(dir, "is not a directory"));
    }
    std::fs::create_dir_all(dir).map_err(|e| io_err(dir, format!("cannot create it: {e}")))?;
    probe_writable(dir).map_err(|e| io_err(dir, format!("cannot write in it: {e}")))
}

/// Writes `bytes` to `path` through [`write_replacing`]: a failed write (a full disk) leaves an
/// earlier file at `path` as it was.
pub fn write_file_replacing(path: &Path, bytes: &[u8]) -> Result<(), ImageError> {
    write_replacing(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|e| io_err(path, e))
    })
}

/// Creates and removes a file in `dir`: a read-only file system or a directory without write
/// permission is found before the work, not when the image is written.
fn probe_writable(dir: &Path) -> std::io::Result<()> {
    static PROBES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = PROBES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let probe = dir.join(format!(".pathspace-probe-{}-{n}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    std::fs::remove_file(&probe)
}
