//! A list of (wavelength, value) pairs reduced to linear sRGB as Mitsuba 3's RGB variants
//! (`scalar_rgb`, `llvm_ad_rgb`) reduce a `<spectrum>` property: `spectrum_list_to_srgb` of
//! Mitsuba 3.9's `src/core/spectrum.cpp`, with the CIE 1931 2-degree standard observer and the
//! CIE D65 illuminant as Mitsuba tabulates them. Book: "Importing scenes".
//!
//! The tables are copied digit for digit from Mitsuba 3.9.1: the colour matching functions from
//! `cie1931_tbl` in `src/core/spectrum.cpp` (CIE 1931 2-degree observer, 5 nm steps over
//! [360, 830] nm), D65 from `d65_table` in `include/mitsuba/core/spectrum.h` (CIE standard
//! illuminant D65, relative to 560 nm), both stored as f32 as Mitsuba stores them.
//! `scripts/spectrum_rgb.py` records Mitsuba's own results that `tests/spec/spectrum/cie.rs`
//! checks these functions against.
#![allow(clippy::excessive_precision)]

use glam::DVec3;

/// Mitsuba's `MI_CIE_MIN` and `MI_CIE_MAX` (nm): the range of the tables.
pub const CIE_MIN: f64 = 360.0;
/// See [`CIE_MIN`].
pub const CIE_MAX: f64 = 830.0;
/// Mitsuba's `MI_CIE_SAMPLES`: entries per table, 5 nm apart.
pub const CIE_SAMPLES: usize = 95;
/// `MI_CIE_Y_NORMALIZATION`: a unit spectrum integrates to luminance 1.
pub const CIE_Y_NORMALIZATION: f64 = 1.0 / 106.7502593994140625;
/// `MI_CIE_D65_NORMALIZATION`: D65 integrates to luminance 1.
pub const CIE_D65_NORMALIZATION: f64 = 1.0 / 98.99741751876255;
/// Wavelengths `spectrum_list_to_srgb` samples, evenly over [360, 830] nm, ends included.
const STEPS: usize = 1000;

/// Mitsuba's `xyz_to_srgb` matrix (rows), f32 entries as its `ScalarMatrix3f` holds them.
const XYZ_TO_SRGB: [[f32; 3]; 3] = [
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

/// How a property's spectrum becomes RGB: the `bounded` and `d65` arguments Mitsuba 3's
/// `Properties::get_texture_impl` (`src/core/properties.cpp`) passes to
/// `spectrum_list_to_srgb`, by the getter the plugin reads the property with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response {
    /// `get_texture` (reflectances, and a medium's `albedo` and `sigma_t` through
    /// `get_volume`): under D65, clamped to [0, 1].
    Bounded,
    /// `get_unbounded_texture` (a conductor's `eta` and `k`): under D65, clamped below at 0.
    Unbounded,
    /// `get_emissive_texture` (an emitter's radiance, intensity, irradiance): without D65,
    /// clamped below at 0.
    Emissive,
}

impl Response {
    /// (bounded, d65) of `spectrum_list_to_srgb`.
    fn flags(self) -> (bool, bool) {
        match self {
            Response::Bounded => (true, true),
            Response::Unbounded => (false, true),
            Response::Emissive => (false, false),
        }
    }
}

/// Table `tbl` linearly interpolated at `w` nm as Mitsuba's `cie1931_xyz` and `cie_d65` do in
/// double precision (0 outside [360, 830]).
fn lookup(tbl: &[f32; CIE_SAMPLES], w: f64) -> f64 {
    if !(CIE_MIN..=CIE_MAX).contains(&w) {
        return 0.0;
    }
    let t = (w - CIE_MIN) * ((CIE_SAMPLES - 1) as f64 / (CIE_MAX - CIE_MIN));
    let i0 = (t as usize).min(CIE_SAMPLES - 2);
    let w1 = t - i0 as f64;
    (1.0 - w1) * tbl[i0] as f64 + w1 * tbl[i0 + 1] as f64
}

/// The CIE 1931 colour matching functions (x-bar, y-bar, z-bar) at `w` nm.
pub fn cie1931_xyz(w: f64) -> DVec3 {
    DVec3::new(
        lookup(&CIE1931_X, w),
        lookup(&CIE1931_Y, w),
        lookup(&CIE1931_Z, w),
    )
}

/// The D65 illuminant at `w` nm, normalised to luminance 1 (Mitsuba's `cie_d65`).
pub fn cie_d65(w: f64) -> f64 {
    lookup(&D65, w) * CIE_D65_NORMALIZATION
}

/// Mitsuba's `xyz_to_srgb`: XYZ to linear sRGB (Rec. 709 primaries).
pub fn xyz_to_srgb(xyz: DVec3) -> DVec3 {
    let row = |r: [f32; 3]| r[0] as f64 * xyz.x + r[1] as f64 * xyz.y + r[2] as f64 * xyz.z;
    DVec3::new(
        row(XYZ_TO_SRGB[0]),
        row(XYZ_TO_SRGB[1]),
        row(XYZ_TO_SRGB[2]),
    )
}

