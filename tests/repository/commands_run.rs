//! Every command the README and the book print runs, as printed, from a fresh clone's state:
//! each document's commands in document order, in a scratch directory holding only what a clone
//! holds that they read (`scenes/`, `assets/`, `tests/fixtures/`, the book's figure
//! directories; no `out/` unless a command creates it), with the built binary.
//!
//! What is run: every line of a `sh` code block (continuations joined, comments cut, `;` and
//! `&&` split, `for VAR in WORDS; do ... done` loops unrolled, `VAR=value` definitions skipped,
//! `?` in a file name matched as the shell would), and the `pathspace` commands of other code
//! blocks and of inline code (those `tests/repository/commands.rs` parses). Synopses (`SCENE`, `...`,
//! `[--flag]`, `A.exr`) are forms, not commands. A `pathspace` command runs with the long values
//! of [`REDUCED`] made small and [`ADDED`]'s flags; a shell command runs through `sh` when its
//! program is one of [`SHELL_PROGRAMS`]; paths under `/tmp/` go to the scratch directory's
//! `tmp/`. Every other command is in [`NOT_RUN`] with the reason. The test fails on a command
//! that fails (naming the document, the line, the command as printed and as run, the exit
//! code and the start of stderr; the document's later commands are not run, as they may read
//! what it did not write), on a command that is neither run nor listed, and on an entry of
//! the list that names no command any more.

use crate::common;

use clap::CommandFactory;
use common::docs::{command_part, documents, is_synopsis, joined_lines, words, PREFIXES};
use pathspace::cli::Cli;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The reductions, `(flag, value)`: a printed value larger than `value` runs as `value`, so that
/// the whole test takes about a minute on 2 cores. Resolutions are divided instead (see
/// [`RESOLUTION_DIVISOR`]). `--threads`, seeds, integrators, shards and everything else run as
/// printed.
const REDUCED: &[(&str, &str)] = &[
    ("--spp", "16"),
    ("--time", "1"),
    ("--budget", "0.5"),
    ("--runs", "2"),
    ("--checkpoints", "3"),
    ("--mutations-per-pixel", "4"),
    ("--mlt-bootstrap", "1024"),
    ("--guide-particles", "1000"),
    ("--adjoint-samples", "4"),
    ("--n", "2"), // rooms --n N: N x N rooms
];

/// The flags added, with [`REDUCED`]'s value, to a command of these subcommands that has none
/// where its parser accepts them with its other flags: the sizes the scene would give are long
/// too. `--guide-particles` only to a `render` that guides (`--guide`; it is refused without
/// guiding, and `converge` refuses it without a `+guide` integrator).
const ADDED: [(&str, &[&str]); 3] = [
    ("--spp", &["render", "reference"]),
    ("--mlt-bootstrap", &["render", "reference", "converge"]),
    ("--guide-particles", &["render"]),
];

/// Resolutions run at 1/`RESOLUTION_DIVISOR` of the printed ones per side (at least
/// [`MIN_SIDE`] pixels), in `--resolution` and in the scratch copies of the scenes (and
/// fixtures) alike: `reference` and `converge` (which read the scene's) write images of the
/// size `render` writes, images the documents compare stay of the same size and images of
/// different sizes stay different. A `render` of no TOML scene (the embedded fog box, 256x256,
/// or a Mitsuba XML scene) gets `--resolution` [`EMBEDDED_RESOLUTION`] reduced.
const RESOLUTION_DIVISOR: u32 = 8;
const MIN_SIDE: u32 = 4;
const EMBEDDED_RESOLUTION: (u32, u32) = (256, 256);

/// The MLT bootstrap of the scratch scenes (`[render.mlt] bootstrap`, added where a scene has
/// none): `--mlt-bootstrap`'s reduced value, for `converge`, which has no such flag.
const REDUCED_BOOTSTRAP: u32 = 1024;

/// A resolution reduced by [`RESOLUTION_DIVISOR`].
fn reduced_size((w, h): (u32, u32)) -> (u32, u32) {
    let side = |x: u32| (x / RESOLUTION_DIVISOR).max(MIN_SIDE);
    (side(w), side(h))
}

/// Paths under `/tmp/` run under the scratch directory's `tmp/`, so that runs share no files.
const TMP: &str = "/tmp/";

/// The shell programs run as printed (through `sh -c`, in the scratch directory).
const SHELL_PROGRAMS: [&str; 2] = ["mkdir", "sed"];

