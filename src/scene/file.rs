//! The scene file format (TOML): the schema, parsing, validation and error locations.
//!
//! Every error names the file, the line and the key, and says what is wrong. Syntax and type
//! errors come from the TOML deserializer with their span; semantic errors (negative sigma,
//! |g| >= 1, an unknown material, an open shape carrying a medium, ...) are raised on the parsed
//! description with a key path, which [`locate`] maps back to a line through a span-keeping parse.
//! The scene description here ([`SceneFile`]) and [`SceneSource`] are what both readers of a
//! scene produce (`scene::source` reads a file and dispatches by format, `scene::mitsuba`
//! translates XML into this format), so they live below both.
//! Book: "Scenes and geometry" (tests: `tests/inputs/scene_errors.rs`).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;

mod diagnostics;
mod fixed;
mod limits;

pub use diagnostics::{line_of, locate, narrow_trials, statement_at};
use diagnostics::{schema_error, syntax_error};
pub use fixed::{exact, exact_opt};
pub(crate) use limits::{check_size, decode};
pub use limits::{escape_controls, MAX_ARRAY_ELEMENTS, MAX_NESTING, MAX_SCENE_BYTES};

/// A scene-file error: where, which key, what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    pub file: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// Dotted key path, e.g. `media.fog.sigma_s` or `shapes[2].material`.
    pub key: String,
    pub message: String,
}

/// The `key` of an error about the file as a whole (it cannot be read, it is too long): such
/// an error has no line and no key, and its message follows the file's name.
pub const FILE_KEY: &str = "(file)";

/// The message a user reads: `file:line: key `k`: message` (`file: message` for the file as a
/// whole), control characters escaped (keys and values are quoted from the file).
impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (file, key) = (escape_controls(&self.file), escape_controls(&self.key));
        let message = escape_controls(&self.message);
        match self.line {
            _ if self.key == FILE_KEY => write!(f, "{file}: {message}"),
            Some(l) => write!(f, "{file}:{l}: key `{key}`: {message}"),
            None => write!(f, "{file}: key `{key}`: {message}"),
        }
    }
}

impl std::error::Error for SceneError {}

/// A number or an RGB triple (`0.4` or `[0.4, 0.5, 0.6]`).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum RgbValue {
    Scalar(f32),
    Triple([f32; 3]),
}

impl fmt::Display for RgbValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RgbValue::Scalar(v) => write!(f, "{v}"),
            RgbValue::Triple([r, g, b]) => write!(f, "[{r}, {g}, {b}]"),
        }
    }
}

impl RgbValue {
    pub fn to_rgb(self) -> glam::Vec3 {
        match self {
            RgbValue::Scalar(v) => glam::Vec3::splat(v),
            RgbValue::Triple(a) => glam::Vec3::from_array(a),
        }
    }
}

/// A colour (a reflectance, or a conductor's `eta` or `k`): a number, an RGB triple, or a
/// texture (`{ texture = "checkerboard" }`).
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum ReflectanceValue {
    Value(RgbValue),
    Texture(TextureDesc),
}

impl From<RgbValue> for ReflectanceValue {
    fn from(v: RgbValue) -> Self {
        ReflectanceValue::Value(v)
    }
}

impl fmt::Display for ReflectanceValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReflectanceValue::Value(v) => write!(f, "{v}"),
            ReflectanceValue::Texture(TextureDesc::Bitmap { file, .. }) => {
                write!(f, "bitmap `{file}`")
            }
            ReflectanceValue::Texture(TextureDesc::Checkerboard { color0, color1, .. }) => {
                write!(f, "checkerboard {color0} / {color1}")
            }
        }
    }
}

/// A shape's `emission`: the radiance its normal side emits, a number, an RGB triple, or a
/// texture over the shape's (u, v) (the syntax of a reflectance, values any finite >= 0; Mitsuba
/// 3 documentation, plugin `area`, `radiance`).
pub type EmissionValue = ReflectanceValue;

/// A roughness: a number, or a texture whose one-channel value (the luminance, as Mitsuba 3's
/// `eval_1`) is the roughness at each point.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum RoughnessValue {
    Value(f32),
    Texture(TextureDesc),
}

impl From<f32> for RoughnessValue {
    fn from(v: f32) -> Self {
        RoughnessValue::Value(v)
    }
}