/// The linear sRGB colour of the spectrum through (`wavelengths`, `values`) (nm, increasing;
/// at least two pairs), as Mitsuba 3's `spectrum_list_to_srgb`: the spectrum, linearly
/// interpolated and zero outside its wavelengths, times D65 unless `Emissive`, is weighted by
/// the CIE 1931 colour matching functions at 1000 wavelengths evenly spaced over [360, 830] nm,
/// summed times 470 nm / 1000, normalised so that a unit spectrum has luminance 1, taken to
/// sRGB, and clamped as `response` says. Returns the colour and whether it was clamped (Mitsuba
/// warns "clamping out-of-gamut color").
pub fn spectrum_list_to_srgb(
    wavelengths: &[f64],
    values: &[f64],
    response: Response,
) -> (DVec3, bool) {
    assert!(wavelengths.len() >= 2 && wavelengths.len() == values.len());
    let (bounded, d65) = response.flags();
    let (first, last) = (wavelengths[0], wavelengths[wavelengths.len() - 1]);
    let mut xyz = DVec3::ZERO;
    for i in 0..STEPS {
        let w = CIE_MIN + (i as f64 / (STEPS - 1) as f64) * (CIE_MAX - CIE_MIN);
        if w < first || w > last {
            continue;
        }
        // the interval [w0, w1] holding w (the last one for w = last)
        let k = (wavelengths.partition_point(|&x| x <= w) - 1).min(wavelengths.len() - 2);
        let (w0, w1, v0, v1) = (wavelengths[k], wavelengths[k + 1], values[k], values[k + 1]);
        let v = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1);
        xyz += cie1931_xyz(w) * v * if d65 { cie_d65(w) } else { 1.0 };
    }
    xyz *= (CIE_MAX - CIE_MIN) * CIE_Y_NORMALIZATION / STEPS as f64;
    let rgb = xyz_to_srgb(xyz);
    let clamped = if bounded {
        rgb.clamp(DVec3::ZERO, DVec3::ONE)
    } else {
        rgb.max(DVec3::ZERO)
    };
    (clamped, clamped != rgb)
}

/// The colour of a uniform `<spectrum value="x">` of an emitter in Mitsuba's RGB variants:
/// `x * xyz_to_srgb(1, 1, 1)` in double precision, the sRGB of a flat spectrum (purplish, since
/// sRGB's white is D65), so that they match its spectral variants
/// (`Properties::get_texture_impl`).
pub fn uniform_emission(x: f64) -> DVec3 {
    xyz_to_srgb(DVec3::ONE) * x
}