/// The commands deliberately not run, by how they begin (a `pathspace` command spelled
/// `pathspace ARGS` whatever its spelling in the document), and why.
const NOT_RUN: &[(&str, &str)] = &[
    (
        "pathspace render --resume long.checkpoint",
        "continues a render stopped by Ctrl-C (a finished render removes its checkpoint); \
         tests/spec/render/checkpoint.rs stops one with SIGINT and runs this very command",
    ),
    (
        "pathspace reference scenes/fog-box.toml --resume out/fog-ref.checkpoint",
        "continues a reference stopped by Ctrl-C (a finished one removes its checkpoint); \
         tests/spec/cli/reference.rs stops one with SIGINT and resumes it",
    ),
    (
        "cargo test --release --test oracles mlt_failures::experiment_multichain -- --ignored",
        "an experiment that prints a table (an ignored test, about a minute), not a check",
    ),
    (
        "cargo test",
        "the executable specification: CI runs all of it (`cargo test --release`)",
    ),
    ("cargo build --release", "builds the binary this test runs"),
    (
        "cargo install mdbook",
        "installs mdbook from crates.io; tests/repository/book.rs builds the book without it",
    ),
    (
        "cargo install",
        "installs into ~/.cargo/bin; this test runs the same build",
    ),
    (
        "mdbook serve",
        "a live server; tests/repository/book.rs builds the book and tests/repository/book_browser.rs serves it",
    ),
    (
        "cargo run --release --example build_book",
        "tests/repository/book.rs builds the book the same way",
    ),
    (
        "cargo run --release --example smc_experiment",
        "the SMC chapter's figure experiments (up to 16384 spp references and 1024 spp \
         studies of the full scenes, minutes to hours each); tests/smc_*.rs check the \
         estimators",
    ),
    (
        "seq 8 | parallel -S",
        "needs ssh hosts; scripts/test-parallel.sh runs shards with GNU parallel on this \
         machine in CI",
    ),
    (
        "scripts/slurm/render.sh",
        "needs a Slurm cluster; scripts/test-slurm.sh runs it on a one-node cluster in CI",
    ),
    (
        "scripts/shard-scale.py",
        "the shard-scaling measurement: full-size renders for minutes",
    ),
    (
        "book/figures.sh",
        "regenerates the book's figures (6 to 90 minutes each)",
    ),
    (
        "pathspace assignment check",
        "compiles the student copy and its graded tests (about a minute); \
         tests/assignments.rs runs `make` and `check`",
    ),
    (
        "pathspace assignment exercise",
        "judges studies of at least 3 runs, and the reduced studies here have 2; \
         course/src/exercise.rs grades synthetic studies",
    ),
    (
        "for n in 16 64 256 1024 4096; do for r in $(seq 1 32)",
        "160 renders for a figure's data; the command after the loop runs the same render",
    ),
    (
        "pathspace merge fog-?.exr -o fog.exr",
        "merges the 8 shards of the GNU parallel command above, which is not run",
    ),
    (
        "pathspace merge a.exr b.exr -o out.exr",
        "inline example in prose, of files no command writes; the merges of the shard \
         blocks (README, measuring.md) run",
    ),
    (
        "pathspace merge study-1 study-2 study-3 study-4 -o study",
        "inline example in prose, of the four shards of a study no command writes",
    ),
    (
        "python3 scripts/fuzz.py",
        "a fuzzing campaign of 20000 cases; .ci/run runs 500 cases of it",
    ),
    (
        "python3 -m venv .venv",
        "the Python package's install (packages from PyPI); .ci/run builds it in a venv and \
         runs its pytest suite",
    ),
    (
        ". .venv/bin/activate",
        "the Python package's install; .ci/run activates its own venv",
    ),
    (
        "pip install ./python",
        "builds the wheel with maturin (Rust and PyPI packages); .ci/run installs it and runs \
         python/tests",
    ),
];

/// What a command of a document does here.
#[derive(Debug, Clone)]
enum What {
    /// The binary with these arguments (the printed ones, before [`REDUCED`]).
    Pathspace(Vec<String>),
    /// A shell command line.
    Shell(String),
    /// Shell this test does not interpret (a nested loop, a variable it does not know).
    Unrunnable,
}

/// One command of a document: its line, the text as printed, and what it does.
#[derive(Debug, Clone)]
struct Cmd {
    line: usize,
    printed: String,
    what: What,
}

