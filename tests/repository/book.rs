//! The book is part of the executable specification: it must build, and it must not drift from
//! the code. mdBook prints an *empty* listing, silently, when an anchor is missing, so every
//! `{{#include file:anchor}}` is checked here: the file exists and the anchor encloses code.
//! Images the book shows must exist, and links between chapters must resolve.

use std::path::{Path, PathBuf};

fn book_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("book")
}

fn chapters() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(book_dir().join("src"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    v.sort();
    v
}

/// Every `{{#include path[:anchor]}}` of a chapter: (path, anchor).
fn includes(text: &str) -> Vec<(String, Option<String>)> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("{{#include ") {
        let after = &rest[i + "{{#include ".len()..];
        let end = after.find("}}").expect("unterminated include");
        let spec = after[..end].trim();
        match spec.split_once(':') {
            Some((p, a)) => out.push((p.to_string(), Some(a.to_string()))),
            None => out.push((spec.to_string(), None)),
        }
        rest = &after[end..];
    }
    out
}

/// The lines between `ANCHOR: name` and `ANCHOR_END: name` (mdBook's rule).
fn anchored(text: &str, anchor: &str) -> Option<String> {
    if anchor.chars().all(|c| c.is_ascii_digit() || c == ':') {
        return Some(text.to_string()); // line ranges
    }
    let start_tag = format!("ANCHOR: {anchor}");
    let end_tag = format!("ANCHOR_END: {anchor}");
    let mut inside = false;
    let mut found = false;
    let mut body = String::new();
    for line in text.lines() {
        if line.contains(&end_tag) {
            return if found { Some(body) } else { None };
        }
        if inside && !line.contains("ANCHOR") {
            body.push_str(line);
            body.push('\n');
        }
        if line.contains(&start_tag) && !line.contains(&end_tag) {
            let tail = &line[line.find(&start_tag).unwrap() + start_tag.len()..];
            if tail.trim().is_empty() {
                inside = true;
                found = true;
            }
        }
    }
    None
}

