//! `pathspace reference` is `render` with other defaults, so `render`'s guarantees hold for it:
//! a bad `-o` and a render above `--max-memory` are refused before any work, a signal stops it
//! after the pass in flight with the image and a checkpoint written (exit 128 + signal),
//! `--resume` gives the uninterrupted reference bit for bit, and references of different seeds
//! record their options and streams, so that `merge` takes them without `--force`.
//! Book: "Measuring a renderer", sections "The reference" and "Interrupted renders".

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const FOG_BOX: &str = include_str!("../../../scenes/fog-box.toml");

/// A fresh scratch directory holding `scene.toml`: the fog box at `width`x`width`.
fn scratch(name: &str, width: u32) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pathspace-ref-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let res = format!("resolution = [{width}, {width}]");
    let text = FOG_BOX.replace("resolution = [256, 256]", &res);
    assert!(text.contains(&res), "the fog box's resolution line moved");
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    dir
}

/// `pathspace reference DIR/scene.toml --threads 2 ARGS`, stdout discarded, stderr piped.
fn reference(dir: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_pathspace"));
    c.arg("reference")
        .arg(dir.join("scene.toml"))
        .args(["--threads", "2"])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).to_string()
}

#[test]
fn a_bad_output_is_refused_before_any_work() {
    let dir = scratch("output", 16);
    let missing = dir.join("no-such-dir").join("ref.exr");
    let png = dir.join("ref.png");
    for (o, says) in [(&missing, "does not exist"), (&png, "name it *.exr")] {
        let out = reference(&dir, &["--spp", "64", "-o", o.to_str().unwrap()])
            .output()
            .unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(says), "{err}");
        assert!(!o.exists(), "{} was written", o.display());
    }
}

#[test]
fn an_over_large_camera_is_refused_by_max_memory_with_the_figure() {
    let dir = scratch("memory", 16384);
    let out = reference(&dir, &["--max-memory", "1"]).output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("GiB"), "no figure: {err}");
    assert!(err.contains("1.0 GiB") || err.contains("1 GiB"), "{err}");
    assert!(err.contains("film"), "the parts are not named: {err}");
    assert!(!dir.join("scene-ref.exr").exists());
}

/// Waits for the first checkpoint of an endless reference into `exr`, then sends SIGINT.
fn interrupt(dir: &Path, exr: &Path) -> Output {
    let o = exr.to_str().unwrap();
    let args = [
        "--spp",
        "1000000",
        "--seed",
        "3",
        "--checkpoint",
        "0",
        "-o",
        o,
    ];
    let child = reference(dir, &args).spawn().unwrap();
    while !exr.with_extension("checkpoint").exists() {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .unwrap()
        .success());
    child.wait_with_output().unwrap()
}

#[test]
fn sigint_keeps_the_samples_and_resume_gives_the_uninterrupted_reference() {
    let dir = scratch("sigint", 24);
    let exr = dir.join("part.exr");
    let out = interrupt(&dir, &exr);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("stopped by SIGINT"), "{err}");
    assert!(err.contains("part.checkpoint"), "{err}");
    let (_, meta) = pathspace::image_io::read_exr(&exr).unwrap();
    assert_eq!(meta.get("complete"), Some("false"));
    assert_eq!(meta.get("reference"), Some("true"));
    let spp: u64 = meta.get("spp").unwrap().parse().unwrap();
    assert!(spp > 0, "no pass was kept");

    let n = (spp + 8).to_string();
    let ckpt = exr.with_extension("checkpoint");
    let o = exr.to_str().unwrap();
    let resume = ["--resume", ckpt.to_str().unwrap()];
    // the checkpoint is read: another seed's reference does not continue it
    let out = reference(&dir, &["--spp", &n, "--seed", "4", "-o", o])
        .args(resume)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let common = ["--spp", &n, "--seed", "3", "--reproducible"];
    let out = reference(&dir, &common)
        .args(["-o", o])
        .args(resume)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let whole = dir.join("whole.exr");
    let out = reference(&dir, &common)
        .args(["-o", whole.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let read = |p: &Path| std::fs::read(p).unwrap();
    assert!(read(&exr) == read(&whole), "the resumed reference differs");
}

#[test]
fn references_of_different_seeds_merge_without_force() {
    let dir = scratch("merge", 16);
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    for (seed, exr) in [("1", &a), ("2", &b)] {
        let out = reference(&dir, &["--spp", "4", "--seed", seed])
            .args(["-o", exr.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        let (_, meta) = pathspace::image_io::read_exr(exr).unwrap();
        assert!(meta.get("render_options").is_some(), "no render_options");
    }
    let merged = dir.join("merged.exr");
    let out = Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .args(["merge", a.to_str().unwrap(), b.to_str().unwrap()])
        .args(["-o", merged.to_str().unwrap()])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains("warning"), "{err}");
    let (_, meta) = pathspace::image_io::read_exr(&merged).unwrap();
    assert_eq!(meta.get("spp"), Some("8"));
}

/// A scene's guide and adjoint image are settings for the methods a reference judges: the
/// reference renders with plain sampling whatever the file says, and records that it did.
#[test]
fn a_reference_ignores_the_scenes_guide_and_adjoint_image() {
    let dir = scratch("guided", 8);
    let text = std::fs::read_to_string(dir.join("scene.toml")).unwrap();
    let guided = text.replacen(
        "integrator = \"path\"",
        "integrator = \"bdpt\"\nadjoint_image = true",
        1,
    ) + "\n[render.guide]\nvertices = \"surface\"\n";
    assert!(
        guided.contains("adjoint_image = true"),
        "the fog box's integrator line moved"
    );
    std::fs::write(dir.join("scene.toml"), guided).unwrap();
    let exr = dir.join("ref.exr");
    let out = reference(&dir, &["--spp", "4", "-o", exr.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let (_, meta) = pathspace::image_io::read_exr(&exr).unwrap();
    let options = meta.get("render_options").unwrap();
    assert!(options.contains("adjoint_image = false"), "{options}");
    assert!(options.contains("vertices = \"off\""), "{options}");
}

/// `converge` renders at the scene's resolution: a line above `--max-memory` is refused with
/// the figure before any run (the reference here is an 8x8 render of the same scene file, so
/// the scene-hash check lets it through).
#[test]
fn converge_refuses_a_line_above_max_memory_before_its_runs() {
    let dir = scratch("converge-memory", 16384);
    let scene = dir.join("scene.toml");
    let reference = dir.join("ref.exr");
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_pathspace"))
            .args(args)
            .output()
            .unwrap()
    };
    let (s, r) = (scene.to_str().unwrap(), reference.to_str().unwrap());
    let out = run(&["render", s, "--resolution", "8x8", "--spp", "1", "-o", r]);
    assert!(out.status.success(), "{}", stderr(&out));
    let charts = dir.join("charts");
    let out = run(&[
        "converge",
        s,
        "--reference",
        r,
        "--integrators",
        "path",
        "--budget",
        "1",
        "--runs",
        "1",
        "--max-memory",
        "1",
        "-o",
        charts.to_str().unwrap(),
    ]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("needs about 44 GiB"), "{err}");
    assert!(!charts.exists(), "converge ran before refusing");
}
