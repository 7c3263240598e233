//! The scene file format (TOML): the schema, parsing, validation and error locations.
//!
//! Every error names the file, the line and the key, and says what is wrong. Syntax and type
//! errors come from the TOML deserializer with their span; semantic errors (negative sigma,
//! |g| >= 1, an unknown material, an open shape carrying a medium, ...) are raised on the parsed
//! description with a key path, which [`locate`] maps back to a line through a span-keeping parse.
//! Book: "Scenes and geometry" (tests: `tests/scene_errors.rs`).

use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

mod diagnostics;

pub use diagnostics::{line_of, locate, statement_at};
use diagnostics::{schema_error, syntax_error};

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

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(
                f,
                "{}:{}: key `{}`: {}",
                self.file, l, self.key, self.message
            ),
            None => write!(f, "{}: key `{}`: {}", self.file, self.key, self.message),
        }
    }
}

impl std::error::Error for SceneError {}

/// A number or an RGB triple (`0.4` or `[0.4, 0.5, 0.6]`).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
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

/// `[render]`: defaults for the command-line flags.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    #[serde(default = "default_integrator")]
    pub integrator: String,
    #[serde(default = "default_spp")]
    pub spp: u32,
    #[serde(default = "default_seed")]
    pub seed: u64,
    pub max_depth: Option<u32>,
    /// Samples per irradiance meter per pixel-sample pass (default 4096).
    pub meter_samples: Option<u32>,
    /// `[render.mlt]`: Metropolis light transport settings.
    pub mlt: Option<MltDesc>,
    /// `[render.smc]`: sequential Monte Carlo settings.
    pub smc: Option<SmcDesc>,
    /// `[render.guide]`: guided local sampling (enlightened local path sampling).
    pub guide: Option<GuideDesc>,
    /// Sample area-light start points from the adjoint image (bdpt, light, mlt; Kristensen
    /// 2010, sec. 5.3.1).
    pub adjoint_image: Option<bool>,
    /// `[render.adjoint]`: the adjoint image's grid, pre-pass size and floor.
    pub adjoint: Option<AdjointDesc>,
}

/// `[render.adjoint]`: the keys of the `--adjoint-*` options (defaults in
/// `enlightened::adjoint`), which override them.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AdjointDesc {
    /// Grid [columns, rows]; columns are rounded up to a multiple of the area lights.
    pub resolution: Option<[u32; 2]>,
    /// Pre-pass BDPT samples per grid cell.
    pub samples_per_cell: Option<u32>,
    /// Floor added to every cell, as a fraction of the mean cell value.
    pub epsilon: Option<f32>,
    /// `bdpt` (default) or `metropolis`: how the pre-pass estimates the cells.
    pub estimator: Option<String>,
}

/// `[render.guide]`: the keys of the `--guide*` options (defaults in `enlightened::guide`),
/// which override them.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GuideDesc {
    /// `off`, `surface`, `volume` or `both`.
    pub vertices: Option<String>,
    /// Map resolution `COLSxROWS` (default `32x16`).
    pub map: Option<String>,
    /// Regions per quantity (k-means centres).
    pub regions: Option<usize>,
    /// Light and eye subpaths traced for the photons and importons.
    pub particles: Option<usize>,
    /// c2 of eqs. (5.17)-(5.19): probability of sampling the map, in (0, 1).
    pub weight: Option<f32>,
    /// alpha of eq. (5.16) per unit length (default 20 / scene radius).
    pub alpha: Option<f32>,
    /// Guided Russian roulette with this normalization (absent: the ordinary roulette).
    pub roulette: Option<f32>,
    /// Only particles at this depth or deeper shape the maps (1: all, 2: indirect only).
    pub min_depth: Option<u32>,
    /// Particle sampler: `classical`, `bidirectional` or `metropolis`.
    pub sampler: Option<String>,
    /// Metropolis particles: small-step deviation in primary sample space.
    pub sigma: Option<f64>,
    /// Metropolis particles: weight of the defensive part of the target.
    pub defensive: Option<f64>,
}