impl fmt::Display for RoughnessValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RoughnessValue::Value(v) => write!(f, "{v}"),
            RoughnessValue::Texture(t) => write!(f, "{}", ReflectanceValue::Texture(t.clone())),
        }
    }
}

/// A texture, as Mitsuba 3's plugins of the same names and defaults (`texture::bitmap`,
/// `texture::checkerboard`); `to_uv` is the rows `[[a, b, c], [d, e, f]]` of u' = a u + b v + c,
/// v' = d u + e v + f.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "texture", rename_all = "snake_case", deny_unknown_fields)]
pub enum TextureDesc {
    /// An 8-bit PNG (sRGB-decoded unless `raw`) or an EXR (linear), relative to the scene file.
    Bitmap {
        file: String,
        #[serde(default)]
        filter_type: FilterTypeDesc,
        #[serde(default)]
        wrap_mode: WrapModeDesc,
        #[serde(default)]
        raw: bool,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to_uv: Option<[[f32; 3]; 2]>,
    },
    /// `color0` (0.4) and `color1` (0.2) alternating on the unit square.
    Checkerboard {
        #[serde(default = "checker0")]
        color0: RgbValue,
        #[serde(default = "checker1")]
        color1: RgbValue,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to_uv: Option<[[f32; 3]; 2]>,
    },
}

fn checker0() -> RgbValue {
    RgbValue::Scalar(crate::texture::checkerboard::COLOR0)
}
fn checker1() -> RgbValue {
    RgbValue::Scalar(crate::texture::checkerboard::COLOR1)
}

/// A bitmap's `filter_type` (Mitsuba 3's names).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum FilterTypeDesc {
    #[default]
    Bilinear,
    Nearest,
}

/// A bitmap's `wrap_mode` (Mitsuba 3's names).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum WrapModeDesc {
    #[default]
    Repeat,
    Mirror,
    Clamp,
}

/// `[camera]`.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum CameraDesc {
    Pinhole {
        #[serde(deserialize_with = "exact")]
        eye: [f32; 3],
        #[serde(deserialize_with = "exact")]
        look_at: [f32; 3],
        #[serde(default = "default_up")]
        #[serde(deserialize_with = "exact")]
        up: [f32; 3],
        /// Vertical field of view in degrees.
        fov_deg: f32,
        #[serde(deserialize_with = "exact")]
        resolution: [u32; 2],
        /// Radius of a thin lens around `eye` (scene units); 0, the default, is the pinhole.
        #[serde(default, skip_serializing_if = "is_zero")]
        aperture_radius: f32,
        /// Distance from the lens to the plane in focus along the viewing direction; needed
        /// when `aperture_radius` > 0.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        focus_distance: Option<f32>,
        /// The pixels' reconstruction filter (Mitsuba 3's `box`, `tent`, `gaussian`).
        #[serde(default, skip_serializing_if = "FilterDesc::is_box")]
        filter: FilterDesc,
    },
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// `[camera] filter`: a reconstruction filter with Mitsuba 3's parameters and defaults.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum FilterDesc {
    #[default]
    Box,
    Tent {
        #[serde(default = "default_tent_radius")]
        radius: f32,
    },
    Gaussian {
        #[serde(default = "default_stddev")]
        stddev: f32,
    },
}

impl FilterDesc {
    fn is_box(&self) -> bool {
        *self == FilterDesc::Box
    }
}

/// Mitsuba 3, plugin `tent`: radius 1 pixel.
fn default_tent_radius() -> f32 {
    1.0
}