/// The shell languages of code blocks whose every line is a command.
const SHELL_LANGS: [&str; 3] = ["sh", "bash", "shell"];

/// The text before an unquoted ` #` (a shell comment).
fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let b = line.as_bytes();
    for (i, &c) in b.iter().enumerate() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, b'\'' | b'"') => quote = Some(c),
            (None, b'#') if i == 0 || b[i - 1] == b' ' => return line[..i].trim_end(),
            _ => {}
        }
    }
    line.trim_end()
}

/// The commands of a shell line: split at unquoted `;` and `&&`.
fn segments(line: &str) -> Vec<String> {
    let (mut out, mut start, mut quote) = (Vec::new(), 0, None);
    let b = line.as_bytes();
    let mut i = 0;
    while i < b.len() {
        match (quote, b[i]) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, c @ (b'\'' | b'"')) => quote = Some(c),
            (None, b';') => {
                out.push(&line[start..i]);
                start = i + 1;
            }
            (None, b'&') if b.get(i + 1) == Some(&b'&') => {
                out.push(&line[start..i]);
                start = i + 2;
                i += 1;
            }
            _ => {}
        }
        i += 1;
    }
    out.push(&line[start..]);
    out.into_iter()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect()
}

/// `NAME=value` (a shell variable definition, as `P=target/release/pathspace`).
fn is_definition(segment: &str) -> bool {
    let name = segment.split('=').next().unwrap_or_default();
    segment.contains('=')
        && !name.is_empty()
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The `pathspace` command of `text` (a segment or an inline code span), if it is one: its
/// arguments, `What::Unrunnable` where they use the shell, `None` for no command or a synopsis.
fn pathspace_command(text: &str, subcommands: &[String]) -> Option<(String, What)> {
    let text = text.trim().trim_start_matches("$ ");
    if text == "cargo run --release" {
        return Some((text.to_string(), What::Pathspace(Vec::new())));
    }
    let prefix = PREFIXES.iter().find(|p| text.starts_with(**p))?;
    let args = command_part(&text[prefix.len()..]);
    let printed = format!("{prefix}{args}");
    let Some(w) = words(args) else {
        return Some((printed, What::Unrunnable));
    };
    let first = w.first()?;
    if !subcommands.contains(first) && !first.starts_with('-') {
        return None; // prose naming the program
    }
    if is_synopsis(&w) {
        return None;
    }
    Some((printed, What::Pathspace(w)))
}

/// `for VAR in WORDS; do` with nothing after `do`: the variable and the words.
fn for_loop(line: &str) -> Option<(String, Vec<String>)> {
    let rest = line.strip_prefix("for ")?;
    let (head, tail) = rest.split_once("; do")?;
    if !tail.trim().is_empty() || head.contains('$') {
        return None;
    }
    let mut w = head.split_whitespace();
    let var = w.next()?.to_string();
    (w.next()? == "in").then_some(())?;
    Some((var, w.map(str::to_string).collect()))
}

/// Every command of a document, in order.
fn document_commands(text: &str, subcommands: &[String]) -> Vec<Cmd> {
    let lines = joined_lines(text);
    let mut out = Vec::new();
    let mut fence: Option<String> = None;
    let mut i = 0;
    while i < lines.len() {
        let (n, line) = (&lines[i].0, lines[i].1.as_str());
        i += 1;
        if let Some(lang) = line.strip_prefix("```") {
            fence = match fence {
                Some(_) => None,
                None => Some(lang.trim().to_string()),
            };
            continue;
        }
        match &fence {
            Some(lang) if SHELL_LANGS.contains(&lang.as_str()) => {
                let line = line.trim_start_matches("$ ");
                if line.starts_with("for ") {
                    let start = i;
                    while i < lines.len() && !lines[i].1.starts_with("done") {
                        i += 1;
                    }
                    let body = &lines[start..i];
                    i += 1;
                    match for_loop(strip_comment(line)) {
                        Some((var, values)) => {
                            for v in &values {
                                for (bn, bl) in body {
                                    let run = bl
                                        .replace(&format!("${{{var}}}"), v)
                                        .replace(&format!("${var}"), v);
                                    shell_line(*bn, bl, &run, subcommands, &mut out);
                                }
                            }
                        }
                        None => out.push(Cmd {
                            line: *n,
                            printed: strip_comment(line).to_string(),
                            what: What::Unrunnable,
                        }),
                    }
                    continue;
                }
                shell_line(*n, line, line, subcommands, &mut out);
            }
            Some(_) => {
                if let Some((printed, what)) = pathspace_command(line, subcommands) {
                    out.push(Cmd {
                        line: *n,
                        printed,
                        what,
                    });
                }
            }
            None => {
                for span in line.split('`').skip(1).step_by(2) {
                    let Some((printed, what)) = pathspace_command(span, subcommands) else {
                        continue;
                    };
                    let cmd = Cmd {
                        line: *n,
                        printed,
                        what,
                    };
                    // an inline span that only names a command (`pathspace info`, `diff
                    // --heatmap`) is prose; one with its arguments is run (as it is parsed)
                    if key(&cmd).split_whitespace().count() > 3 {
                        out.push(cmd);
                    }
                }
            }
        }
    }
    out
}

/// The commands of one line of a shell block (`run` is `printed` with a loop's variable set).
fn shell_line(n: usize, printed: &str, run: &str, subcommands: &[String], out: &mut Vec<Cmd>) {
    let printed = strip_comment(printed);
    let run = strip_comment(run);
    if printed.is_empty() {
        return;
    }
    let (ps, rs) = (segments(printed), segments(run));
    for (p, r) in ps.iter().zip(&rs) {
        if is_definition(p) {
            continue;
        }
        let what = match pathspace_command(r, subcommands) {
            Some((_, what)) => what,
            None if PREFIXES.iter().any(|pre| r.starts_with(pre)) => continue, // a synopsis
            None => What::Shell(r.clone()),
        };
        out.push(Cmd {
            line: n,
            printed: p.clone(),
            what,
        });
    }
}

/// How `NOT_RUN` names a command: `pathspace ARGS` for the binary's, whatever its spelling.
fn key(cmd: &Cmd) -> String {
    match PREFIXES.iter().find(|p| cmd.printed.starts_with(**p)) {
        Some(p) => format!("pathspace {}", &cmd.printed[p.len()..]),
        None => cmd.printed.clone(),
    }
}

/// A printed numeric value larger than the reduced one.
fn larger(printed: &str, reduced: &str) -> bool {
    matches!((printed.parse::<f64>(), reduced.parse::<f64>()), (Ok(p), Ok(r)) if p > r)
}

/// The arguments run for the printed ones: [`REDUCED`]'s values, resolutions reduced,
/// [`ADDED`]'s flags, `/tmp/` under the scratch directory. No subcommand is `render`, what the
/// binary does without one.
fn reduced(printed: &[String], scratch: &Path) -> Vec<String> {
    let mut args: Vec<String> = printed.to_vec();
    if args.is_empty() {
        args.push("render".into());
    }
    for i in 1..args.len() {
        if let Some((_, value)) = REDUCED.iter().find(|(flag, _)| *flag == args[i - 1]) {
            if larger(&args[i], value) {
                args[i] = value.to_string();
            }
        }
        if args[i - 1] == "--resolution" {
            if let Some((w, h)) = args[i].split_once('x') {
                let (w, h) = reduced_size((w.parse().unwrap(), h.parse().unwrap()));
                args[i] = format!("{w}x{h}");
            }
        }
    }
    let (w, h) = reduced_size(EMBEDDED_RESOLUTION);
    let embedded = format!("{w}x{h}");
    let toml_scene = args.get(1).is_some_and(|a| a.ends_with(".toml"));
    let resolution = (!toml_scene).then_some(("--resolution", &["render"][..]));
    for (flag, subcommands) in ADDED.into_iter().chain(resolution) {
        if !subcommands.contains(&args[0].as_str()) || args.iter().any(|a| a == flag) {
            continue;
        }
        // guide options without guiding are refused
        if flag.starts_with("--guide-") && !args.iter().any(|a| a == "--guide") {
            continue;
        }
        let value = match REDUCED.iter().find(|(f, _)| *f == flag) {
            Some((_, v)) => v.to_string(),
            None => embedded.clone(),
        };
        let mut with = args.clone();
        with.extend([flag.to_string(), value]);
        let argv = std::iter::once("pathspace".to_string()).chain(with.iter().cloned());
        if <Cli as clap::Parser>::try_parse_from(argv).is_ok() {
            args = with;
        }
    }
    args.iter().map(|a| in_scratch_tmp(a, scratch)).collect()
}

/// `text` with `/tmp/` paths under the scratch directory's `tmp/`.
fn in_scratch_tmp(text: &str, scratch: &Path) -> String {
    text.replace(TMP, &format!("{}/tmp/", scratch.display()))
}

/// A word with `?` matched against the files of its directory (as the shell would), sorted;
/// the word itself where nothing matches.
fn glob(word: &str, cwd: &Path) -> Vec<String> {
    if !word.contains('?') {
        return vec![word.to_string()];
    }
    let path = Path::new(word);
    let (dir, name) = (path.parent().unwrap_or(Path::new("")), path.file_name());
    let pattern: Vec<char> = name
        .map(|n| n.to_string_lossy().chars().collect())
        .unwrap_or_default();
    let mut found: Vec<String> = std::fs::read_dir(cwd.join(dir))
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| {
            let n: Vec<char> = n.chars().collect();
            n.len() == pattern.len() && n.iter().zip(&pattern).all(|(c, p)| p == &'?' || c == p)
        })
        .map(|n| dir.join(n).to_string_lossy().to_string())
        .collect();
    found.sort();
    if found.is_empty() {
        found.push(word.to_string());
    }
    found
}

