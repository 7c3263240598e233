//! Mitsuba 3 scene XML, translated into pathspace's scene file (`scene::file::SceneFile` plus
//! its `[render]` table), which the ordinary build then turns into a `Scene`.
//!
//! The subset research scenes use (book: "Importing scenes", with the table of every plugin and
//! parameter): `<default>` and `$name`, `id` / `<ref>`, the `path`/`volpath` integrators,
//! the `direct` integrator, the `perspective` sensor with `hdrfilm` (box filter) and any sampler, the shapes
//! `rectangle`, `disk`, `cube`, `sphere`, `obj`, `ply`, the BSDFs `diffuse`, `conductor`, `roughconductor`,
//! `dielectric`, `roughdielectric`, `thindielectric`, `plastic`, `twosided`, `null`, the media `homogeneous` and
//! `heterogeneous` (`gridvolume`), the phases `isotropic` and `hg`, the emitters `area`,
//! `point`, `spot`, `directional`, `constant`. Conventions are Mitsuba's (tests:
//! `tests/inputs/mitsuba_import.rs`). Anything else (a plugin, a parameter, a texture) is an error naming
//! it, the file and the line: a scene is imported as Mitsuba renders it or not at all. The
//! generated keys keep their XML lines (`file::Origin`), so errors of the build name XML lines
//! too.

mod include;
mod plugins;
mod props;
pub mod spectrum;

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use crate::scene::file::{place, Origin, SceneFile, SceneSource, FILE_KEY};
use crate::scene::SceneError;
use props::{newlines, Doc};

/// The most XML nodes a scene may have (the text is already limited to `MAX_SCENE_BYTES`).
pub const MAX_XML_NODES: u32 = 1 << 22;

/// The most attributes one XML element may have. Mitsuba's elements have at most four
/// (`type`, `name`, `value`, `id`); the XML library checks each new attribute against all
/// earlier ones of its element, so an element with 80,000 takes tens of CPU seconds: the
/// count is checked first, in one linear pass.
pub const MAX_XML_ATTRIBUTES: usize = 64;

/// Refuses an element with more than [`MAX_XML_ATTRIBUTES`] attributes before the XML library
/// sees the text: one pass counting the `=` outside quotes inside each tag (comments, CDATA,
/// processing instructions and declarations skipped), naming the line where the tag starts.
fn check_attribute_counts(name: &str, text: &str) -> Result<(), SceneError> {
    let bytes = text.as_bytes();
    let (mut i, mut line, mut tag_line) = (0, 1, 1);
    let (mut in_tag, mut quote, mut count) = (false, None, 0usize);
    while i < bytes.len() {
        let b = bytes[i];
        if b == b'\n' {
            line += 1;
        }
        if !in_tag {
            if b == b'<' {
                let rest = &bytes[i..];
                let skip_to = |end: &[u8]| {
                    rest.windows(end.len())
                        .position(|w| w == end)
                        .map(|p| p + end.len())
                };
                let skipped = if rest.starts_with(b"<!--") {
                    skip_to(b"-->")
                } else if rest.starts_with(b"<![CDATA[") {
                    skip_to(b"]]>")
                } else if rest.starts_with(b"<?") {
                    skip_to(b"?>")
                } else {
                    None
                };
                if let Some(n) = skipped {
                    line += rest[..n].iter().filter(|&&c| c == b'\n').count();
                    i += n;
                    continue;
                }
                (in_tag, count, tag_line) = (true, 0, line);
            }
        } else if let Some(q) = quote {
            if b == q {
                quote = None;
            }
        } else {
            match b {
                b'"' | b'\'' => quote = Some(b),
                b'=' => count += 1,
                b'>' => in_tag = false,
                _ => {}
            }
            if count > MAX_XML_ATTRIBUTES {
                return Err(SceneError {
                    file: name.to_string(),
                    line: Some(tag_line),
                    key: "(xml)".into(),
                    message: format!(
                        "an element with more than {MAX_XML_ATTRIBUTES} attributes (Mitsuba's \
                         have at most 4)"
                    ),
                });
            }
        }
        i += 1;
    }
    Ok(())
}