/// Mitsuba 3, plugin `gaussian`: standard deviation 0.5 pixels.
fn default_stddev() -> f32 {
    0.5
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// `[materials.NAME]`.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MaterialDesc {
    /// `one_sided`: black behind the normal, as Mitsuba's `diffuse` (default: two-sided).
    /// `albedo` may be a texture.
    Lambert {
        albedo: ReflectanceValue,
        #[serde(default)]
        one_sided: bool,
    },
    Mirror {
        #[serde(default = "one_rgb")]
        reflectance: RgbValue,
        #[serde(default)]
        one_sided: bool,
    },
    /// Smooth glass: `ior` inside over outside; `specular_reflectance` and
    /// `specular_transmittance` (1, or textures) scale reflection and refraction, as Mitsuba
    /// 3's `dielectric`.
    Dielectric {
        ior: f32,
        #[serde(default = "one_reflectance")]
        specular_reflectance: ReflectanceValue,
        #[serde(default = "one_reflectance")]
        specular_transmittance: ReflectanceValue,
    },
    /// A thin dielectric sheet (Mitsuba 3's `thindielectric`): reflects or lets light through
    /// unbent; `ior` is the sheet's index over the surrounding one; the two factors as
    /// `dielectric`'s.
    ThinDielectric {
        ior: f32,
        #[serde(default = "one_reflectance")]
        specular_reflectance: ReflectanceValue,
        #[serde(default = "one_reflectance")]
        specular_transmittance: ReflectanceValue,
    },
    /// Smooth metal (Mitsuba 3's `conductor`): the Fresnel reflectance of a complex index,
    /// `material` (one of Mitsuba's named conductors, `"Au"`) or `eta` and `k`; eta 0, k 1
    /// (reflectance 1) when neither is given; `specular` (1, or a texture) scales it.
    Conductor {
        #[serde(default)]
        material: Option<String>,
        #[serde(default)]
        eta: Option<ReflectanceValue>,
        #[serde(default)]
        k: Option<ReflectanceValue>,
        #[serde(default = "one_reflectance")]
        specular: ReflectanceValue,
        #[serde(default)]
        one_sided: bool,
    },
    /// Microfacet metal: `alpha` (a number or a texture) or `alpha_u` and `alpha_v` (each a
    /// number or a texture: the roughness along the shape's dp/du and across it),
    /// `distribution` (default ggx), and
    /// `reflectance` (Schlick), `material` (a named conductor) or `eta` and `k` (complex index);
    /// reflectance 1 when none is given; `specular` (1, or a texture) scales the Fresnel term.
    RoughConductor {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha: Option<RoughnessValue>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha_u: Option<RoughnessValue>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha_v: Option<RoughnessValue>,
        #[serde(default)]
        distribution: DistributionDesc,
        #[serde(default)]
        reflectance: Option<RgbValue>,
        #[serde(default)]
        material: Option<String>,
        #[serde(default)]
        eta: Option<ReflectanceValue>,
        #[serde(default)]
        k: Option<ReflectanceValue>,
        #[serde(default = "one_reflectance")]
        specular: ReflectanceValue,
        #[serde(default)]
        one_sided: bool,
    },
    /// Microfacet glass: `ior` inside over outside, `alpha` (a number or a texture) or
    /// `alpha_u` and `alpha_v` (as `rough_conductor`'s), `distribution` (default ggx), the two
    /// factors as `dielectric`'s.
    RoughDielectric {
        ior: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha: Option<RoughnessValue>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha_u: Option<RoughnessValue>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        alpha_v: Option<RoughnessValue>,
        #[serde(default)]
        distribution: DistributionDesc,
        #[serde(default = "one_reflectance")]
        specular_reflectance: ReflectanceValue,
        #[serde(default = "one_reflectance")]
        specular_transmittance: ReflectanceValue,
    },
    /// A diffuse base under a rough dielectric coating (Mitsuba 3's `roughplastic`), with
    /// Mitsuba's defaults: `diffuse` 0.5, `specular` 1 (both may be textures), `alpha` 0.1,
    /// `distribution` beckmann, `ior` 1.49 / 1.000277 (polypropylene in air), `nonlinear` false;
    /// two-sided unless `one_sided`.
    RoughPlastic {
        #[serde(default = "half_reflectance")]
        diffuse: ReflectanceValue,
        #[serde(default = "one_reflectance")]
        specular: ReflectanceValue,
        #[serde(default = "plastic_alpha")]
        alpha: f32,
        #[serde(default = "beckmann")]
        distribution: DistributionDesc,
        #[serde(default = "plastic_ior")]
        ior: f32,
        #[serde(default)]
        nonlinear: bool,
        #[serde(default)]
        one_sided: bool,
    },
    /// Smooth plastic (Mitsuba 3's `plastic`): `diffuse` (default 0.5) under a dielectric coat
    /// of `ior` inside over outside (default 1.49 / 1.000277) reflecting `specular` (default
    /// 1, or a texture) times Fresnel; `nonlinear` internal bounces; `one_sided` as for
    /// `lambert`.
    Plastic {
        #[serde(default = "half_reflectance")]
        diffuse: ReflectanceValue,
        #[serde(default = "one_reflectance")]
        specular: ReflectanceValue,
        #[serde(default)]
        ior: Option<f32>,
        #[serde(default)]
        nonlinear: bool,
        #[serde(default)]
        one_sided: bool,
    },
    Null {},
}