/// x-bar.
#[rustfmt::skip]
pub const CIE1931_X: [f32; CIE_SAMPLES] = [
    0.000129900000, 0.000232100000, 0.000414900000, 0.000741600000, 0.001368000000,
    0.002236000000, 0.004243000000, 0.007650000000, 0.014310000000, 0.023190000000,
    0.043510000000, 0.077630000000, 0.134380000000, 0.214770000000, 0.283900000000,
    0.328500000000, 0.348280000000, 0.348060000000, 0.336200000000, 0.318700000000,
    0.290800000000, 0.251100000000, 0.195360000000, 0.142100000000, 0.095640000000,
    0.057950010000, 0.032010000000, 0.014700000000, 0.004900000000, 0.002400000000,
    0.009300000000, 0.029100000000, 0.063270000000, 0.109600000000, 0.165500000000,
    0.225749900000, 0.290400000000, 0.359700000000, 0.433449900000, 0.512050100000,
    0.594500000000, 0.678400000000, 0.762100000000, 0.842500000000, 0.916300000000,
    0.978600000000, 1.026300000000, 1.056700000000, 1.062200000000, 1.045600000000,
    1.002600000000, 0.938400000000, 0.854449900000, 0.751400000000, 0.642400000000,
    0.541900000000, 0.447900000000, 0.360800000000, 0.283500000000, 0.218700000000,
    0.164900000000, 0.121200000000, 0.087400000000, 0.063600000000, 0.046770000000,
    0.032900000000, 0.022700000000, 0.015840000000, 0.011359160000, 0.008110916000,
    0.005790346000, 0.004109457000, 0.002899327000, 0.002049190000, 0.001439971000,
    0.000999949300, 0.000690078600, 0.000476021300, 0.000332301100, 0.000234826100,
    0.000166150500, 0.000117413000, 0.000083075270, 0.000058706520, 0.000041509940,
    0.000029353260, 0.000020673830, 0.000014559770, 0.000010253980, 0.000007221456,
    0.000005085868, 0.000003581652, 0.000002522525, 0.000001776509, 0.000001251141,
];
/// y-bar.
#[rustfmt::skip]
pub const CIE1931_Y: [f32; CIE_SAMPLES] = [
    0.000003917000, 0.000006965000, 0.000012390000, 0.000022020000, 0.000039000000,
    0.000064000000, 0.000120000000, 0.000217000000, 0.000396000000, 0.000640000000,
    0.001210000000, 0.002180000000, 0.004000000000, 0.007300000000, 0.011600000000,
    0.016840000000, 0.023000000000, 0.029800000000, 0.038000000000, 0.048000000000,
    0.060000000000, 0.073900000000, 0.090980000000, 0.112600000000, 0.139020000000,
    0.169300000000, 0.208020000000, 0.258600000000, 0.323000000000, 0.407300000000,
    0.503000000000, 0.608200000000, 0.710000000000, 0.793200000000, 0.862000000000,
    0.914850100000, 0.954000000000, 0.980300000000, 0.994950100000, 1.000000000000,
    0.995000000000, 0.978600000000, 0.952000000000, 0.915400000000, 0.870000000000,
    0.816300000000, 0.757000000000, 0.694900000000, 0.631000000000, 0.566800000000,
    0.503000000000, 0.441200000000, 0.381000000000, 0.321000000000, 0.265000000000,
    0.217000000000, 0.175000000000, 0.138200000000, 0.107000000000, 0.081600000000,
    0.061000000000, 0.044580000000, 0.032000000000, 0.023200000000, 0.017000000000,
    0.011920000000, 0.008210000000, 0.005723000000, 0.004102000000, 0.002929000000,
    0.002091000000, 0.001484000000, 0.001047000000, 0.000740000000, 0.000520000000,
    0.000361100000, 0.000249200000, 0.000171900000, 0.000120000000, 0.000084800000,
    0.000060000000, 0.000042400000, 0.000030000000, 0.000021200000, 0.000014990000,
    0.000010600000, 0.000007465700, 0.000005257800, 0.000003702900, 0.000002607800,
    0.000001836600, 0.000001293400, 0.000000910930, 0.000000641530, 0.000000451810,
];
/// z-bar.
#[rustfmt::skip]
pub const CIE1931_Z: [f32; CIE_SAMPLES] = [
    0.000606100000, 0.001086000000, 0.001946000000, 0.003486000000, 0.006450001000,
    0.010549990000, 0.020050010000, 0.036210000000, 0.067850010000, 0.110200000000,
    0.207400000000, 0.371300000000, 0.645600000000, 1.039050100000, 1.385600000000,
    1.622960000000, 1.747060000000, 1.782600000000, 1.772110000000, 1.744100000000,
    1.669200000000, 1.528100000000, 1.287640000000, 1.041900000000, 0.812950100000,
    0.616200000000, 0.465180000000, 0.353300000000, 0.272000000000, 0.212300000000,
    0.158200000000, 0.111700000000, 0.078249990000, 0.057250010000, 0.042160000000,
    0.029840000000, 0.020300000000, 0.013400000000, 0.008749999000, 0.005749999000,
    0.003900000000, 0.002749999000, 0.002100000000, 0.001800000000, 0.001650001000,
    0.001400000000, 0.001100000000, 0.001000000000, 0.000800000000, 0.000600000000,
    0.000340000000, 0.000240000000, 0.000190000000, 0.000100000000, 0.000049999990,
    0.000030000000, 0.000020000000, 0.000010000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
    0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000, 0.000000000000,
];
/// The CIE D65 illuminant, relative to its power at 560 nm.
#[rustfmt::skip]
pub const D65: [f32; CIE_SAMPLES] = [
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482,
    68.7015, 82.7549, 87.1204, 91.486, 92.4589, 93.4318, 90.057,
    86.6823, 95.7736, 104.865, 110.936, 117.008, 117.41, 117.812,
    116.336, 114.861, 115.392, 115.923, 112.367, 108.811, 109.082,
    109.354, 108.578, 107.802, 106.296, 104.79, 106.239, 107.689,
    106.047, 104.405, 104.225, 104.046, 102.023, 100.0, 98.1671,
    96.3342, 96.0611, 95.788, 92.2368, 88.6856, 89.3459, 90.0062,
    89.8026, 89.5991, 88.6489, 87.6987, 85.4936, 83.2886, 83.4939,
    83.6992, 81.863, 80.0268, 80.1207, 80.2146, 81.2462, 82.2778,
    80.281, 78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979,
    74.349, 67.9765, 61.604, 65.7448, 69.8856, 72.4863, 75.087,
    69.3398, 63.5927, 55.0054, 46.4182, 56.6118, 66.8054, 65.0941,
    63.3828, 63.8434, 64.304, 61.8779, 59.4519, 55.7054, 51.959,
    54.6998, 57.4406, 58.8765, 60.3125,
];
