//! `<include filename="..."/>`: the included file's elements in place of the element, as
//! Mitsuba 3's parser merges them. The file is found relative to the including file, then
//! relative to the main file (Mitsuba prepends the including file's folder to its resolver,
//! which holds the main file's); its root is a `<scene>` of version 2 or 3 whose children are
//! spliced in. Relative paths inside it stay relative to the main file, as Mitsuba resolves
//! resources after parsing. Includes nest at most [`MAX_INCLUDE_DEPTH`] files deep (Mitsuba's
//! limit) and a file including itself is refused. The spliced text keeps a map from its lines
//! to each file's own, so errors name the included file and its line.

use std::path::{Path, PathBuf};

use super::props::newlines;
use super::{check_attribute_counts, parse};
use crate::scene::file::MAX_SCENE_BYTES;
use crate::scene::SceneError;

/// How deep files may include files (Mitsuba's `max_include_depth`: the main file is at depth
/// 0, and depth 15 is refused).
pub const MAX_INCLUDE_DEPTH: usize = 15;

pub use crate::scene::file::Segments;

/// The text of the main file `name` (in `dir`) with every include spliced in, and the map of
/// its lines (empty when there is no include: the text is returned as it is).
pub fn expand(name: &str, text: &str, dir: &Path) -> Result<(String, Segments), SceneError> {
    check_attribute_counts(name, text)?;
    if !text.contains("<include") {
        return Ok((text.to_string(), Segments::new()));
    }
    let mut out = Spliced {
        text: String::new(),
        lines: 1,
        segments: Segments::new(),
        main_dir: dir.to_path_buf(),
        stack: std::fs::canonicalize(name).into_iter().collect(),
    };
    out.file(name, text, dir, 0)?;
    Ok((out.text, out.segments))
}

struct Spliced {
    text: String,
    /// The line the next character of `text` is on.
    lines: usize,
    segments: Segments,
    main_dir: PathBuf,
    /// The files being spliced, outermost first (a file in it including itself is a cycle).
    stack: Vec<PathBuf>,
}

impl Spliced {
    /// Appends `text[range]` of file `name`, starting on a line of its own.
    fn chunk(&mut self, name: &str, text: &str, range: std::ops::Range<usize>) {
        if !self.text.is_empty() && !self.text.ends_with('\n') {
            self.text.push('\n');
            self.lines += 1;
        }
        let local = text[..range.start].matches('\n').count() + 1;
        self.segments.push((self.lines, name.to_string(), local));
        let piece = &text[range];
        self.lines += piece.matches('\n').count();
        self.text.push_str(piece);
    }

    /// Splices file `name` (at `depth`; its includes relative to `dir`): all of it at depth 0,
    /// the children of its `<scene>` below.
    fn file(&mut self, name: &str, text: &str, dir: &Path, depth: usize) -> Result<(), SceneError> {
        if depth > 0 {
            check_attribute_counts(name, text)?;
        }
        let xml = parse(name, text)?;
        let root = xml.root_element();
        let lines = newlines(text);
        let err = |node: roxmltree::Node, message: String| SceneError {
            file: name.to_string(),
            line: Some(lines.partition_point(|&i| i < node.range().start) + 1),
            key: format!("<{}>", node.tag_name().name()),
            message,
        };
        let content = if depth == 0 {
            0..text.len()
        } else {
            let version = root.attribute("version").unwrap_or("");
            if !root.has_tag_name("scene")
                || !(version.starts_with("2.") || version.starts_with("3."))
            {
                return Err(err(
                    root,
                    "an included file's root must be <scene version=\"3.x\"> (or 2.x)".into(),
                ));
            }
            match (root.first_child(), root.last_child()) {
                (Some(a), Some(b)) => a.range().start..b.range().end,
                _ => return Ok(()),
            }
        };
        let mut at = content.start;
        for inc in root.descendants().filter(|n| n.has_tag_name("include")) {
            self.chunk(name, text, at..inc.range().start);
            let file = inc_file(inc).map_err(|m| err(inc, m))?;
            let (path, shown) = self.resolve(&file, dir, name);
            if depth + 1 >= MAX_INCLUDE_DEPTH {
                return Err(err(
                    inc,
                    format!(
                        "includes nest deeper than {MAX_INCLUDE_DEPTH} files (Mitsuba's limit)"
                    ),
                ));
            }
            let key = std::fs::canonicalize(&path).unwrap_or(path.clone());
            if self.stack.contains(&key) {
                return Err(err(
                    inc,
                    format!("`{file}` includes itself (a cycle of includes)"),
                ));
            }
            let bytes = crate::conventions::read_at_most(&path, MAX_SCENE_BYTES as u64)
                .map_err(|e| err(inc, format!("`{file}` cannot be read: {shown}: {e}")))?;
            let inner = String::from_utf8(bytes)
                .map_err(|_| err(inc, format!("`{file}`: {shown} is not UTF-8 text")))?;
            self.stack.push(key);
            let sub = path.parent().map(Path::to_path_buf).unwrap_or_default();
            self.file(&shown, &inner, &sub, depth + 1)?;
            self.stack.pop();
            if self.text.len() > MAX_SCENE_BYTES {
                return Err(err(
                    inc,
                    format!("the scene grows beyond {MAX_SCENE_BYTES} bytes with its includes"),
                ));
            }
            at = inc.range().end;
        }
        self.chunk(name, text, at..content.end);
        Ok(())
    }

    /// The path of include `file` (relative to `dir`, the including file's folder, else to the
    /// main file's) and its name in messages (beside the including file's `name`).
    fn resolve(&self, file: &str, dir: &Path, name: &str) -> (PathBuf, String) {
        let near = dir.join(file);
        let path = if near.exists() {
            near
        } else {
            let far = self.main_dir.join(file);
            if far.exists() {
                far
            } else {
                near
            }
        };
        let shown = match Path::new(name).parent() {
            Some(p) if path.starts_with(dir) && !Path::new(file).is_absolute() => {
                p.join(file).display().to_string()
            }
            _ => path.display().to_string(),
        };
        (path, shown)
    }
}

/// The `filename` of an `<include>`, the only attribute it may have, without `$name`s.
fn inc_file(inc: roxmltree::Node) -> Result<String, String> {
    if let Some(a) = inc.attributes().find(|a| a.name() != "filename") {
        return Err(format!(
            "<include> takes only `filename`, not `{}`",
            a.name()
        ));
    }
    if inc.children().any(|c| c.is_element()) {
        return Err("<include> has no child elements".into());
    }
    let file = inc
        .attribute("filename")
        .ok_or("the attribute `filename` is missing")?;
    if file.contains('$') {
        return Err(format!(
            "filename=\"{file}\": a `$name` in an include's file name is not imported"
        ));
    }
    Ok(file.to_string())
}