fn half_reflectance() -> ReflectanceValue {
    ReflectanceValue::Value(RgbValue::Scalar(0.5))
}

fn one_reflectance() -> ReflectanceValue {
    ReflectanceValue::Value(RgbValue::Scalar(1.0))
}

fn one_rgb() -> RgbValue {
    RgbValue::Scalar(1.0)
}

fn plastic_alpha() -> f32 {
    0.1
}

fn beckmann() -> DistributionDesc {
    DistributionDesc::Beckmann
}

/// Mitsuba's `roughplastic` default: polypropylene (1.49) over air (1.000277).
fn plastic_ior() -> f32 {
    (1.49f64 / 1.000277) as f32
}

/// A microfacet distribution by name.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum DistributionDesc {
    #[default]
    Ggx,
    Beckmann,
}

/// A phase function.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PhaseDesc {
    Isotropic {},
    Hg {
        g: f32,
    },
    Schlick {
        k: f32,
    },
    Mix {
        weights: Vec<f32>,
        lobes: Vec<PhaseDesc>,
    },
}

/// `[media.NAME]`.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MediumDesc {
    Homogeneous {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
        /// L_e,V0 of eq. (1): radiance added per unit length (pbrt-v4: sigma_a times its `Le`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<RgbValue>,
    },
    /// A density grid read from `file` (text, or Mitsuba `.vol`), trilinearly interpolated over
    /// the box [min, max] (a `.vol` brings its own box), scaling sigma_a and sigma_s.
    Grid {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
        /// L_e,V0 per unit density (eq. 1), scaled by the density like sigma_a and sigma_s.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<RgbValue>,
        file: String,
        #[serde(default, deserialize_with = "exact_opt")]
        min: Option<[f32; 3]>,
        #[serde(default, deserialize_with = "exact_opt")]
        max: Option<[f32; 3]>,
        #[serde(default)]
        propagation: PropagationDesc,
        /// Marching step as a fraction of the box's largest side.
        step: Option<f32>,
    },
    /// A float grid of an OpenVDB file (`grid`, default `density`), trilinearly interpolated
    /// between its voxels over its active box (grown by one voxel) in the world space of the
    /// grid's transform, scaling sigma_a and sigma_s.
    Vdb {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
        /// L_e,V0 per unit density (eq. 1), scaled by the density like sigma_a and sigma_s.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<RgbValue>,
        file: String,
        /// The grid's name in the file.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        grid: Option<String>,
        #[serde(default)]
        propagation: PropagationDesc,
        step: Option<f32>,
    },
    /// A density field evaluated on the fly over the box [min, max] (or baked onto a
    /// `resolution`^3 grid), scaling sigma_a and sigma_s.
    Procedural {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
        /// L_e,V0 per unit density (eq. 1), scaled by the density like sigma_a and sigma_s.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        emission: Option<RgbValue>,
        density: DensityDesc,
        #[serde(deserialize_with = "exact")]
        min: [f32; 3],
        #[serde(deserialize_with = "exact")]
        max: [f32; 3],
        /// `linear`: the axis and the densities at its two ends; `plume`: the axis it
        /// streams along (default y, rising).
        axis: Option<AxisDesc>,
        from: Option<f32>,
        to: Option<f32>,
        /// `cloud`, `plume`: fBm parameters.
        octaves: Option<u32>,
        frequency: Option<f32>,
        seed: Option<u32>,
        /// Bake the field onto a grid of this many vertices per axis.
        resolution: Option<u32>,
        #[serde(default)]
        propagation: PropagationDesc,
        step: Option<f32>,
    },
}

/// `propagation = "..."`: how the line integral of sigma_t is computed (Pauly et al. sec. 4.1).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum PropagationDesc {
    Equidistant,
    Stratified,
    RandomOffset,
    /// The unbiased default.
    #[default]
    DeltaTracking,
}

/// `density = "..."` of a procedural medium.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq)]
#[serde(rename_all = "kebab-case")]
pub enum DensityDesc {
    Constant,
    Linear,
    Cloud,
    Plume,
}

