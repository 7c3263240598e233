//! `<spectrum>` properties: one value (uniform), `value="400:0.1, 500:0.5, ..."` wavelength:value
//! pairs, or `filename="x.spd"`, read as Mitsuba 3.9's `Properties::Spectrum`
//! (`src/core/properties.cpp`) reads them and reduced to RGB as its RGB variants do
//! (`spectrum::cie::spectrum_list_to_srgb`).

use glam::DVec3;
use std::path::Path;

use crate::spectrum::cie::{spectrum_list_to_srgb, uniform_emission, Response};

/// The longest `.spd` file read (Mitsuba's spectra have a few hundred lines).
pub const MAX_SPD_BYTES: u64 = 1 << 20;

/// A spectrum as written: one value, or pairs with increasing wavelengths (nm).
#[derive(Debug, PartialEq)]
pub enum Spectrum {
    Uniform(f64),
    Pairs(Vec<f64>, Vec<f64>),
}

impl Spectrum {
    /// The RGB colour Mitsuba's RGB variants give the property (`Properties::get_texture_impl`):
    /// a uniform value is that grey except on an emitter (`uniform_emission`); pairs go through
    /// `spectrum_list_to_srgb`. The flag says whether a list's colour was clamped.
    pub fn rgb(&self, response: Response) -> (DVec3, bool) {
        match self {
            Spectrum::Uniform(x) if response == Response::Emissive => (uniform_emission(*x), false),
            Spectrum::Uniform(x) => (DVec3::splat(*x), false),
            Spectrum::Pairs(w, v) => spectrum_list_to_srgb(w, v, response),
        }
    }
}

/// A number of a spectrum (finite, as every number the importer reads).
fn number(s: &str, what: &str) -> Result<f64, String> {
    let t = s.trim_matches([' ', '\t']);
    // one leading `+`, as Mitsuba's `parse_float` skips
    t.strip_prefix('+')
        .unwrap_or(t)
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| format!("the {what} `{s}` is not a finite number"))
}

/// The pairs checked as Mitsuba checks them (at least two, wavelengths increasing), and values
/// not negative (every spectrum the importer reads is a reflectance, an index, a coefficient or
/// an emission).
fn checked(w: Vec<f64>, v: Vec<f64>) -> Result<Spectrum, String> {
    if w.len() < 2 {
        return Err(format!(
            "{} wavelength:value pair{}: a spectrum needs at least two",
            w.len(),
            if w.len() == 1 { "" } else { "s" }
        ));
    }
    if let Some(k) = (1..w.len()).find(|&k| w[k] <= w[k - 1]) {
        return Err(format!(
            "the wavelengths must increase: {} nm follows {} nm",
            w[k],
            w[k - 1]
        ));
    }
    if let Some(k) = v.iter().position(|&x| x < 0.0) {
        return Err(format!("the value {} at {} nm is negative", v[k], w[k]));
    }
    Ok(Spectrum::Pairs(w, v))
}

/// `value="..."`: one number, or `wavelength:value` pairs separated by commas or spaces.
pub fn parse_value(text: &str) -> Result<Spectrum, String> {
    let tokens: Vec<&str> = text.split([',', ' ']).filter(|t| !t.is_empty()).collect();
    if let [t] = tokens.as_slice() {
        if !t.contains(':') {
            return number(t, "value").map(Spectrum::Uniform);
        }
    }
    let (mut w, mut v) = (Vec::new(), Vec::new());
    for t in tokens {
        let Some((a, b)) = t.split_once(':').filter(|(_, b)| !b.contains(':')) else {
            return Err(format!("`{t}` is not a wavelength:value pair"));
        };
        w.push(number(a, "wavelength")?);
        v.push(number(b, "value")?);
    }
    checked(w, v)
}

/// The text of a `.spd` file: a wavelength and a value per line, separated by spaces or tabs;
/// lines that are empty or start with `#` are skipped, and a `#` after the two numbers starts a
/// comment (Mitsuba ignores the rest of a line; anything but a comment there is refused here).
/// Errors name the line.
pub fn parse_spd(text: &str) -> Result<Spectrum, String> {
    let (mut w, mut v) = (Vec::new(), Vec::new());
    for (k, line) in text.split('\n').enumerate() {
        let line = line.strip_suffix('\r').unwrap_or(line);
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let data = line.split('#').next().unwrap_or("");
        let fields: Vec<&str> = data.split([' ', '\t']).filter(|f| !f.is_empty()).collect();
        let at = |m: String| format!("line {}: {m}", k + 1);
        match fields.as_slice() {
            [a, b] => {
                w.push(number(a, "wavelength").map_err(at)?);
                v.push(number(b, "value").map_err(at)?);
            }
            f => {
                return Err(at(format!(
                    "{} fields where a wavelength and a value are expected",
                    f.len()
                )))
            }
        }
    }
    checked(w, v)
}

/// Reads and parses the `.spd` file at `path` (at most [`MAX_SPD_BYTES`]).
pub fn read_spd(path: &Path) -> Result<Spectrum, String> {
    let bytes = crate::conventions::read_at_most(path, MAX_SPD_BYTES).map_err(|e| e.to_string())?;
    let text = std::str::from_utf8(&bytes).map_err(|_| "is not text (UTF-8)".to_string())?;
    parse_spd(text)
}
