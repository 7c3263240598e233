//! What a scene file may cost before it is parsed, and how its text is quoted in messages.
//!
//! The TOML parser builds the whole document before serde looks at it (and the diagnostics
//! parse it again), so a 2-million-element array cost seconds and hundreds of megabytes only to
//! be refused. These checks run first, on the bytes: the file's size, then one lexical pass that
//! counts the elements and the nesting of every inline array and table. The limits are far above
//! anything the schema reads (its longest arrays are a phase mixture's weights).

use std::borrow::Cow;

use super::{statement_at, SceneError};

/// The largest scene file read, in bytes (the shipped scenes are under 10 KiB; meshes and
/// density grids are files of their own).
pub const MAX_SCENE_BYTES: usize = 8 << 20;

/// The most elements an inline array (or entries an inline table) of a scene file may hold.
pub const MAX_ARRAY_ELEMENTS: usize = 4096;

/// The deepest nesting of inline arrays and tables.
pub const MAX_NESTING: usize = 32;

/// An error about the file as a whole (its key is [`super::FILE_KEY`]).
fn file_error(name: &str, message: String) -> SceneError {
    SceneError {
        file: name.to_string(),
        line: None,
        key: super::FILE_KEY.into(),
        message,
    }
}

/// Refuses a file longer than [`MAX_SCENE_BYTES`] (`len` bytes, or more).
pub fn check_size(name: &str, len: usize) -> Result<(), SceneError> {
    if len > MAX_SCENE_BYTES {
        return Err(file_error(
            name,
            format!(
                "the scene file has more than {MAX_SCENE_BYTES} bytes (the limit of a scene file)"
            ),
        ));
    }
    Ok(())
}

/// The text of a scene file's bytes; invalid UTF-8 is reported with its byte offset, line,
/// column and the statement it lies in.
pub fn decode(bytes: Vec<u8>, name: &str) -> Result<String, SceneError> {
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let valid = std::str::from_utf8(&e.as_bytes()[..at]).unwrap_or_default();
        let line_start = valid.rfind('\n').map_or(0, |i| i + 1);
        let column = valid[line_start..].chars().count() + 1;
        let line = valid.bytes().filter(|&b| b == b'\n').count() + 1;
        SceneError {
            file: name.to_string(),
            line: Some(line),
            key: statement_at(valid, at).map_or("(document)".into(), |(k, _)| k),
            message: format!(
                "invalid UTF-8 at byte offset {at} (line {line}, column {column}): byte 0x{:02x}",
                e.as_bytes()[at]
            ),
        }
    })
}

/// One open inline array or table of the scan: where it opened, its commas so far, and
/// whether an element follows the last comma (a trailing comma is allowed).
struct Open {
    at: usize,
    commas: usize,
    pending: bool,
    table: bool,
}

impl Open {
    /// The error when this array or table holds more than [`MAX_ARRAY_ELEMENTS`] elements.
    fn check(&self, text: &str, name: &str) -> Result<(), SceneError> {
        if self.commas + usize::from(self.pending) <= MAX_ARRAY_ELEMENTS {
            return Ok(());
        }
        let (what, unit) = match self.table {
            true => ("an inline table of more than", "entries"),
            false => ("an array of more than", "elements"),
        };
        let message = format!("{what} {MAX_ARRAY_ELEMENTS} {unit} (the limit of a scene file)");
        Err(too_much(text, name, self.at, message))
    }
}

/// Refuses an inline array with more than [`MAX_ARRAY_ELEMENTS`] elements (an inline table
/// with more entries), or nesting deeper than [`MAX_NESTING`], at the key that opens it. A
/// lexical scan that tracks strings, comments and table headers, so the cost is one pass over
/// the text and no allocation per element.
pub fn check_arrays(text: &str, name: &str) -> Result<(), SceneError> {
    let b = text.as_bytes();
    let mut open: Vec<Open> = Vec::new();
    let mut at_line_start = true;
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        let line_start = std::mem::replace(&mut at_line_start, false);
        let element = !matches!(c, b'\n' | b' ' | b'\t' | b'\r' | b'#' | b',' | b']' | b'}');
        if let Some(o) = open.last_mut().filter(|_| element) {
            o.pending = true;
        }
        match c {
            b'\n' => at_line_start = true,
            b' ' | b'\t' | b'\r' => at_line_start = line_start,
            b'#' => i = skip_to_newline(b, i),
            b'"' | b'\'' => i = skip_string(b, i),
            b'[' if line_start && open.is_empty() => i = skip_to_newline(b, i), // a header
            b'[' | b'{' => {
                if open.len() == MAX_NESTING {
                    let message = format!("inline arrays and tables nested more than {MAX_NESTING} deep (the limit of a scene file)");
                    return Err(too_much(text, name, i, message));
                }
                let table = c == b'{';
                open.push(Open {
                    at: i,
                    commas: 0,
                    pending: false,
                    table,
                });
            }
            b']' | b'}' => {
                if let Some(o) = open.pop() {
                    o.check(text, name)?;
                }
            }
            b',' => {
                if let Some(o) = open.last_mut() {
                    // every comma follows an element: refused as soon as there are too many
                    (o.commas, o.pending) = (o.commas + 1, false);
                    o.check(text, name)?;
                }
            }
            _ => {}
        }
        i += 1;
    }
    Ok(())
}