/// `axis = "x" | "y" | "z"`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq)]
#[serde(rename_all = "lowercase")]
pub enum AxisDesc {
    X,
    Y,
    Z,
}

fn default_phase() -> PhaseDesc {
    PhaseDesc::Isotropic {}
}

/// Keys every shape accepts.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ShapeCommon {
    pub material: Option<String>,
    pub emission: Option<EmissionValue>,
    pub interior: Option<String>,
    pub exterior: Option<String>,
}

/// `[[shapes]]`.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeDesc {
    /// A parallelogram `origin + a u + b v`, a, b in [0, 1], whose (u, v) are (a, b); normal
    /// `normalize(u x v)`, the opposite with `flip_normals` (Mitsuba 3's `rectangle`).
    Quad {
        #[serde(deserialize_with = "exact")]
        origin: [f32; 3],
        #[serde(deserialize_with = "exact")]
        u: [f32; 3],
        #[serde(deserialize_with = "exact")]
        v: [f32; 3],
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        flip_normals: bool,
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    Box {
        #[serde(deserialize_with = "exact")]
        min: [f32; 3],
        #[serde(deserialize_with = "exact")]
        max: [f32; 3],
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    /// A sphere; its (u, v) are (phi / 2 pi, theta / pi) in its own axes: theta from `z_axis`,
    /// phi from `x_axis` towards `z_axis x x_axis` (default: the world's z and x), as Mitsuba 3's
    /// `sphere` measures them in the rotation of its `to_world`.
    Sphere {
        #[serde(deserialize_with = "exact")]
        center: [f32; 3],
        radius: f32,
        #[serde(
            default,
            deserialize_with = "exact_opt",
            skip_serializing_if = "Option::is_none"
        )]
        x_axis: Option<[f32; 3]>,
        #[serde(
            default,
            deserialize_with = "exact_opt",
            skip_serializing_if = "Option::is_none"
        )]
        z_axis: Option<[f32; 3]>,
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    /// An elliptic disk `center + a u + b v`, a^2 + b^2 <= 1 (a circle of radius r when u and
    /// v are orthogonal of length r); normal `normalize(u x v)`, the opposite with
    /// `flip_normals`; (u, v) are the polar (r, phi / 2 pi) of (a, b) either way.
    Disk {
        #[serde(deserialize_with = "exact")]
        center: [f32; 3],
        #[serde(deserialize_with = "exact")]
        u: [f32; 3],
        #[serde(deserialize_with = "exact")]
        v: [f32; 3],
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        flip_normals: bool,
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    /// An open cylinder (Mitsuba 3's `cylinder`, no caps) of `radius` about the segment from
    /// `p0` to `p1`; its normal points outwards, inwards with `flip_normals`. Its (u, v) are
    /// (phi / 2 pi, height / length), phi from `x_axis` (perpendicular to the axis; default
    /// Mitsuba 3's frame about the axis) towards `axis x x_axis`.
    Cylinder {
        #[serde(deserialize_with = "exact")]
        p0: [f32; 3],
        #[serde(deserialize_with = "exact")]
        p1: [f32; 3],
        radius: f32,
        #[serde(default)]
        flip_normals: bool,
        #[serde(
            default,
            deserialize_with = "exact_opt",
            skip_serializing_if = "Option::is_none"
        )]
        x_axis: Option<[f32; 3]>,
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    Mesh {
        /// The mesh file, relative to the scene file: OBJ, or PLY (`.ply`), or Mitsuba's
        /// serialized format (`.serialized`), by its extension unless `format` says.
        obj: String,
        /// The file's format whatever its name (Mitsuba 3 reads a mesh by its plugin, `obj`,
        /// `ply` or `serialized`, not by the file's extension).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        format: Option<MeshFormat>,
        /// An affine map applied to the file's vertices: three rows [a, b, c, t] of
        /// x' = a x + b y + c z + t (how an imported scene places a mesh).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to_world: Option<[[f32; 4]; 3]>,
        /// Shade with normals interpolated from the vertices (the file's `vn` or `nx, ny, nz`,
        /// else angle-weighted face normals, as Mitsuba 3's meshes without `face_normals`);
        /// false: the face normal everywhere.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        smooth_normals: bool,
        /// Read a texture coordinate v as 1 - v; by default true for an OBJ file and false for a
        /// PLY file, as Mitsuba 3's `obj` and `ply` (`flip_tex_coords`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        flip_tex_coords: Option<bool>,
        /// Which shape of a Mitsuba `.serialized` file (0 by default), as Mitsuba 3's
        /// `serialized` (`shape_index`); refused for other files.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        shape_index: Option<u32>,
        /// Negate the geometric and the shading normals (their side: emission, one-sided
        /// materials, interior and exterior), the corners and (u, v) unchanged (Mitsuba 3's
        /// `flip_normals` on `obj`, `ply` and `serialized`).
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        flip_normals: bool,
        material: Option<String>,
        emission: Option<EmissionValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
}