/// `[render.smc]`: the keys of the `--smc-*` options (defaults in `integrator::smc`), which
/// override them.
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SmcDesc {
    /// `is0|is1` x `cv0|cv1|cv2` (default `is1_cv2`).
    pub variant: Option<String>,
    /// Refinement threshold on the average record count of a cache.
    pub threshold: Option<f64>,
    /// Memory budget of the structure: bytes, or a string with a unit (`"512MiB"`).
    pub cache_budget: Option<ByteCount>,
    /// `march` (eq. 8-9) or `distance` (eq. 7).
    pub estimator: Option<String>,
    /// Ray-marching step in mean free paths (march only).
    pub step: Option<f32>,
}

/// A byte count written as an integer or as a string with a unit.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum ByteCount {
    Bytes(i64),
    Text(String),
}

/// `[render.mlt]`: pre-pass size, chains, mutation selection weights and perturbation ranges
/// (defaults in `integrator::mlt`).
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MltDesc {
    pub bootstrap: Option<u64>,
    pub chains: Option<u32>,
    pub bidirectional: Option<f64>,
    pub sensor: Option<f64>,
    pub light: Option<f64>,
    pub propagation: Option<f64>,
    pub multichain: Option<f64>,
    /// Sensor perturbation film offset [min, max] in pixels.
    pub sensor_offset: Option<[f32; 2]>,
    /// Light and multi-chain perturbation angle [min, max] in radians.
    pub light_angle: Option<[f32; 2]>,
    /// Propagation perturbation distance [min, max] as fractions of the scene radius.
    pub propagation_distance: Option<[f32; 2]>,
    /// BDPT samples per mutation that keep refining b during the run (0: pre-pass only).
    pub b_refine: Option<f64>,
}

fn default_integrator() -> String {
    "path".into()
}
fn default_spp() -> u32 {
    64
}
fn default_seed() -> u64 {
    1
}

impl Default for RenderDesc {
    fn default() -> Self {
        RenderDesc {
            integrator: default_integrator(),
            spp: default_spp(),
            seed: default_seed(),
            max_depth: None,
            meter_samples: None,
            mlt: None,
            smc: None,
            guide: None,
            adjoint_image: None,
            adjoint: None,
        }
    }
}

/// `[camera]`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum CameraDesc {
    Pinhole {
        eye: [f32; 3],
        look_at: [f32; 3],
        #[serde(default = "default_up")]
        up: [f32; 3],
        /// Vertical field of view in degrees.
        fov_deg: f32,
        resolution: [u32; 2],
    },
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// `[materials.NAME]`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MaterialDesc {
    Lambert {
        albedo: RgbValue,
    },
    Mirror {
        #[serde(default = "one_rgb")]
        reflectance: RgbValue,
    },
    Dielectric {
        ior: f32,
    },
    Null {},
}

fn one_rgb() -> RgbValue {
    RgbValue::Scalar(1.0)
}

/// A phase function.
#[derive(Debug, Clone, Deserialize, PartialEq)]
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
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MediumDesc {
    Homogeneous {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
    },
    /// A density grid read from `file` (text, or Mitsuba `.vol`), trilinearly interpolated over
    /// the box [min, max] (a `.vol` brings its own box), scaling sigma_a and sigma_s.
    Grid {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
        file: String,
        min: Option<[f32; 3]>,
        max: Option<[f32; 3]>,
        #[serde(default)]
        propagation: PropagationDesc,
        /// Marching step as a fraction of the box's largest side.
        step: Option<f32>,
    },
    /// A density field evaluated on the fly over the box [min, max] (or baked onto a
    /// `resolution`^3 grid), scaling sigma_a and sigma_s.
    Procedural {
        sigma_a: RgbValue,
        sigma_s: RgbValue,
        #[serde(default = "default_phase")]
        phase: PhaseDesc,
        density: DensityDesc,
        min: [f32; 3],
        max: [f32; 3],
        /// `linear`: the axis and the densities at its two ends.
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
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Default)]
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
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "kebab-case")]
pub enum DensityDesc {
    Constant,
    Linear,
    Cloud,
    Plume,
}

/// `axis = "x" | "y" | "z"`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
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
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ShapeCommon {
    pub material: Option<String>,
    pub emission: Option<RgbValue>,
    pub interior: Option<String>,
    pub exterior: Option<String>,
}