/// The directories of the repository a fresh clone gives the commands: copied with their
/// files (scene files with the camera's resolution reduced), or created empty (directories
/// the commands write into).
const COPIED: [&str; 3] = ["scenes", "assets", "tests/fixtures"];
const CREATED: [&str; 1] = ["book/src/figures"];

/// A copy of `from` in `to`, `.toml` files reduced ([`reduced_scene`]).
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if e.file_type().unwrap().is_dir() {
            copy_tree(&src, &dst);
        } else if src.extension().is_some_and(|x| x == "toml") {
            let text = std::fs::read_to_string(&src).unwrap();
            std::fs::write(&dst, reduced_scene(&text)).unwrap();
        } else {
            std::fs::copy(&src, &dst).unwrap();
        }
    }
}

/// A scene's text with its camera's `resolution = [W, H]` reduced ([`reduced_size`]) and its
/// MLT bootstrap set to [`REDUCED_BOOTSTRAP`] (a `[render.mlt]` table added where it has none).
fn reduced_scene(text: &str) -> String {
    let mut section = String::new();
    let mut out = String::new();
    let mut has_mlt = false;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            section = t.trim_matches(|c| c == '[' || c == ']').trim().to_string();
            if section == "render.mlt" {
                has_mlt = true;
                out.push_str(&format!("{line}\nbootstrap = {REDUCED_BOOTSTRAP}\n"));
                continue;
            }
        }
        let key = t.split('=').next().unwrap_or_default().trim();
        if section == "camera" && key == "resolution" {
            let value = t.split_once('=').unwrap().1;
            let sides: Vec<u32> = value
                .trim_matches(|c: char| c == '[' || c == ']' || c.is_whitespace())
                .split(',')
                .map(|x| {
                    x.trim()
                        .parse()
                        .expect("a camera resolution [W, H] on one line")
                })
                .collect();
            let (w, h) = reduced_size((sides[0], sides[1]));
            out.push_str(&format!("resolution = [{w}, {h}]\n"));
        } else if section == "render.mlt" && key == "bootstrap" {
            continue;
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    if !has_mlt && text.contains("[camera") {
        out.push_str(&format!(
            "\n[render.mlt]\nbootstrap = {REDUCED_BOOTSTRAP}\n"
        ));
    }
    out
}