impl ShapeDesc {
    /// The keys every shape shares.
    pub fn common(&self) -> ShapeCommon {
        match self {
            ShapeDesc::Quad {
                material,
                emission,
                interior,
                exterior,
                ..
            }
            | ShapeDesc::Box {
                material,
                emission,
                interior,
                exterior,
                ..
            }
            | ShapeDesc::Sphere {
                material,
                emission,
                interior,
                exterior,
                ..
            }
            | ShapeDesc::Disk {
                material,
                emission,
                interior,
                exterior,
                ..
            }
            | ShapeDesc::Cylinder {
                material,
                emission,
                interior,
                exterior,
                ..
            }
            | ShapeDesc::Mesh {
                material,
                emission,
                interior,
                exterior,
                ..
            } => ShapeCommon {
                material: material.clone(),
                emission: emission.clone(),
                interior: interior.clone(),
                exterior: exterior.clone(),
            },
        }
    }

    /// The `type` name.
    pub fn kind(&self) -> &'static str {
        match self {
            ShapeDesc::Quad { .. } => "quad",
            ShapeDesc::Box { .. } => "box",
            ShapeDesc::Sphere { .. } => "sphere",
            ShapeDesc::Disk { .. } => "disk",
            ShapeDesc::Cylinder { .. } => "cylinder",
            ShapeDesc::Mesh { .. } => "mesh",
        }
    }
}

/// `format = "obj" | "ply" | "serialized"` of a mesh.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum MeshFormat {
    Obj,
    Ply,
    Serialized,
}

/// `[[lights]]`: delta and infinite lights.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum LightDesc {
    /// Collimated light travelling along `direction`, irradiance on a plane facing it.
    Directional {
        #[serde(deserialize_with = "exact")]
        direction: [f32; 3],
        irradiance: RgbValue,
    },
    /// Isotropic point light of radiant intensity `intensity` (W/sr).
    Point {
        #[serde(deserialize_with = "exact")]
        position: [f32; 3],
        intensity: RgbValue,
    },
    /// A spot light: `intensity` inside `cone_deg` (half-angle), smooth falloff over the last
    /// `falloff_deg` degrees.
    Spot {
        #[serde(deserialize_with = "exact")]
        position: [f32; 3],
        #[serde(deserialize_with = "exact")]
        direction: [f32; 3],
        intensity: RgbValue,
        cone_deg: f32,
        #[serde(default)]
        falloff_deg: f32,
    },
    /// Radiance arriving from infinitely far: constant (`radiance`), a vertical gradient
    /// (`zenith`, `horizon`, `nadir`), or a latitude-longitude EXR `map` (relative to the scene
    /// file, Mitsuba 3's `envmap` convention) times `scale`, turned by the rotation `to_world`
    /// (rows of a 3x3 orthogonal matrix), sampled by luminance or `sampling = "uniform"`.
    Environment {
        radiance: Option<RgbValue>,
        zenith: Option<RgbValue>,
        horizon: Option<RgbValue>,
        nadir: Option<RgbValue>,
        map: Option<String>,
        scale: Option<f32>,
        to_world: Option<[[f32; 3]; 3]>,
        sampling: Option<EnvSamplingDesc>,
    },
}

/// `sampling = "..."` of an environment map: directions by the map's luminance (the default),
/// or uniform on the sphere (for comparisons).
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Default)]
#[serde(rename_all = "lowercase")]
pub enum EnvSamplingDesc {
    #[default]
    Luminance,
    Uniform,
}

