//! Diagnostics of a scene file: the line and the key of every error. Serde and the TOML
//! parser report byte spans (or, for the internally tagged enums, the span of a whole table);
//! these functions map spans and key paths to lines, find the statement a syntax error lies in
//! without valid TOML, and narrow a schema error down to the key that causes it.

use std::collections::BTreeMap;

use super::{KeyPath, KeySeg, SceneError, SceneFile};

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

/// A syntax error (the text is not TOML) at the line where the parser stopped, with the key
/// of the statement it was reading.
pub(super) fn syntax_error(text: &str, name: &str, e: &toml::de::Error) -> SceneError {
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

thread_local! {
    static TRIALS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// How many deserializations [`narrow`] has tried on this thread: the work of locating a
/// schema error, which a test bounds.
#[doc(hidden)]
pub fn narrow_trials() -> usize {
    TRIALS.with(|t| t.get())
}

// ANCHOR: narrow
/// Narrows the error `error` of the whole file down from `at`: the element of an array of
/// tables, or the key of a table, whose deletion changes the error is where it lies (the `type`
/// tag excepted: without it nothing inside the table is looked at). With `tables_only`, only
/// sub-tables are candidates (for a missing key, deleting any required sibling would change
/// the error too). The candidates are halved, deleting a whole range at a time, so a file of
/// n shapes costs log n deserializations per level, not n.
fn narrow(root: &toml::Value, at: KeyPath, error: &str, tables_only: bool) -> KeyPath {
    let children = candidates(root, &at, tables_only);
    let changes = |range: &[KeySeg]| -> bool {
        TRIALS.with(|t| t.set(t.get() + 1));
        let mut r = root.clone();
        if let Some(v) = value_at_mut(&mut r, &at.0) {
            remove(v, range);
        }
        match r.try_into::<SceneFile>() {
            Ok(_) => true,
            Err(e) => e.message().trim() != error,
        }
    };
    let (mut lo, mut hi) = (0, children.len());
    if hi == 0 || !changes(&children) {
        return at;
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if changes(&children[lo..mid]) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    // the halving assumes that the error is the first of its kind; check the one it found,
    // and in a short list try the others (a long one stays at `at`, its cost bounded)
    let tries = if children.len() <= 32 {
        children.len()
    } else {
        1
    };
    let found = children[lo..]
        .iter()
        .chain(&children[..lo])
        .take(tries)
        .find(|c| changes(std::slice::from_ref(c)));
    match found {
        Some(KeySeg::Key(k)) => narrow(root, at.clone().key(k), error, tables_only),
        Some(KeySeg::Index(i)) => narrow(root, at.clone().index(*i), error, tables_only),
        None => at,
    }
}

/// The children of `at` that [`narrow`] may delete: the keys of a table (not `type`; only
/// sub-tables with `tables_only`), or the indices of an array of tables.
fn candidates(root: &toml::Value, at: &KeyPath, tables_only: bool) -> Vec<KeySeg> {
    let is_table = |v: &toml::Value| matches!(v, toml::Value::Table(_));
    let is_table_array = |v: &toml::Value| matches!(v, toml::Value::Array(a) if !a.is_empty() && a.iter().all(is_table));
    let mut scratch = root.clone();
    match value_at_mut(&mut scratch, &at.0) {
        Some(toml::Value::Table(t)) => t
            .iter()
            .filter(|(k, v)| *k != "type" && (!tables_only || is_table(v) || is_table_array(v)))
            .map(|(k, _)| KeySeg::Key(k.clone()))
            .collect(),
        Some(v @ toml::Value::Array(_)) if is_table_array(v) => {
            (0..v.as_array().map_or(0, Vec::len))
                .map(KeySeg::Index)
                .collect()
        }
        _ => Vec::new(),
    }
}

/// Deletes `children` (keys, or indices in increasing order) from the table or array `v`.
fn remove(v: &mut toml::Value, children: &[KeySeg]) {
    match v {
        toml::Value::Table(t) => {
            for c in children {
                if let KeySeg::Key(k) = c {
                    t.remove(k);
                }
            }
        }
        toml::Value::Array(a) => {
            if let (Some(KeySeg::Index(first)), Some(KeySeg::Index(last))) =
                (children.first(), children.last())
            {
                a.drain(*first..=(*last).min(a.len().saturating_sub(1)));
            }
        }
        _ => {}
    }
}
// ANCHOR_END: narrow

/// Whether `message` refuses the `type` of the table `value` (an inline table of a tagged
/// enum, whose error carries only the table's span): the key is then its `type`.
fn is_unknown_tag(message: &str, value: Option<&toml::Value>) -> bool {
    let tag = message
        .strip_prefix("unknown variant `")
        .and_then(|r| r.split('`').next());
    let Some(toml::Value::Table(t)) = value else {
        return false;
    };
    tag.is_some_and(|tag| t.get("type").and_then(toml::Value::as_str) == Some(tag))
}

/// A schema error (unknown key, missing key, wrong type) at the key that causes it.
pub(super) fn schema_error(
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
            let mut root = root;
            let value = value_at_mut(&mut root, &key.0);
            if is_unknown_tag(&message, value.as_deref()) {
                key = key.key("type");
            }
            got = value.map(|v| v.to_string());
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
