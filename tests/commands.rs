//! The commands the README and the book show are commands the CLI takes: every `pathspace ...`
//! line (also written `cargo run --release -- ...`, `./target/release/pathspace ...` or `$P ...`
//! with `P=target/release/pathspace`), in code blocks and in inline code, is parsed by the
//! command line's own parser. A renamed flag or subcommand turns this red before a reader finds
//! the stale command.

use clap::{CommandFactory, Parser};
use pathspace::cli::Cli;
use std::path::{Path, PathBuf};

/// The spellings of the binary the documents use, each followed by the arguments.
const PREFIXES: [&str; 5] = [
    "cargo run --release -- ",
    "./target/release/pathspace ",
    "target/release/pathspace ",
    "$P ",
    "pathspace ",
];

fn documents() -> Vec<PathBuf> {
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

/// A synopsis rather than a command: `...`, `[optional parts]`, or a placeholder in capitals
/// (`SCENE`, `N`) where a value belongs.
fn is_synopsis(words: &[String]) -> bool {
    words.iter().any(|w| {
        w.contains("...")
            || w.starts_with('[')
            || (w.chars().any(|c| c.is_ascii_uppercase())
                && w.chars()
                    .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_'))
    })
}

/// Shell words of `line`, with single and double quotes; None where the line uses the shell
/// beyond words (a variable other than `$P`, a substitution, a glob), which it cannot parse.
fn words(line: &str) -> Option<Vec<String>> {
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
fn command_part(line: &str) -> &str {
    let mut end = line.len();
    for cut in [" #", " |", " >", " 2>", " &&", ";"] {
        if let Some(i) = line.find(cut) {
            end = end.min(i);
        }
    }
    line[..end].trim()
}

/// The lines of `text` with shell continuations (`\` at the end) joined, by first line number.
fn joined_lines(text: &str) -> Vec<(usize, String)> {
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
fn commands(text: &str) -> Vec<(usize, String)> {
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

#[test]
fn every_command_in_the_readme_and_the_book_parses() {
    let subcommands: Vec<String> = Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    let (mut checked, mut failures) = (0, Vec::new());
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        for (line, args) in commands(&text) {
            let Some(words) = words(&args) else { continue };
            // prose that merely names the program ("pathspace is ...") is no command
            let Some(sub) = words.first() else { continue };
            if is_synopsis(&words) {
                continue;
            }
            if !subcommands.contains(sub) && !sub.starts_with('-') {
                continue;
            }
            checked += 1;
            let argv = std::iter::once("pathspace".to_string()).chain(words);
            let parsed = Cli::try_parse_from(argv)
                .map(|_| ())
                .or_else(|e| match e.kind() {
                    clap::error::ErrorKind::DisplayHelp
                    | clap::error::ErrorKind::DisplayVersion => Ok(()),
                    _ => Err(e),
                });
            if let Err(e) = parsed {
                let first = e.to_string().lines().next().unwrap_or_default().to_string();
                failures.push(format!("{}:{line}: `{args}`: {first}", doc.display()));
            }
        }
    }
    eprintln!("{checked} commands checked");
    assert!(
        checked >= 60,
        "only {checked} commands found: the extraction broke"
    );
    assert!(
        failures.is_empty(),
        "{} commands do not parse:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