/// `[[sensors]]`: virtual measuring instruments.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SensorDesc {
    /// Mean irradiance arriving on the normal side (normalize(u x v)) of a parallelogram.
    IrradianceMeter {
        name: String,
        #[serde(deserialize_with = "exact")]
        origin: [f32; 3],
        #[serde(deserialize_with = "exact")]
        u: [f32; 3],
        #[serde(deserialize_with = "exact")]
        v: [f32; 3],
    },
}

/// A whole scene file.
#[derive(Debug, Clone, Deserialize, Serialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// `[render]`: the render settings, read apart from the scene (their schema is
    /// `integrator::settings`, a layer above the scene), so any table is accepted here.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub render: Option<toml::Table>,
    pub camera: Option<CameraDesc>,
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDesc>,
    #[serde(default)]
    pub media: BTreeMap<String, MediumDesc>,
    #[serde(default)]
    pub shapes: Vec<ShapeDesc>,
    #[serde(default)]
    pub lights: Vec<LightDesc>,
    #[serde(default)]
    pub sensors: Vec<SensorDesc>,
    /// Leaves out of the measurement every path with no scattering vertex: light reaching the
    /// camera from an emitter through null boundaries and media alone (Mitsuba 3 documentation,
    /// integrators `path`, `volpath`: `hide_emitters`, "hide directly visible emitters").
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub hide_emitters: bool,
}

/// One step of a key path.
#[derive(Debug, Clone, PartialEq)]
pub enum KeySeg {
    Key(String),
    Index(usize),
}

/// A key path such as `shapes[2].material`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KeyPath(pub Vec<KeySeg>);

impl KeyPath {
    pub fn key(mut self, k: &str) -> Self {
        self.0.push(KeySeg::Key(k.to_string()));
        self
    }
    pub fn index(mut self, i: usize) -> Self {
        self.0.push(KeySeg::Index(i));
        self
    }
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, seg) in self.0.iter().enumerate() {
            match seg {
                KeySeg::Key(k) if i == 0 => write!(f, "{k}")?,
                KeySeg::Key(k) => write!(f, ".{k}")?,
                KeySeg::Index(n) => write!(f, "[{n}]")?,
            }
        }
        Ok(())
    }
}

/// Start `path` for building key paths.
pub fn path(k: &str) -> KeyPath {
    KeyPath::default().key(k)
}

/// Parses and validates the syntax and types of a scene file. `name` is what errors call it.
///
/// Three kinds of error come out of here, each with a line and a full key path:
/// * syntax errors (the text is not TOML): the line where the parser stopped and the key of the
///   statement it was reading, found by a tolerant lexical scan ([`statement_at`]);
/// * schema errors (unknown key, missing key, wrong type) from serde: the key path is the deepest
///   node of the span-keeping parse containing the error's span. The scene's enums are
///   internally tagged (`type = "..."`), and serde buffers such a table before it picks the
///   variant, so its errors only carry the span of the whole table: the offending key is then
///   found by name (`unknown field`), appended (`missing field`), or by deleting the table's
///   keys one at a time until the error changes (wrong types).
pub fn parse(text: &str, name: &str) -> Result<SceneFile, SceneError> {
    parse_as(text, name)
}

/// [`parse`] into any schema of the file (the scene's, or the render settings' of
/// `integrator::settings`), with the same errors.
pub fn parse_as<T: serde::de::DeserializeOwned>(text: &str, name: &str) -> Result<T, SceneError> {
    // what the parse may cost, checked before it
    limits::check_size(name, text.len())?;
    limits::check_format(text, name)?;
    limits::check_arrays(text, name)?;
    let doc = match toml::de::DeTable::parse(text) {
        Ok(doc) => doc,
        Err(e) => return Err(syntax_error(text, name, &e)),
    };
    match toml::from_str::<T>(text) {
        Ok(f) => Ok(f),
        Err(e) => Err(schema_error(text, name, doc.get_ref(), &e)),
    }
}

/// A scene file with its text (kept for error locations and hashing): what either reader of
/// [`SceneSource::read`] produces (a TOML file as it is, a Mitsuba scene translated).
#[derive(Debug, Clone)]
pub struct SceneSource {
    pub name: String,
    pub text: String,
    /// Directory for relative paths (OBJ files, density grids).
    pub base_dir: PathBuf,
    /// For a scene translated from another format (Mitsuba XML, `scene::mitsuba`), where each
    /// generated key came from: errors then name the original file's lines.
    pub origin: Option<std::sync::Arc<Origin>>,
    /// The files the scene read while it was built (meshes, grids, maps), each as the scene
    /// names it with the FNV-1a hash of its bytes: with [`SceneSource::hash`], what a render's
    /// identity is made of, so a resume or a merge names the file that changed.
    pub inputs: std::sync::Arc<std::sync::Mutex<Vec<(String, u64)>>>,
}

