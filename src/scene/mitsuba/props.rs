//! Reading a Mitsuba 3 XML element: its attributes with `$name` substitution, its named
//! properties (`float`, `rgb`, `transform`, nested plugins, `ref`s), and the rule that every
//! property is either translated or refused (`Props::finish`).

use glam::{DMat3, DMat4, DVec3, DVec4};
use roxmltree::Node;
use std::collections::HashMap;

use super::spectrum;
use crate::scene::SceneError;
pub use crate::spectrum::cie::Response;

/// The longest attribute value after `$name` substitution (a default repeated in one attribute
/// would otherwise multiply the file's size).
pub const MAX_ATTRIBUTE_BYTES: usize = 1 << 20;

/// What the whole document shares: its name, `<default>` values and `id`s.
pub(super) struct Doc<'a> {
    pub name: String,
    pub defaults: HashMap<String, String>,
    pub ids: HashMap<String, Node<'a, 'a>>,
    /// The byte offset of every newline of the text, so that a node's line is a binary search
    /// (roxmltree's `text_pos_at` scans from the start: quadratic over many elements).
    pub newlines: Vec<usize>,
    /// Where the lines of a text spliced from included files come from (empty for one file).
    pub segments: crate::scene::file::Segments,
    /// The directory relative file names are read from (a spectrum's `.spd` file).
    pub base_dir: std::path::PathBuf,
}

/// The offsets of the newlines of `text`, for `Doc::line`.
pub(super) fn newlines(text: &str) -> Vec<usize> {
    text.bytes()
        .enumerate()
        .filter(|&(_, b)| b == b'\n')
        .map(|(i, _)| i)
        .collect()
}

impl<'a> Doc<'a> {
    /// The 1-based line where `node` starts.
    pub fn line(&self, node: Node) -> usize {
        self.newlines.partition_point(|&i| i < node.range().start) + 1
    }

    /// The file and the line in it where `node` starts (an included file's own).
    pub fn place(&self, node: Node) -> (&str, usize) {
        crate::scene::file::place(&self.segments, &self.name, self.line(node))
    }

    /// Where `node` starts, for messages: `line N`, or `file line N` in an included file.
    pub fn at(&self, node: Node) -> String {
        match self.place(node) {
            (file, line) if file == self.name => format!("line {line}"),
            (file, line) => format!("{file} line {line}"),
        }
    }

    /// An error at `node`: file, line, the element as key.
    pub fn err(&self, node: Node, message: impl Into<String>) -> SceneError {
        let (file, line) = self.place(node);
        let ty = node.attribute("type").map(|t| format!(" type=\"{t}\""));
        let id = node.attribute("name").map(|t| format!(" name=\"{t}\""));
        SceneError {
            file: file.to_string(),
            line: Some(line),
            key: format!(
                "<{}{}{}>",
                node.tag_name().name(),
                ty.unwrap_or_default(),
                id.unwrap_or_default()
            ),
            message: message.into(),
        }
    }

    /// Attribute `a` of `node` with every `$name` replaced by its `<default>`.
    pub fn attr(&self, node: Node, a: &str) -> Result<Option<String>, SceneError> {
        let Some(raw) = node.attribute(a) else {
            return Ok(None);
        };
        let mut out = String::new();
        let mut rest = raw;
        while let Some(k) = rest.find('$') {
            out.push_str(&rest[..k]);
            let tail = &rest[k + 1..];
            let n = tail
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(tail.len());
            let key = &tail[..n];
            let value = self.defaults.get(key).ok_or_else(|| {
                self.err(
                    node,
                    format!("`${key}` in {a}=\"{raw}\" has no <default name=\"{key}\">"),
                )
            })?;
            out.push_str(value);
            if out.len() > MAX_ATTRIBUTE_BYTES {
                return Err(self.err(
                    node,
                    format!(
                        "{a}=\"...\" grows beyond {MAX_ATTRIBUTE_BYTES} bytes with its defaults"
                    ),
                ));
            }
            rest = &tail[n..];
        }
        out.push_str(rest);
        Ok(Some(out))
    }

    /// A required attribute.
    pub fn need(&self, node: Node, a: &str) -> Result<String, SceneError> {
        self.attr(node, a)?
            .ok_or_else(|| self.err(node, format!("the attribute `{a}` is missing")))
    }

    /// The plugin type of an object element (`type="..."`).
    pub fn plugin(&self, node: Node) -> Result<String, SceneError> {
        self.need(node, "type")
    }