/// Translates the Mitsuba 3 XML `text` (read from the file `name`, relative paths from
/// `base_dir`) into a scene source whose text is the equivalent scene file.
pub fn import(name: &str, text: &str, base_dir: PathBuf) -> Result<SceneSource, SceneError> {
    let (text, segments) = include::expand(name, text, &base_dir)?;
    let xml = parse(name, &text).map_err(|mut e| {
        let (file, line) = place(&segments, name, e.line.unwrap_or(1));
        (e.file, e.line) = (file.to_string(), Some(line));
        e
    })?;
    let root = xml.root_element();
    let mut doc = Doc {
        name: name.to_string(),
        defaults: HashMap::new(),
        ids: HashMap::new(),
        newlines: newlines(xml.input_text()),
        segments,
        base_dir: base_dir.clone(),
    };
    resolve(&mut doc, root)?;
    let mut imp = plugins::Importer::new(&doc, base_dir.clone());
    imp.scene(root)?;
    let (file, mut origin) = imp.finish(root)?;
    origin.segments = doc.segments.clone();
    let text = generated_text(name, &file)?;
    Ok(SceneSource {
        name: name.to_string(),
        text,
        base_dir,
        origin: Some(Arc::new(origin)),
        inputs: Default::default(),
    })
}

/// Parses XML `text` (of the file `name`) with the limits.
fn parse<'t>(name: &str, text: &'t str) -> Result<roxmltree::Document<'t>, SceneError> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: false,
        nodes_limit: MAX_XML_NODES,
        ..roxmltree::ParsingOptions::default()
    };
    roxmltree::Document::parse_with_options(text, options).map_err(|e| SceneError {
        file: name.to_string(),
        line: Some(e.pos().row as usize),
        key: "(xml)".into(),
        message: format!("not well-formed XML: {e}"),
    })
}

/// Checks the root and the version, and resolves what every element may refer to: the
/// `<default>` values, every `$name` (wherever it is: Mitsuba substitutes while parsing) and
/// the `id`s.
fn resolve<'a>(doc: &mut Doc<'a>, root: roxmltree::Node<'a, 'a>) -> Result<(), SceneError> {
    if root.tag_name().name() != "scene" {
        return Err(doc.err(root, "the root element must be <scene>"));
    }
    let version = doc.need(root, "version")?;
    if !(version.starts_with("2.") || version.starts_with("3.")) {
        return Err(doc.err(
            root,
            format!("version=\"{version}\": only Mitsuba 2/3 scenes are imported (0.x scenes use other parameter names)"),
        ));
    }
    for d in root.children().filter(|c| c.has_tag_name("default")) {
        let (k, v) = (doc.need(d, "name")?, doc.need(d, "value")?);
        doc.defaults.insert(k, v);
    }
    // every `$name` resolves, wherever it is (Mitsuba substitutes while parsing)
    for n in root.descendants().filter(|n| n.is_element()) {
        for a in n.attributes() {
            doc.attr(n, a.name())?;
        }
    }
    for n in root
        .descendants()
        .filter(|n| n.is_element() && !n.has_tag_name("ref"))
    {
        if let Some(id) = n.attribute("id") {
            if let Some(old) = doc.ids.insert(id.to_string(), n) {
                return Err(doc.err(n, format!("id=\"{id}\" is already used at {}", doc.at(old))));
            }
        }
    }
    Ok(())
}

/// The scene file as TOML text (what `Scene::load` and the render settings read).
fn generated_text(name: &str, file: &SceneFile) -> Result<String, SceneError> {
    // no file name here: the scene's hash (provenance, shards) must not depend on the path
    let header = "# Translated from a Mitsuba 3 scene by pathspace's importer.\n".to_string();
    toml::to_string(file)
        .map(|t| header + &t)
        .map_err(|e| SceneError {
            file: name.to_string(),
            line: None,
            key: FILE_KEY.into(),
            message: format!("the translated scene cannot be written: {e}"),
        })
}

/// The origin of a scene built from XML: `Origin::format`.
pub const FORMAT: &str = "Mitsuba 3 XML";

/// Whether `origin` came from this importer.
pub fn is_mitsuba(origin: &Origin) -> bool {
    origin.format == FORMAT
}