/// Where the keys of a translated scene came from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Origin {
    /// The format, e.g. `Mitsuba 3 XML`.
    pub format: String,
    /// (generated key path, 1-based line of the original file): an error at a key takes the
    /// line of its longest listed prefix.
    pub lines: Vec<(String, usize)>,
    /// What was imported and how, one line per element (printed by `info`).
    pub notes: Vec<String>,
    /// The medium the original file places the camera in (`None`: no medium), checked
    /// against the medium around the eye when the scene is built.
    pub camera_medium: Option<String>,
    /// Where the lines of a text spliced from several files (Mitsuba's `<include>`) come from;
    /// empty for one file.
    pub segments: Segments,
}

/// Lines of a text spliced from files: (its first line there, the file, that line in the
/// file), ascending.
pub type Segments = Vec<(usize, String, usize)>;

/// The file and line of line `line` of a spliced text (`main` and `line` before the first
/// segment, as for a text of one file).
pub fn place<'s>(segments: &'s Segments, main: &'s str, line: usize) -> (&'s str, usize) {
    match segments.partition_point(|s| s.0 <= line) {
        0 => (main, line),
        k => {
            let (start, file, local) = &segments[k - 1];
            (file, local + (line - start))
        }
    }
}

impl Origin {
    /// The original line of `key`: its longest listed prefix (a whole segment).
    pub fn line_of(&self, key: &str) -> Option<usize> {
        self.lines
            .iter()
            .filter(|(k, _)| {
                key.strip_prefix(k.as_str())
                    .is_some_and(|rest| rest.is_empty() || rest.starts_with(['.', '[']))
            })
            .max_by_key(|(k, _)| k.len())
            .map(|&(_, l)| l)
    }
}

impl SceneSource {
    /// An in-memory scene (the embedded default).
    pub fn embedded(name: &str, text: &str) -> Self {
        SceneSource {
            name: name.to_string(),
            text: text.to_string(),
            base_dir: PathBuf::from("."),
            origin: None,
            inputs: Default::default(),
        }
    }

    /// An error raised on the generated text of a translated scene, moved to the original
    /// file's line (unchanged for a scene read as it is).
    pub fn relocate(&self, mut e: SceneError) -> SceneError {
        if let Some(o) = &self.origin {
            let (file, line) = place(&o.segments, &self.name, o.line_of(&e.key).unwrap_or(1));
            (e.file, e.line) = (file.to_string(), Some(line));
        }
        e
    }

    /// A semantic error at `key`. A key the file lacks altogether (a missing `[camera]`) is
    /// reported at line 1, where a new top-level table would go.
    pub fn error(&self, key: &KeyPath, message: impl Into<String>) -> SceneError {
        let (file, line) = match &self.origin {
            Some(o) => place(
                &o.segments,
                &self.name,
                o.line_of(&key.to_string()).unwrap_or(1),
            ),
            None => (self.name.as_str(), locate(&self.text, key).unwrap_or(1)),
        };
        SceneError {
            file: file.to_string(),
            line: Some(line),
            key: key.to_string(),
            message: message.into(),
        }
    }

    /// A 64-bit FNV-1a hash of the text: references record which scene they belong to.
    pub fn hash(&self) -> u64 {
        crate::conventions::fnv1a(self.text.as_bytes())
    }

    /// Records a file the scene read, as the scene names it (`name`), by the FNV-1a hash of
    /// its bytes ([`crate::conventions::fnv1a`], computed by the reader from the bytes it
    /// parsed).
    pub fn record_input(&self, name: &str, hash: u64) {
        let mut inputs = self.inputs.lock().unwrap_or_else(|e| e.into_inner());
        inputs.push((name.to_string(), hash));
    }

    /// The files the scene read, sorted by name, each once with the hash of its bytes.
    pub fn inputs(&self) -> Vec<(String, u64)> {
        let mut v = self
            .inputs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        v.sort();
        v.dedup();
        v
    }
}