    /// Numbers separated by commas or spaces.
    pub fn numbers(&self, node: Node, text: &str) -> Result<Vec<f64>, SceneError> {
        text.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|w| !w.is_empty())
            .map(|w| {
                w.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| self.err(node, format!("`{w}` is not a finite number")))
            })
            .collect()
    }

    fn number(&self, node: Node, a: &str) -> Result<Option<f64>, SceneError> {
        match self.attr(node, a)? {
            None => Ok(None),
            Some(t) => match self.numbers(node, &t)?.as_slice() {
                [x] => Ok(Some(*x)),
                _ => Err(self.err(node, format!("{a}=\"{t}\" must be one number"))),
            },
        }
    }

    /// A point or vector: `value="x, y, z"` or attributes `x`, `y`, `z` (missing ones `dflt`).
    pub fn triple(&self, node: Node, dflt: f64) -> Result<DVec3, SceneError> {
        if let Some(t) = self.attr(node, "value")? {
            return match self.numbers(node, &t)?.as_slice() {
                [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                [x] => Ok(DVec3::splat(*x)),
                _ => Err(self.err(node, format!("value=\"{t}\" must be one or three numbers"))),
            };
        }
        Ok(DVec3::new(
            self.number(node, "x")?.unwrap_or(dflt),
            self.number(node, "y")?.unwrap_or(dflt),
            self.number(node, "z")?.unwrap_or(dflt),
        ))
    }

    /// The element an object child stands for: itself, or what a `<ref id>` names.
    pub fn resolve(&self, node: Node<'a, 'a>) -> Result<Node<'a, 'a>, SceneError> {
        if node.tag_name().name() != "ref" {
            return Ok(node);
        }
        let id = self.need(node, "id")?;
        self.ids
            .get(&id)
            .copied()
            .ok_or_else(|| self.err(node, format!("no element has id=\"{id}\"")))
    }
}

/// The tags of value properties (everything else is a nested object or a `ref`).
const VALUE_TAGS: [&str; 9] = [
    "float",
    "integer",
    "boolean",
    "string",
    "rgb",
    "spectrum",
    "point",
    "vector",
    "transform",
];

/// One property of an element.
struct Entry<'a> {
    /// `name="..."`, if given.
    name: Option<String>,
    /// The element as written (for its line).
    at: Node<'a, 'a>,
    /// The value element (a `ref` resolved).
    node: Node<'a, 'a>,
}

/// The properties of one plugin element, each to be consumed exactly once.
pub(super) struct Props<'a, 'd> {
    pub doc: &'d Doc<'a>,
    pub node: Node<'a, 'a>,
    pub plugin: String,
    entries: Vec<Entry<'a>>,
    used: Vec<bool>,
}

impl<'a, 'd> Props<'a, 'd> {
    pub fn new(doc: &'d Doc<'a>, node: Node<'a, 'a>) -> Result<Self, SceneError> {
        let plugin = doc.plugin(node)?;
        let mut entries = Vec::new();
        for c in node.children().filter(Node::is_element) {
            let name = doc.attr(c, "name")?;
            let value = doc.resolve(c)?;
            if VALUE_TAGS.contains(&c.tag_name().name()) && name.is_none() {
                return Err(doc.err(c, "a property needs a `name`"));
            }
            entries.push(Entry {
                name,
                at: c,
                node: value,
            });
        }
        let used = vec![false; entries.len()];
        Ok(Props {
            doc,
            node,
            plugin,
            entries,
            used,
        })
    }

    /// An error at this plugin's element.
    pub fn err(&self, message: impl Into<String>) -> SceneError {
        self.doc.err(self.node, message)
    }

    fn take(&mut self, name: &str) -> Option<(Node<'a, 'a>, Node<'a, 'a>)> {
        let k = self
            .entries
            .iter()
            .position(|e| e.name.as_deref() == Some(name))?;
        self.used[k] = true;
        Some((self.entries[k].at, self.entries[k].node))
    }

    /// The tag of the property `name`, if present (without consuming it).
    pub fn tag_of(&self, name: &str) -> Option<&str> {
        self.entries
            .iter()
            .find(|e| e.name.as_deref() == Some(name))
            .map(|e| e.node.tag_name().name())
    }

    /// The value element of `name` with one of `tags`, if present.
    fn value(&mut self, name: &str, tags: &[&str]) -> Result<Option<Node<'a, 'a>>, SceneError> {
        let Some((at, node)) = self.take(name) else {
            return Ok(None);
        };
        let tag = node.tag_name().name();
        if tags.contains(&tag) {
            return Ok(Some(node));
        }
        Err(self.doc.err(
            at,
            format!(
                "`{name}` of `{}` is a <{tag}>; the importer accepts {} here{}",
                self.plugin,
                tags.join(" or "),
                if tag == "texture" {
                    " (textures beyond constant values are not supported)"
                } else {
                    ""
                }
            ),
        ))
    }

    pub fn float(&mut self, name: &str) -> Result<Option<f64>, SceneError> {
        let Some(n) = self.value(name, &["float", "integer"])? else {
            return Ok(None);
        };
        let t = self.doc.need(n, "value")?;
        match self.doc.numbers(n, &t)?.as_slice() {
            [x] => Ok(Some(*x)),
            _ => Err(self.doc.err(n, format!("value=\"{t}\" must be one number"))),
        }
    }

