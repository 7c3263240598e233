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
    /// `[render]`: the render settings, read apart from the scene (their schema is
    /// `integrator::settings`, a layer above the scene), so any table is accepted here.
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

/// The 1-based line of the byte offset `pos` in `text`.
pub fn line_of(text: &str, pos: usize) -> usize {
    text[..pos.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

/// The line where the key path is written: the deepest existing part of the path, so a
/// missing key points at the table that lacks it.
pub fn locate(text: &str, key: &KeyPath) -> Option<usize> {
    use toml::de::{DeTable, DeValue};
    let doc = DeTable::parse(text).ok()?;
    let mut best: Option<usize> = None;
    let mut table: Option<&DeTable> = Some(doc.get_ref());
    let mut value: Option<&DeValue> = None;
    for seg in &key.0 {
        match seg {
            KeySeg::Key(k) => {
                let t = match (table, value) {
                    (Some(t), _) => t,
                    (None, Some(DeValue::Table(t))) => t,
                    _ => break,
                };
                let Some((kspan, v)) = t
                    .iter()
                    .find(|(kk, _)| kk.get_ref().as_ref() == k.as_str())
                    .map(|(kk, v)| (kk.span(), v))
                else {
                    break;
                };
                best = Some(line_of(text, kspan.start));
                table = None;
                value = Some(v.get_ref());
            }
            KeySeg::Index(i) => {
                let Some(DeValue::Array(a)) = value else {
                    break;
                };
                let Some(item) = a.get(*i) else { break };
                best = Some(line_of(text, item.span().start));
                value = Some(item.get_ref());
                table = None;
            }
        }
    }
    best
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
    let doc = match toml::de::DeTable::parse(text) {
        Ok(doc) => doc,
        Err(e) => return Err(syntax_error(text, name, &e)),
    };
    match toml::from_str::<T>(text) {
        Ok(f) => Ok(f),
        Err(e) => Err(schema_error(text, name, doc.get_ref(), &e)),
    }
}

fn syntax_error(text: &str, name: &str, e: &toml::de::Error) -> SceneError {
    let pos = e.span().map_or(text.len(), |s| s.start);
    let line = line_of(text, pos);
    let mut message = e.message().trim().to_string();
    let key = match statement_at(text, pos) {
        Some((key, start)) => {
            if start < line {
                message =
                    format!("{message} (in the value of `{key}`, which begins on line {start})");
            }
            key
        }
        None => "(document)".into(),
    };
    SceneError {
        file: name.to_string(),
        line: Some(line),
        key,
        message,
    }
}

/// The key of the TOML statement (a `key = value` or a table header) that byte `pos` lies in,
/// and the line it begins on. A lexical scan that needs no valid TOML: it tracks strings,
/// comments and brackets, so an unclosed array is attributed to the key that opened it.
/// `[[name]]` headers are numbered, giving keys such as `shapes[2].center`.
pub fn statement_at(text: &str, pos: usize) -> Option<(String, usize)> {
    let mut table = String::new();
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut current: Option<(String, usize)> = None;
    let mut depth = 0usize;
    let mut line = 1usize;
    let mut at_line_start = true;
    let mut chars = text.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        if i > pos {
            break;
        }
        match c {
            '\n' => {
                line += 1;
                at_line_start = true;
                continue;
            }
            ' ' | '\t' | '\r' => continue,
            '#' => {
                while chars.peek().is_some_and(|&(_, c)| c != '\n') {
                    chars.next();
                }
                continue;
            }
            '"' | '\'' => {
                // a string on one line (multi-line strings end up here too, harmlessly)
                let mut escaped = false;
                while let Some(&(_, d)) = chars.peek() {
                    if d == '\n' {
                        break;
                    }
                    chars.next();
                    if c == '"' && d == '\\' && !escaped {
                        escaped = true;
                        continue;
                    }
                    if d == c && !escaped {
                        break;
                    }
                    escaped = false;
                }
            }
            '[' if at_line_start && depth == 0 => {
                let rest = &text[i..];
                let end = rest.find('\n').unwrap_or(rest.len());
                let header = rest[..end].split('#').next().unwrap_or("").trim();
                let array = header.starts_with("[[");
                let inner = header.trim_matches(['[', ']']).trim().to_string();
                table = if inner.is_empty() {
                    "(table header)".to_string()
                } else if array {
                    let n = counts.entry(inner.clone()).or_insert(0);
                    *n += 1;
                    format!("{inner}[{}]", *n - 1)
                } else {
                    inner
                };
                current = Some((table.clone(), line));
                // skip the header
                while chars.peek().is_some_and(|&(_, c)| c != '\n') {
                    chars.next();
                }
            }
            '[' | '{' => depth += 1,
            ']' | '}' => depth = depth.saturating_sub(1),
            _ if at_line_start && depth == 0 => {
                let rest = &text[i..];
                let end = rest.find(['=', '\n']).unwrap_or(rest.len());
                let k = rest[..end].trim();
                let full = match (table.is_empty(), k.is_empty()) {
                    (_, true) if !table.is_empty() => table.clone(),
                    (_, true) => "(document)".to_string(),
                    (true, false) => k.to_string(),
                    (false, false) => format!("{table}.{k}"),
                };
                current = Some((full, line));
            }
            _ => {}
        }
        at_line_start = false;
    }
    current
}

/// The deepest key whose key or value span contains `pos`, with the line of its key.
fn key_at(text: &str, doc: &toml::de::DeTable, pos: usize) -> Option<(KeyPath, usize)> {
    use toml::de::{DeTable, DeValue};
    fn walk_value(
        text: &str,
        v: &DeValue,
        pos: usize,
        here: &KeyPath,
        best: &mut Option<(KeyPath, usize)>,
    ) {
        match v {
            DeValue::Table(t) => walk_table(text, t, pos, here, best),
            DeValue::Array(a) => {
                for (i, item) in a.iter().enumerate() {
                    let p = here.clone().index(i);
                    if item.span().contains(&pos) && deeper(&p, best) {
                        *best = Some((p.clone(), line_of(text, item.span().start)));
                    }
                    walk_value(text, item.get_ref(), pos, &p, best);
                }
            }
            _ => {}
        }
    }
    fn deeper(p: &KeyPath, best: &Option<(KeyPath, usize)>) -> bool {
        best.as_ref().is_none_or(|(b, _)| p.0.len() >= b.0.len())
    }
    fn walk_table(
        text: &str,
        t: &DeTable,
        pos: usize,
        here: &KeyPath,
        best: &mut Option<(KeyPath, usize)>,
    ) {
        for (k, v) in t.iter() {
            let p = here.clone().key(k.get_ref());
            let inside =
                k.span().contains(&pos) || v.span().contains(&pos) || pos == v.span().start;
            if inside && deeper(&p, best) {
                *best = Some((p.clone(), line_of(text, k.span().start)));
            }
            walk_value(text, v.get_ref(), pos, &p, best);
        }
    }
    let mut best = None;
    walk_table(text, doc, pos, &KeyPath::default(), &mut best);
    best
}

/// The value at `key` in a plain TOML tree.
fn value_at_mut<'a>(root: &'a mut toml::Value, key: &[KeySeg]) -> Option<&'a mut toml::Value> {
    let mut v = root;
    for seg in key {
        v = match (seg, v) {
            (KeySeg::Key(k), toml::Value::Table(t)) => t.get_mut(k)?,
            (KeySeg::Index(i), toml::Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(v)
}

// ANCHOR: narrow
/// Narrows the error `error` of the whole file down from `at`: the element of an array of
/// tables, or the key of a table, whose deletion changes the error is where it lies (the `type`
/// tag excepted: without it nothing inside the table is looked at). With `tables_only`, only
/// sub-tables are candidates (for a missing key, deleting any required sibling would change
/// the error too).
fn narrow(root: &toml::Value, at: KeyPath, error: &str, tables_only: bool) -> KeyPath {
    let changes = |mut r: toml::Value, remove: &dyn Fn(&mut toml::Value)| -> bool {
        if let Some(v) = value_at_mut(&mut r, &at.0) {
            remove(v);
        }
        match r.try_into::<SceneFile>() {
            Ok(_) => true,
            Err(e) => e.message().trim() != error,
        }
    };
    let is_table = |v: &toml::Value| matches!(v, toml::Value::Table(_));
    let is_table_array = |v: &toml::Value| matches!(v, toml::Value::Array(a) if !a.is_empty() && a.iter().all(is_table));
    let mut scratch = root.clone();
    match value_at_mut(&mut scratch, &at.0) {
        Some(toml::Value::Table(t)) => {
            for (k, v) in t.iter() {
                if k == "type" || (tables_only && !is_table(v) && !is_table_array(v)) {
                    continue;
                }
                if changes(root.clone(), &|v| {
                    if let toml::Value::Table(t) = v {
                        t.remove(k);
                    }
                }) {
                    return narrow(root, at.clone().key(k), error, tables_only);
                }
            }
        }
        Some(v @ toml::Value::Array(_)) if is_table_array(v) => {
            let n = v.as_array().map_or(0, Vec::len);
            for i in 0..n {
                if changes(root.clone(), &|v| {
                    if let toml::Value::Array(a) = v {
                        a.remove(i);
                    }
                }) {
                    return narrow(root, at.clone().index(i), error, tables_only);
                }
            }
        }
        _ => {}
    }
    at
}
// ANCHOR_END: narrow

fn schema_error(
    text: &str,
    name: &str,
    doc: &toml::de::DeTable,
    e: &toml::de::Error,
) -> SceneError {
    let message = e.message().trim().to_string();
    let pos = e.span().map_or(0, |s| s.start);
    // the error's span: a key, a value, or (for the tagged enums) a whole table or array of tables
    let mut key = key_at(text, doc, pos).map(|(k, _)| k).unwrap_or_default();
    while matches!(key.0.last(), Some(KeySeg::Index(_))) {
        key.0.pop();
    }
    let missing = message
        .strip_prefix("missing field `")
        .and_then(|r| r.split('`').next())
        .map(str::to_string);
    let mut got = None;
    if let Ok(root) = toml::from_str::<toml::Value>(text) {
        if let Err(re) = root.clone().try_into::<SceneFile>() {
            key = narrow(&root, key, re.message().trim(), missing.is_some());
            got = value_at_mut(&mut root.clone(), &key.0).map(|v| v.to_string());
        }
    }
    if let Some(field) = &missing {
        if !matches!(key.0.last(), Some(KeySeg::Key(k)) if k == field) {
            key = key.key(field);
        }
    }
    let line = locate(text, &key).or_else(|| e.span().map(|s| line_of(text, s.start)));
    // serde's message for an untagged enum names the Rust type, not what the file should hold
    let message = if message.contains("untagged enum RgbValue") {
        let got = got.map_or(String::new(), |v| format!(", got {v}"));
        format!("expected a number or an array of three numbers [r, g, b]{got}")
    } else {
        message
    };
    SceneError {
        file: name.to_string(),
        line,
        key: if key.0.is_empty() {
            "(document)".into()
        } else {
            key.to_string()
        },
        message,
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
