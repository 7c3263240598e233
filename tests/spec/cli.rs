//! What a newcomer meets around a render: `pathspace` alone prints a short usage (it starts no
//! render), a render whose stderr is a file or a pipe (a batch job's log) writes progress lines
//! rather than a bar it cannot draw, and `--resolution` is taken by every command that renders
//! a scene (`render`, `reference`, `converge`).
//! Book: "Measuring a renderer", sections "The reference" and "Interrupted renders".

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const FOG_BOX: &str = include_str!("../../scenes/fog-box.toml");

/// A fresh directory holding `fog-box.toml`.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pathspace-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("fog-box.toml"), FOG_BOX).unwrap();
    dir
}

/// `pathspace ARGS` in `dir`, stdout and stderr piped (so stderr is no terminal).
fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).to_string()
}

#[test]
fn pathspace_alone_prints_usage_and_renders_nothing() {
    let dir = scratch("bare");
    let out = run(&dir, &[]);
    let usage = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(usage.contains("pathspace render"), "{usage}");
    assert!(usage.contains("--help"), "{usage}");
    let written: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(
        written.len(),
        1,
        "a bare `pathspace` wrote files: {written:?}"
    );
}

/// Progress in a pipe: one line after the first pass and one after the last (the passes
/// between fall within the interval), each with the samples done of the target.
#[test]
fn a_render_into_a_pipe_writes_progress_lines() {
    let dir = scratch("log");
    let args = [
        "render",
        "fog-box.toml",
        "--resolution",
        "16x16",
        "--spp",
        "12",
    ];
    let out = run(&dir, &args);
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("render: ")).collect();
    assert!(
        lines.first().is_some_and(|l| l.contains("4/12 spp")),
        "{err}"
    );
    assert!(
        lines.last().is_some_and(|l| l.contains("12/12 spp")),
        "{err}"
    );
    assert_eq!(lines.len(), 2, "{err}");
    assert!(
        !err.contains('\r') && !err.contains('\u{1b}'),
        "a bar's control codes: {err}"
    );
}

/// `reference --resolution` renders at that size, and `converge --resolution` compares a
/// render of that size with it.
#[test]
fn reference_and_converge_take_resolution() {
    let dir = scratch("resolution");
    let size = ["--resolution", "12x8"];
    let out = run(
        &dir,
        &[
            &["reference", "fog-box.toml", "--spp", "4", "-o", "ref.exr"][..],
            &size,
        ]
        .concat(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let (img, _) = pathspace::image_io::read_exr(&dir.join("ref.exr")).unwrap();
    assert_eq!((img.width, img.height), (12, 8));
    let study = [
        "converge",
        "fog-box.toml",
        "--reference",
        "ref.exr",
        "--budget",
        "0.2",
        "--checkpoints",
        "2",
        "-o",
        "study",
    ];
    let out = run(&dir, &[&study[..], &size].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(dir.join("study/convergence.csv").exists());
    let out = run(&dir, &study);
    assert!(
        !out.status.success(),
        "converge at the scene's 256x256 against a 12x8 reference"
    );
}

/// `--threads` far beyond any machine is refused at once, with the bound and the cores.
#[test]
fn a_thread_count_beyond_reason_is_refused_before_any_work() {
    let dir = scratch("threads");
    for command in [
        &["render", "fog-box.toml"][..],
        &["reference", "fog-box.toml"],
    ] {
        let out = run(&dir, &[command, &["--threads", "100000"]].concat());
        let err = text(&out.stderr);
        assert!(!out.status.success(), "{err}");
        assert!(err.contains("--threads 100000: at most 1024"), "{err}");
    }
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "a refused render wrote files"
    );
}

/// What a file holds reaches the terminal escaped and cut: an escape sequence in an EXR
/// attribute (one that would retitle the window) is printed as `\u{1b}`, and a value of
/// 100,000 characters as its start and end.
#[test]
fn strings_from_files_reach_the_terminal_escaped_and_cut() {
    use pathspace::image_io::{self, Image, ImageMeta};
    let dir = scratch("escape");
    let mut meta = ImageMeta::default();
    let hostile = format!("\u{1b}]0;PWNED\u{7}{}", "x".repeat(100_000));
    meta.set("scene", &hostile)
        .set("scene_hash", "0000000000000000");
    let img = Image::new(4, 4);
    image_io::write_exr(&dir.join("ref.exr"), &img, &meta).unwrap();
    let out = run(
        &dir,
        &[
            "converge",
            "fog-box.toml",
            "--reference",
            "ref.exr",
            "--budget",
            "1",
        ],
    );
    let err = text(&out.stderr);
    assert!(err.contains("reference of another scene"), "{err}");
    assert!(
        !err.contains('\u{1b}') && !err.contains('\u{7}'),
        "raw control codes: {err}"
    );
    assert!(err.contains("\\u{1b}]0;PWNED\\u{7}"), "{err}");
    assert!(
        err.len() < 5_000 && err.contains("characters left out"),
        "{} bytes",
        err.len()
    );
    let kept = pathspace::cli::printable("line one\n\ttabbed line two");
    assert_eq!(kept, "line one\n\ttabbed line two");
}

/// Numbers from the command line are echoed compactly: `--time 1e-300` is not printed as 300
/// digits, and a refused `--checkpoint -1e-300` names its value in scientific notation.
#[test]
fn tiny_and_huge_numbers_are_echoed_compactly() {
    let dir = scratch("numbers");
    let base = ["render", "fog-box.toml", "--resolution", "4x4"];
    let out = run(&dir, &[&base[..], &["--time", "1e-300"]].concat());
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("of the 1e-300 s of --time"), "{err}");
    let out = run(&dir, &[&base[..], &["--checkpoint=-1e-300"]].concat());
    let err = text(&out.stderr);
    assert!(err.contains("--checkpoint -1e-300 must be"), "{err}");
    assert!(err.lines().all(|l| l.len() < 200), "{err}");
}

/// Channel names are text from a file too: `diff` lists a hostile one escaped.
#[test]
fn diff_lists_hostile_channel_names_escaped() {
    use pathspace::image_io::{self, Channel, Image, ImageMeta};
    let dir = scratch("channels");
    let img = Image::new(2, 2);
    let evil = Channel {
        name: "\u{1b}]0;PWNED\u{7}.R".into(),
        values: vec![0.0; 4],
    };
    let path = dir.join("a.exr");
    image_io::write_exr_channels(&path, &img, &[evil], &ImageMeta::default()).unwrap();
    let out = run(&dir, &["diff", "a.exr", "a.exr"]);
    let said = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(said.contains("layers A"), "{said}");
    assert!(
        !said.contains('\u{1b}') && said.contains("\\u{1b}]0;PWNED"),
        "{said}"
    );
}

// The modules of `src/cli/` (the layout: tests/repository/index.rs).
mod display;
mod reference;