    pub fn integer(&mut self, name: &str) -> Result<Option<i64>, SceneError> {
        let Some(n) = self.value(name, &["integer"])? else {
            return Ok(None);
        };
        let t = self.doc.need(n, "value")?;
        t.trim()
            .parse::<i64>()
            .map(Some)
            .map_err(|_| self.doc.err(n, format!("value=\"{t}\" is not an integer")))
    }

    pub fn boolean(&mut self, name: &str) -> Result<Option<bool>, SceneError> {
        let Some(n) = self.value(name, &["boolean"])? else {
            return Ok(None);
        };
        match self.doc.need(n, "value")?.trim() {
            "true" => Ok(Some(true)),
            "false" => Ok(Some(false)),
            t => Err(self
                .doc
                .err(n, format!("value=\"{t}\" is not true or false"))),
        }
    }

    pub fn string(&mut self, name: &str) -> Result<Option<String>, SceneError> {
        match self.value(name, &["string"])? {
            None => Ok(None),
            Some(n) => self.doc.need(n, "value").map(Some),
        }
    }

    /// A constant colour: `<float>`, `<rgb>`, or a `<spectrum>` (one value, wavelength:value
    /// pairs or a `.spd` file) reduced to RGB with `response`, the way the plugin reads the
    /// property in Mitsuba 3 (`spectrum::cie::Response`).
    pub fn color(&mut self, name: &str, response: Response) -> Result<Option<DVec3>, SceneError> {
        let Some(n) = self.value(name, &["float", "rgb", "spectrum"])? else {
            return Ok(None);
        };
        if n.tag_name().name() == "spectrum" {
            return self.spectrum(n, response).map(Some);
        }
        let t = self.doc.need(n, "value")?;
        match (n.tag_name().name(), self.doc.numbers(n, &t)?.as_slice()) {
            (_, [x]) => Ok(Some(DVec3::splat(*x))),
            ("rgb", [r, g, b]) => Ok(Some(DVec3::new(*r, *g, *b))),
            _ => Err(self.doc.err(
                n,
                format!("value=\"{t}\" must be one number (or three for <rgb>)"),
            )),
        }
    }

    /// A `<spectrum>` with `value` or (exclusively) `filename` (relative to the main XML file's
    /// directory), as RGB.
    fn spectrum(&self, n: Node, response: Response) -> Result<DVec3, SceneError> {
        let spectrum = match (self.doc.attr(n, "value")?, self.doc.attr(n, "filename")?) {
            (Some(t), None) => spectrum::parse_value(&t)
                .map_err(|e| self.doc.err(n, format!("value=\"{t}\": {e}")))?,
            (None, Some(f)) => spectrum::read_spd(&self.spd_path(n, &f))
                .map_err(|e| self.doc.err(n, format!("filename=\"{f}\": {e}")))?,
            _ => {
                return Err(self.doc.err(
                    n,
                    "a <spectrum> takes either `value` or `filename` (but not both)",
                ))
            }
        };
        // the f32 colour Mitsuba's `srgb` texture holds
        Ok(spectrum.rgb(response).0.as_vec3().as_dvec3())
    }

    /// Where a `.spd` file is read from: Mitsuba resolves it while parsing, with the folder of
    /// an included file searched before the main file's.
    fn spd_path(&self, n: Node, f: &str) -> std::path::PathBuf {
        let (file, _) = self.doc.place(n);
        if file != self.doc.name {
            if let Some(near) = std::path::Path::new(file).parent().map(|d| d.join(f)) {
                if near.exists() {
                    return near;
                }
            }
        }
        self.doc.base_dir.join(f)
    }

    pub fn point(&mut self, name: &str) -> Result<Option<DVec3>, SceneError> {
        match self.value(name, &["point", "vector"])? {
            None => Ok(None),
            Some(n) => self.doc.triple(n, 0.0).map(Some),
        }
    }

    pub fn transform(&mut self, name: &str) -> Result<Option<DMat4>, SceneError> {
        match self.value(name, &["transform"])? {
            None => Ok(None),
            Some(n) => transform(self.doc, n).map(Some),
        }
    }

    /// The property `name` when it is a `<texture>` (nested or referenced).
    pub fn texture(&mut self, name: &str) -> Option<Node<'a, 'a>> {
        if self.tag_of(name) != Some("texture") {
            return None;
        }
        self.take(name).map(|(_, node)| node)
    }

