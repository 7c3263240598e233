//! Images in memory and on disk: OpenEXR (linear, with the render's metadata as attributes) and
//! PNG previews (exposure 0, sRGB transfer, clamped).

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

/// Failure to read or write an image.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {message}")]
    Io { path: String, message: String },
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> ImageError {
    ImageError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Writes a linear RGB float EXR with `meta` as string attributes.
pub fn write_exr(path: &Path, image: &Image, meta: &ImageMeta) -> Result<(), ImageError> {
    use exr::prelude::*;
    let w = image.width as usize;
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = image.pixels[pos.y() * w + pos.x()];
        (p.x, p.y, p.z)
    });
    let mut layer_attributes = LayerAttributes::named("pathspace");
    for (k, v) in &meta.attributes {
        layer_attributes.other.insert(
            Text::from(k.as_str()),
            AttributeValue::Text(Text::from(v.as_str())),
        );
    }
    let layer = Layer::new(
        (image.width as usize, image.height as usize),
        layer_attributes,
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    exr::image::Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| io_err(path, e))
}

/// Reads an RGB(A) EXR written by pathspace or any other renderer, with its text attributes.
pub fn read_exr(path: &Path) -> Result<(Image, ImageMeta), ImageError> {
    use exr::prelude::*;
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| {
                super::image_io::Image::new(resolution.width() as u32, resolution.height() as u32)
            },
            |image: &mut super::image_io::Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = image.width as usize;
                image.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| io_err(path, e))?;
    let mut meta = ImageMeta::default();
    for (k, v) in &img.layer_data.attributes.other {
        if let AttributeValue::Text(t) = v {
            meta.attributes.insert(k.to_string(), t.to_string());
        }
    }
    Ok((img.layer_data.channel_data.pixels, meta))
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

/// Writes raw 8-bit RGB data as a PNG.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, data: &[u8]) -> Result<(), ImageError> {
    let file = std::fs::File::create(path).map_err(|e| io_err(path, e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(|e| io_err(path, e))?;
    writer.write_image_data(data).map_err(|e| io_err(path, e))
}