/// A fresh scratch directory for `doc`, as a clone gives it (see [`COPIED`]).
fn fresh_clone(doc: &Path) -> PathBuf {
    let name = doc.file_stem().unwrap().to_string_lossy().to_string();
    let dir = common::cli::scratch("commands-run", &name);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for d in COPIED {
        copy_tree(&root.join(d), &dir.join(d));
    }
    for d in CREATED {
        for e in std::fs::read_dir(root.join(d)).unwrap() {
            let e = e.unwrap();
            if e.file_type().unwrap().is_dir() {
                std::fs::create_dir_all(dir.join(d).join(e.file_name())).unwrap();
            }
        }
    }
    std::fs::create_dir_all(dir.join("tmp")).unwrap();
    dir
}

/// What happened to one document's commands.
#[derive(Default)]
struct Outcome {
    ran: usize,
    not_run: Vec<String>,
    failures: Vec<String>,
    used: Vec<&'static str>,
}

/// Runs `doc`'s commands in order in a fresh scratch directory; stops at the first failure
/// (the later commands may read what it did not write).
fn run_document(doc: &Path, subcommands: &[String]) -> Outcome {
    let name = doc
        .strip_prefix(env!("CARGO_MANIFEST_DIR"))
        .unwrap_or(doc)
        .display()
        .to_string();
    let text = std::fs::read_to_string(doc).unwrap();
    let cmds = document_commands(&text, subcommands);
    let mut outcome = Outcome::default();
    if cmds.is_empty() {
        return outcome;
    }
    let scratch = fresh_clone(doc);
    let started = Instant::now();
    for cmd in &cmds {
        let k = key(cmd);
        if let Some((pattern, reason)) = NOT_RUN.iter().find(|(p, _)| k.starts_with(p)) {
            outcome.used.push(pattern);
            outcome
                .not_run
                .push(format!("{name}:{}: `{}`: {reason}", cmd.line, cmd.printed));
            continue;
        }
        let (program, args): (String, Vec<String>) = match &cmd.what {
            What::Pathspace(printed) => (
                env!("CARGO_BIN_EXE_pathspace").to_string(),
                reduced(printed, &scratch)
                    .iter()
                    .flat_map(|a| glob(a, &scratch))
                    .collect(),
            ),
            What::Shell(line)
                if SHELL_PROGRAMS.contains(&line.split_whitespace().next().unwrap_or("")) =>
            {
                (
                    "sh".into(),
                    vec!["-c".into(), in_scratch_tmp(line, &scratch)],
                )
            }
            _ => {
                outcome.failures.push(format!(
                    "{name}:{}: `{}` is neither run nor listed in NOT_RUN (tests/repository/commands_run.rs)",
                    cmd.line, cmd.printed
                ));
                continue;
            }
        };
        let t0 = Instant::now();
        let out = Command::new(&program)
            .args(&args)
            .current_dir(&scratch)
            .output()
            .expect("the command starts");
        outcome.ran += 1;
        eprintln!(
            "{name}:{}: {:.1} s: {}",
            cmd.line,
            t0.elapsed().as_secs_f64(),
            cmd.printed
        );
        if !out.status.success() {
            let stderr = String::from_utf8_lossy(&out.stderr);
            let head: Vec<&str> = stderr.lines().take(12).collect();
            outcome.failures.push(format!(
                "{name}:{}: `{}`\n  run as: {program} {}\n  in: {}\n  exit code: {:?}\n  stderr:\n    {}",
                cmd.line,
                cmd.printed,
                args.join(" "),
                scratch.display(),
                out.status.code(),
                head.join("\n    ")
            ));
            break;
        }
    }
    eprintln!("{name}: {:.1} s", started.elapsed().as_secs_f64());
    outcome
}