    /// The nested object with tag `tag` (named `name`, or any name when `None`).
    pub fn object(
        &mut self,
        tag: &str,
        name: Option<&str>,
    ) -> Result<Option<Node<'a, 'a>>, SceneError> {
        let found: Vec<usize> = (0..self.entries.len())
            .filter(|&k| {
                self.entries[k].node.tag_name().name() == tag
                    && !VALUE_TAGS.contains(&self.entries[k].at.tag_name().name())
                    && (name.is_none() || self.entries[k].name.as_deref() == name)
            })
            .collect();
        match found.as_slice() {
            [] => Ok(None),
            [k] => {
                self.used[*k] = true;
                Ok(Some(self.entries[*k].node))
            }
            [_, k, ..] => Err(self.doc.err(
                self.entries[*k].at,
                format!("`{}` takes one <{tag}>", self.plugin),
            )),
        }
    }

    /// Properties that do not change the image (accepted and not translated).
    pub fn ignore(&mut self, names: &[&str]) {
        for n in names {
            let _ = self.take(n);
        }
    }

    /// Refuses every property that was not translated: a scene is never imported differently.
    pub fn finish(self) -> Result<(), SceneError> {
        match self.used.iter().position(|u| !u) {
            None => Ok(()),
            Some(k) => {
                let e = &self.entries[k];
                let what = match &e.name {
                    Some(n) => format!("the parameter `{n}`"),
                    None => format!("a nested <{}>", e.node.tag_name().name()),
                };
                Err(self.doc.err(
                    e.at,
                    format!(
                        "{what} of `{}` is not supported by the importer",
                        self.plugin
                    ),
                ))
            }
        }
    }
}

/// A rotation by `deg` degrees about `axis` (right-handed), exact at multiples of 90 degrees
/// so that walls built by rotation stay exactly coplanar.
fn rotation(axis: DVec3, deg: f64) -> DMat4 {
    let quarter = deg / 90.0;
    let (s, c) = if quarter == quarter.round() {
        const SC: [(f64, f64); 4] = [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)];
        SC[(quarter.round() as i64).rem_euclid(4) as usize]
    } else {
        deg.to_radians().sin_cos()
    };
    let a = axis.normalize();
    let k = DMat3::from_cols(
        DVec3::new(0.0, a.z, -a.y),
        DVec3::new(-a.z, 0.0, a.x),
        DVec3::new(a.y, -a.x, 0.0),
    );
    // Rodrigues: c I + (1 - c) a a^T + s [a]x
    let aat = DMat3::from_cols(a * a.x, a * a.y, a * a.z);
    DMat4::from_mat3(DMat3::IDENTITY * c + aat * (1.0 - c) + k * s)
}

/// Mitsuba's look-at frame: columns left = up x dir, up' = dir x left, dir, origin.
fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - origin).try_normalize()?;
    let left = up.cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    ))
}

/// A `<transform>`: its operations applied in order (each multiplies from the left).
pub(super) fn transform(doc: &Doc, node: Node) -> Result<DMat4, SceneError> {
    let mut m = DMat4::IDENTITY;
    for op in node.children().filter(Node::is_element) {
        let step = match op.tag_name().name() {
            "translate" => DMat4::from_translation(doc.triple(op, 0.0)?),
            "scale" => DMat4::from_scale(doc.triple(op, 1.0)?),
            "rotate" => {
                let axis = doc.triple(op, 0.0)?;
                let angle = doc.number(op, "angle")?.unwrap_or(0.0);
                if axis.length_squared() == 0.0 {
                    return Err(doc.err(op, "the rotation axis is zero"));
                }
                rotation(axis, angle)
            }
            "matrix" => {
                let t = doc.need(op, "value")?;
                match doc.numbers(op, &t)?.as_slice() {
                    v if v.len() == 16 => DMat4::from_cols_array(v.try_into().unwrap()).transpose(),
                    v if v.len() == 9 => {
                        DMat4::from_mat3(DMat3::from_cols_array(v.try_into().unwrap()).transpose())
                    }
                    _ => return Err(doc.err(op, "a matrix has 16 (or 9) numbers, row by row")),
                }
            }
            "lookat" => {
                let v = |a: &str| -> Result<DVec3, SceneError> {
                    match doc.numbers(op, &doc.need(op, a)?)?.as_slice() {
                        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                        _ => Err(doc.err(op, format!("`{a}` must be three numbers"))),
                    }
                };
                let up = match doc.attr(op, "up")? {
                    Some(_) => v("up")?,
                    None => DVec3::Y,
                };
                look_at(v("origin")?, v("target")?, up).ok_or_else(|| {
                    doc.err(op, "origin equals target, or up is parallel to the view")
                })?
            }
            t => {
                return Err(doc.err(
                    op,
                    format!("<{t}> in a <transform> is not supported (translate, rotate, scale, matrix, lookat are)"),
                ))
            }
        };
        m = step * m;
    }
    if !m.is_finite() || m.row(3) != DVec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err(doc.err(node, "the transform must be finite and affine"));
    }
    Ok(m)
}