/// `[[shapes]]`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeDesc {
    Quad {
        origin: [f32; 3],
        u: [f32; 3],
        v: [f32; 3],
        material: Option<String>,
        emission: Option<RgbValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    Box {
        min: [f32; 3],
        max: [f32; 3],
        material: Option<String>,
        emission: Option<RgbValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    Sphere {
        center: [f32; 3],
        radius: f32,
        material: Option<String>,
        emission: Option<RgbValue>,
        interior: Option<String>,
        exterior: Option<String>,
    },
    Mesh {
        obj: String,
        material: Option<String>,
        emission: Option<RgbValue>,
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
            | ShapeDesc::Mesh {
                material,
                emission,
                interior,
                exterior,
                ..
            } => ShapeCommon {
                material: material.clone(),
                emission: *emission,
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
            ShapeDesc::Mesh { .. } => "mesh",
        }
    }
}

/// `[[lights]]`: delta and infinite lights.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum LightDesc {
    /// Collimated light travelling along `direction`, irradiance on a plane facing it.
    Directional {
        direction: [f32; 3],
        irradiance: RgbValue,
    },
    /// Isotropic point light of radiant intensity `intensity` (W/sr).
    Point {
        position: [f32; 3],
        intensity: RgbValue,
    },
    /// A spot light: `intensity` inside `cone_deg` (half-angle), smooth falloff over the last
    /// `falloff_deg` degrees.
    Spot {
        position: [f32; 3],
        direction: [f32; 3],
        intensity: RgbValue,
        cone_deg: f32,
        #[serde(default)]
        falloff_deg: f32,
    },
    /// Radiance arriving from infinitely far: constant (`radiance`) or a vertical gradient
    /// (`zenith`, `horizon`, `nadir`).
    Environment {
        radiance: Option<RgbValue>,
        zenith: Option<RgbValue>,
        horizon: Option<RgbValue>,
        nadir: Option<RgbValue>,
    },
}

/// `[[sensors]]`: virtual measuring instruments.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SensorDesc {
    /// Mean irradiance arriving on the normal side (normalize(u x v)) of a parallelogram.
    IrradianceMeter {
        name: String,
        origin: [f32; 3],
        u: [f32; 3],
        v: [f32; 3],
    },
}

/// A whole scene file.
#[derive(Debug, Clone, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    #[serde(default)]
    pub render: RenderDesc,
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
    let doc = match toml::de::DeTable::parse(text) {
        Ok(doc) => doc,
        Err(e) => return Err(syntax_error(text, name, &e)),
    };
    match toml::from_str::<SceneFile>(text) {
        Ok(f) => Ok(f),
        Err(e) => Err(schema_error(text, name, doc.get_ref(), &e)),
    }
}

/// A scene file read from disk with its text (kept for error locations and hashing).
#[derive(Debug, Clone)]
pub struct SceneSource {
    pub name: String,
    pub text: String,
    /// Directory for relative paths (OBJ files, density grids).
    pub base_dir: PathBuf,
}

impl SceneSource {
    /// Reads a file.
    pub fn read(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: path.display().to_string(),
            line: None,
            key: "(file)".into(),
            message: format!("cannot read the scene file: {e}"),
        })?;
        Ok(SceneSource {
            name: path.display().to_string(),
            text,
            base_dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        })
    }

    /// An in-memory scene (the embedded default).
    pub fn embedded(name: &str, text: &str) -> Self {
        SceneSource {
            name: name.to_string(),
            text: text.to_string(),
            base_dir: PathBuf::from("."),
        }
    }

    /// A semantic error at `key`. A key the file lacks altogether (a missing `[camera]`) is
    /// reported at line 1, where a new top-level table would go.
    pub fn error(&self, key: &KeyPath, message: impl Into<String>) -> SceneError {
        SceneError {
            file: self.name.clone(),
            line: Some(locate(&self.text, key).unwrap_or(1)),
            key: key.to_string(),
            message: message.into(),
        }
    }

    /// A 64-bit FNV-1a hash of the text: references record which scene they belong to.
    pub fn hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in self.text.bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        h
    }
}