/// The error of a limit exceeded by the array or table opened at byte `at`.
fn too_much(text: &str, name: &str, at: usize, message: String) -> SceneError {
    let (key, _) = statement_at(text, at).unwrap_or(("(document)".into(), 1));
    SceneError {
        file: name.to_string(),
        line: Some(super::line_of(text, at)),
        key,
        message,
    }
}

/// The index of the newline that ends the line of byte `i` (or the end).
fn skip_to_newline(b: &[u8], i: usize) -> usize {
    b[i..]
        .iter()
        .position(|&c| c == b'\n')
        .map_or(b.len(), |n| i + n - 1)
}

/// The index of the last byte of the string that opens at byte `i`: basic (`"`, with
/// escapes) or literal (`'`), one-line or multi-line (tripled quotes). An unclosed one-line
/// string ends at its line (the parser reports it).
fn skip_string(b: &[u8], i: usize) -> usize {
    let q = b[i];
    let triple = b.len() >= i + 3 && b[i + 1] == q && b[i + 2] == q;
    let mut j = if triple { i + 3 } else { i + 1 };
    while j < b.len() {
        match b[j] {
            b'\\' if q == b'"' => j += 1,
            b'\n' if !triple => return j - 1,
            c if c == q && !triple => return j,
            c if c == q && b[j..].starts_with(&[q, q, q]) => {
                // up to two quotes may close a multi-line string's content
                let mut end = j + 2;
                while end + 1 < b.len() && b[end + 1] == q {
                    end += 1;
                }
                return end;
            }
            _ => {}
        }
        j += 1;
    }
    b.len()
}

/// `s` with its control characters (and the bidirectional overrides, which reorder what a
/// terminal shows) escaped, `\u{1b}` for ESC: messages quote keys and values of the file, and
/// a file must not write to the user's terminal through them.
pub fn escape_controls(s: &str) -> Cow<'_, str> {
    let hidden =
        |c: char| c.is_control() || matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}');
    if !s.chars().any(hidden) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        if hidden(c) {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// pbrt's scene directives: a file whose first statement is one of them is a pbrt scene.
const PBRT_DIRECTIVES: [&str; 12] = [
    "LookAt",
    "Camera",
    "Film",
    "Sampler",
    "Integrator",
    "WorldBegin",
    "Shape",
    "Include",
    "Import",
    "Transform",
    "PixelFilter",
    "ColorSpace",
];

/// Refuses a scene in another renderer's format with what it is, instead of the TOML parser's
/// confusing first complaint (`key with no value` at `<scene version`): a Mitsuba scene is XML
/// and begins with `<`, a pbrt scene with a directive such as `LookAt` or `WorldBegin`.
pub fn check_format(text: &str, name: &str) -> Result<(), SceneError> {
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap_or("");
    let word = first
        .split(|c: char| !c.is_ascii_alphabetic())
        .next()
        .unwrap_or("");
    let what = if first.starts_with('<') {
        "XML (a Mitsuba scene?)"
    } else if PBRT_DIRECTIVES.contains(&word) && !first.contains('=') {
        "a pbrt scene"
    } else {
        return Ok(());
    };
    let import = if first.starts_with('<') {
        "; it imports Mitsuba 3 XML from files named `.xml` (the book's chapter Importing scenes)"
    } else {
        "; it has no importer for pbrt"
    };
    Err(file_error(
        name,
        format!(
            "this file is {what}: pathspace reads its own TOML scene files (see \
             scenes/fog-box.toml and the book's chapter Scenes){import}"
        ),
    ))
}