#[test]
fn every_include_exists_and_every_anchor_is_non_empty() {
    let mut checked = 0;
    for ch in chapters() {
        let text = std::fs::read_to_string(&ch).unwrap();
        for (path, anchor) in includes(&text) {
            let file = ch.parent().unwrap().join(&path);
            let src = std::fs::read_to_string(&file)
                .unwrap_or_else(|e| panic!("{}: include {path} not readable: {e}", ch.display()));
            if let Some(a) = anchor {
                let body = anchored(&src, &a).unwrap_or_else(|| {
                    panic!("{}: anchor `{a}` not found in {path}", ch.display())
                });
                assert!(
                    !body.trim().is_empty(),
                    "{}: anchor `{a}` in {path} is empty",
                    ch.display()
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 0, "the book includes no code at all");
}

#[test]
fn every_image_and_internal_link_resolves() {
    for ch in chapters() {
        let text = std::fs::read_to_string(&ch).unwrap();
        // markdown links and images: ](target)
        for part in text.split("](").skip(1) {
            let Some(end) = part.find(')') else { continue };
            let target = part[..end].split_whitespace().next().unwrap_or("");
            if target.starts_with("http")
                || target.starts_with('#')
                || target.starts_with("mailto:")
            {
                continue;
            }
            let file = target.split('#').next().unwrap();
            if file.is_empty() {
                continue;
            }
            let p = ch.parent().unwrap().join(file);
            assert!(
                p.exists(),
                "{}: link or image `{target}` does not exist",
                ch.display()
            );
        }
    }
}

#[test]
fn every_chapter_is_in_the_summary() {
    let summary = std::fs::read_to_string(book_dir().join("src/SUMMARY.md")).unwrap();
    for ch in chapters() {
        let name = ch.file_name().unwrap().to_string_lossy().to_string();
        if name == "SUMMARY.md" {
            continue;
        }
        assert!(
            summary.contains(&format!("({name})")),
            "{name} is not listed in SUMMARY.md"
        );
    }
}

#[test]
fn the_book_builds() {
    let out = std::env::temp_dir().join(format!("pathspace-book-{}", std::process::id()));
    let mut book = mdbook_driver::MDBook::load(book_dir()).expect("book.toml and SUMMARY.md load");
    book.config.build.build_dir = out.clone();
    book.build().expect("the book builds");
    assert!(out.join("index.html").exists() || out.join("html/index.html").exists());
    let _ = std::fs::remove_dir_all(&out);
}

/// The chapters of the papers' equations, in paper order (Pauly et al. eqs. 1-8 and Table 1,
/// Pegoraro et al. eqs. 1-9, BDPT's MIS, measuring).
const EQUATION_CHAPTERS: [&str; 18] = [
    "primer.md",
    "error-analysis.md",
    "conventions.md",
    "scenes.md",
    "envmap.md",
    "transport-equations.md",
    "phase-functions.md",
    "bsdf.md",
    "table1-homogeneous.md",
    "table1-inhomogeneous.md",
    "neumann-series.md",
    "path-space.md",
    "bdpt.md",
    "mlt.md",
    "smc.md",
    "smc-cache.md",
    "smc-estimators.md",
    "measuring.md",
];

/// Every chapter of an equation maps its symbols to code names in a table, and ends with a
/// "Check it yourself" section that names the exact test command.
#[test]
fn every_equation_chapter_has_a_symbol_table_and_a_check_it_yourself_section() {
    for name in EQUATION_CHAPTERS {
        let text = std::fs::read_to_string(book_dir().join("src").join(name)).unwrap();
        assert!(
            text.lines()
                .any(|l| l.starts_with("| symbol |") && l.contains("code")),
            "{name}: no table of symbols and code names"
        );
        let check = text
            .split("## Check it yourself")
            .nth(1)
            .unwrap_or_else(|| panic!("{name}: no 'Check it yourself' section"));
        assert!(
            check.contains("cargo test --release --test "),
            "{name}: 'Check it yourself' names no test command"
        );
    }
}

/// Markdown eats a backslash before punctuation before MathJax sees the formula: `\,` becomes a
/// comma, `\\` (a line break in `cases`) a single backslash, `\|` a bar, `\#` a `#` (a TeX
/// error). Inside `$$ ... $$` and
/// `\\( ... \\)`, `\\[ ... \\]` every such TeX command must be written with its backslash doubled.
#[test]
fn math_keeps_its_backslashes_through_markdown() {
    let mut bad = Vec::new();
    for ch in chapters() {
        let text = std::fs::read_to_string(&ch).unwrap();
        // drop fenced code: listings may contain anything
        let prose: String = text
            .split("```")
            .enumerate()
            .filter(|(i, _)| i % 2 == 0)
            .map(|(_, p)| p)
            .collect::<Vec<_>>()
            .join("\n");
        let mut segments = Vec::new();
        for (open, close) in [("$$", "$$"), ("\\\\(", "\\\\)"), ("\\\\[", "\\\\]")] {
            let mut rest = prose.as_str();
            while let Some(a) = rest.find(open) {
                let after = &rest[a + open.len()..];
                let Some(b) = after.find(close) else { break };
                segments.push(after[..b].to_string());
                rest = &after[b + close.len()..];
            }
        }
        for seg in segments {
            let bytes = seg.as_bytes();
            let mut i = 0;
            while i < bytes.len() {
                if bytes[i] == b'\\' {
                    let mut run = 0;
                    while i + run < bytes.len() && bytes[i + run] == b'\\' {
                        run += 1;
                    }
                    let next = bytes.get(i + run).copied().unwrap_or(b' ');
                    // one backslash before punctuation, two meaning a TeX line break, or four
                    // before a spacing mark (markdown leaves `\\,`: a line break and a comma)
                    let eaten = (run == 1 && b",;!{}|#%&_$".contains(&next))
                        || (run == 2 && !next.is_ascii_punctuation())
                        || (run == 4 && b",;:!".contains(&next))
                        || seg.contains('\t');
                    if eaten {
                        let s = i.saturating_sub(20);
                        let e = (i + 20).min(bytes.len());
                        bad.push(format!(
                            "{}: …{}…",
                            ch.file_name().unwrap().to_string_lossy(),
                            String::from_utf8_lossy(&bytes[s..e])
                        ));
                    }
                    i += run;
                } else {
                    i += 1;
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "TeX escapes markdown will eat:\n{}",
        bad.join("\n")
    );
}

/// Math that markdown strips or a reader never sees: a single-backslash `\(` in prose becomes a
/// plain parenthesis (the page shows "( \Delta = 1/8 )"), and a control character (a tab that
/// was once `\t` of `\tau`) shows as a gap. Code blocks and inline code are left out.
#[test]
fn prose_has_no_stripped_math_delimiters_and_no_control_characters() {
    let mut bad = Vec::new();
    for ch in chapters() {
        let name = ch.file_name().unwrap().to_string_lossy().to_string();
        let text = std::fs::read_to_string(&ch).unwrap();
        let mut in_code = false;
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("```") {
                in_code = !in_code;
            }
            if in_code {
                continue;
            }
            let outside_code: String = line.split('`').step_by(2).collect();
            let b = outside_code.as_bytes();
            for i in 0..b.len() {
                let single = b[i] == b'\\'
                    && matches!(b.get(i + 1), Some(b'(') | Some(b')'))
                    && (i == 0 || b[i - 1] != b'\\');
                if single {
                    bad.push(format!("{name}:{}: a single-backslash delimiter", n + 1));
                }
            }
            if outside_code.chars().any(|c| c.is_control()) {
                bad.push(format!("{name}:{}: a control character", n + 1));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "math a reader does not see:\n{}",
        bad.join("\n")
    );
}

/// A line of display math that starts like a markdown block (`+ `, `- `, `* `, `> `, `#`, `1. `)
/// is turned into a list, a quote or a heading before MathJax sees it, and the formula is lost
/// (the book's equation of transfer was, until `tests/repository/book_browser.rs` showed it): put the
/// operator at the end of the line before.
#[test]
fn display_math_has_no_line_that_markdown_takes_for_a_block() {
    let mut bad = Vec::new();
    for ch in chapters() {
        let text = std::fs::read_to_string(&ch).unwrap();
        for (k, prose) in text.split("```").enumerate() {
            if k % 2 == 1 {
                continue; // fenced code
            }
            for (open, close) in [("$$", "$$"), ("\\\\[", "\\\\]")] {
                let mut rest = prose;
                while let Some(a) = rest.find(open) {
                    let after = &rest[a + open.len()..];
                    let Some(b) = after.find(close) else { break };
                    for line in after[..b].lines().skip(1) {
                        let t = line.trim_start();
                        let digits = t.chars().take_while(|c| c.is_ascii_digit()).count();
                        let block = ["+ ", "- ", "* ", "> ", "#"]
                            .iter()
                            .any(|p| t.starts_with(p))
                            || (digits > 0
                                && (t[digits..].starts_with(". ")
                                    || t[digits..].starts_with(") ")));
                        if block {
                            bad.push(format!(
                                "{}: `{}`",
                                ch.file_name().unwrap().to_string_lossy(),
                                line.trim()
                            ));
                        }
                    }
                    rest = &after[b + close.len()..];
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "display math lines markdown reads as a list, quote or heading:\n{}",
        bad.join("\n")
    );
}

/// The rows of the book's key tables of the nested `[render.T]` tables: a table headed
/// `| key | default | meaning |` under a line that names `` `[render.T]` ``, as (chapter, T,
/// key, default cell).
fn nested_key_tables() -> Vec<(String, String, String, String)> {
    let mut rows = Vec::new();
    for path in chapters() {
        let chapter = path.file_name().unwrap().to_string_lossy().to_string();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if line.trim() != "| key | default | meaning |" {
                continue;
            }
            // the table it documents: the last `[render.T]` named in the lines just above
            let table = lines[i.saturating_sub(4)..i].iter().rev().find_map(|l| {
                let at = l.rfind("`[render.")?;
                let name = &l[at + "`[render.".len()..];
                Some(name[..name.find("]`")?].to_string())
            });
            let Some(table) = table else {
                continue;
            };
            for row in lines[i + 2..].iter().take_while(|l| l.starts_with('|')) {
                let cells: Vec<&str> = row.split('|').map(str::trim).collect();
                let key = cells[1].trim_matches('`').to_string();
                rows.push((chapter.clone(), table.clone(), key, cells[2].to_string()));
            }
        }
    }
    rows
}

/// A key table's default cell as the TOML value a scene would write (`1/32` as its value).
fn toml_value(cell: &str) -> Option<String> {
    let v = cell.trim_matches('`');
    let v = match v.split_once('/') {
        Some((a, b)) if !v.starts_with('"') => {
            (a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?).to_string()
        }
        _ => v.to_string(),
    };
    toml::from_str::<toml::Table>(&format!("v = {v}")).ok()?;
    Some(v)
}

/// The settings a `[render]` table added to the fog box loads to (the record of the options
/// given left out), or why it does not load.
fn settings_with(render: &str) -> Result<String, String> {
    use pathspace::integrator::settings::{load, RenderOptions};
    let text = format!("{}\n{render}", pathspace::scene::FOG_BOX);
    let (_, mut s) = load(&pathspace::scene::SceneSource::embedded("fog.toml", &text))
        .map_err(|e| e.to_string())?;
    s.given = RenderOptions::default();
    Ok(format!("{s:?}"))
}

/// The defaults of the nested tables are written once, in their settings' `Default`; the
/// book's key tables state them in the chapters, and this test keeps the two together: each
/// table lists every key of its schema, and writing a key's stated default into a scene leaves
/// every setting as the code's defaults make it (a default changed in the code, or in the book,
/// fails here).
#[test]
fn the_books_key_tables_state_the_schemas_defaults() {
    use pathspace::integrator::{mlt::MltOptions, pssmlt::PssmltOptions, smc::SmcOptions};
    let schema = |v: serde_json::Value| -> Vec<String> {
        let mut keys: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        keys
    };
    let tables = [
        (
            "mlt",
            schema(serde_json::to_value(MltOptions::default()).unwrap()),
        ),
        (
            "pssmlt",
            schema(serde_json::to_value(PssmltOptions::default()).unwrap()),
        ),
        (
            "smc",
            schema(serde_json::to_value(SmcOptions::default()).unwrap()),
        ),
    ];
    let rows = nested_key_tables();
    let defaults = settings_with("").unwrap();
    for (table, keys) in &tables {
        let mut listed: Vec<String> = rows
            .iter()
            .filter(|r| r.1 == *table)
            .map(|r| r.2.clone())
            .collect();
        listed.sort();
        assert_eq!(&listed, keys, "the book's key table of [render.{table}]");
    }
    for (chapter, table, key, cell) in &rows {
        let value = toml_value(cell).unwrap_or_else(|| {
            panic!("{chapter}: the default `{cell}` of [render.{table}] {key} is no TOML value")
        });
        let loaded = settings_with(&format!("[render.{table}]\n{key} = {value}\n"))
            .unwrap_or_else(|e| panic!("{chapter}: [render.{table}] {key} = {value}: {e}"));
        assert!(
            loaded == defaults,
            "{chapter}: the book states the default of [render.{table}] {key} as {cell}; the \
             code's is another"
        );
    }
    assert!(rows.len() >= 20, "only {} rows found", rows.len());
}
