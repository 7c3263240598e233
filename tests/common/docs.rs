//! The commands the README and the book print, as text: the documents, the spellings of the
//! binary, shell words, continuation lines and comments. `tests/repository/commands.rs` parses these
//! commands with the CLI's parser; `tests/repository/commands_run.rs` runs them.

use std::path::{Path, PathBuf};

/// The spellings of the binary the documents use, each followed by the arguments.
pub const PREFIXES: [&str; 5] = [
    "cargo run --release -- ",
    "./target/release/pathspace ",
    "target/release/pathspace ",
    "$P ",
    "pathspace ",
];

pub fn documents() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut docs = vec![root.join("README.md")];
    let mut chapters: Vec<PathBuf> = std::fs::read_dir(root.join("book/src"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    chapters.sort();
    docs.extend(chapters);
    docs
}

/// A synopsis rather than a command: `...` (or `…`), `[optional parts]`, or a placeholder in
/// capitals (`SCENE`, `N`, `A.exr`) where a value belongs.
pub fn is_synopsis(words: &[String]) -> bool {
    let placeholder = |w: &str| {
        w.chars().any(|c| c.is_ascii_uppercase())
            && w.chars()
                .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
    };
    words.iter().any(|w| {
        w.contains("...")
            || w.contains('…')
            || w.starts_with('[')
            || placeholder(w)
            || w.split_once('.').is_some_and(|(stem, _)| placeholder(stem))
    })
}

/// Shell words of `line`, with single and double quotes; None where the line uses the shell
/// beyond words (a variable other than `$P`, a substitution, a glob), which it cannot parse.
pub fn words(line: &str) -> Option<Vec<String>> {
    let (mut out, mut word, mut quote, mut any) = (Vec::new(), String::new(), None, false);
    for c in line.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => word.push(c),
            (None, '\'' | '"') => (quote, any) = (Some(c), true),
            (None, '$' | '`' | '*' | '{' | '<') => return None,
            (None, c) if c.is_whitespace() => {
                if any || !word.is_empty() {
                    out.push(std::mem::take(&mut word));
                }
                any = false;
            }
            (None, c) => word.push(c),
        }
    }
    if any || !word.is_empty() {
        out.push(word);
    }
    Some(out)
}

/// The command of a shell line: continuation lines joined by the caller, a trailing comment,
/// a pipe, a redirection or a second command cut off.
pub fn command_part(line: &str) -> &str {
    let mut end = line.len();
    for cut in [" #", " |", " >", " 2>", " &&", ";"] {
        if let Some(i) = line.find(cut) {
            end = end.min(i);
        }
    }
    line[..end].trim()
}

/// The lines of `text` with shell continuations (`\` at the end) joined, by first line number.
pub fn joined_lines(text: &str) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = Vec::new();
    let mut acc: Option<(usize, String)> = None;
    for (i, raw) in text.lines().enumerate() {
        let (n, line) = match acc.take() {
            Some((n, head)) => (n, format!("{head} {}", raw.trim())),
            None => (i + 1, raw.trim().to_string()),
        };
        match line.strip_suffix('\\') {
            Some(head) => acc = Some((n, head.trim_end().to_string())),
            None => out.push((n, line)),
        }
    }
    out
}

/// Every command of `text` after one of [`PREFIXES`], in a whole line or an inline code span,
/// as (line number, arguments).
pub fn commands(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (n, line) in joined_lines(text) {
        let spans: Vec<&str> = if line.contains('`') {
            line.split('`').skip(1).step_by(2).collect()
        } else {
            vec![line.as_str()]
        };
        let inline = spans.len() > 1 || line.contains('`');
        for span in spans {
            let span = span.trim_start_matches("$ ");
            if let Some(args) = PREFIXES.iter().find_map(|p| span.strip_prefix(p)) {
                let args = command_part(args);
                // inline code that only names a command (`pathspace info`, `diff --heatmap`)
                // is prose; an inline command with its arguments is checked like a block's
                if !inline || args.split_whitespace().count() >= 3 {
                    out.push((n, args.to_string()));
                }
            }
        }
    }
    out
}