#[test]
fn every_command_in_the_readme_and_the_book_runs() {
    let subcommands: Vec<String> = Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    assert!(REDUCED.contains(&("--mlt-bootstrap", REDUCED_BOOTSTRAP.to_string().as_str())));
    let docs = documents();
    // two documents at a time: each command uses every core only part of its time
    let next = std::sync::atomic::AtomicUsize::new(0);
    let outcomes = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(doc) = docs.get(i) else { break };
                let o = run_document(doc, &subcommands);
                outcomes.lock().unwrap().push((i, o));
            });
        }
    });
    let mut outcomes = outcomes.into_inner().unwrap();
    outcomes.sort_by_key(|(i, _)| *i);
    let ran: usize = outcomes.iter().map(|(_, o)| o.ran).sum();
    let not_run: Vec<&String> = outcomes.iter().flat_map(|(_, o)| &o.not_run).collect();
    let failures: Vec<&String> = outcomes.iter().flat_map(|(_, o)| &o.failures).collect();
    let used: Vec<&str> = outcomes.iter().flat_map(|(_, o)| o.used.clone()).collect();
    let stale: Vec<&str> = NOT_RUN
        .iter()
        .map(|(p, _)| *p)
        .filter(|p| !used.contains(p))
        .collect();
    eprintln!(
        "{ran} commands run; {} deliberately not run:",
        not_run.len()
    );
    for n in &not_run {
        eprintln!("  {n}");
    }
    assert!(
        failures.is_empty(),
        "{} commands fail:\n\n{}",
        failures.len(),
        failures
            .iter()
            .map(|f| f.as_str())
            .collect::<Vec<_>>()
            .join("\n\n")
    );
    assert!(ran >= 60, "only {ran} commands run: the extraction broke");
    assert!(
        stale.is_empty(),
        "NOT_RUN entries that name no command of the documents: {stale:?}"
    );
}
