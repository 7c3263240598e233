//! Writes that cannot destroy: outputs that cannot be written are refused before the render
//! starts, a failed write is an error with a nonzero exit, and it leaves an earlier file at the
//! path as it was (images go to a temporary file beside the target, renamed once complete).

use std::path::Path;
use std::process::{Command, Output};

use crate::common;
use common::cli::{pathspace, scratch, stderr};

/// The prefix of this file's scratch directories.
const GROUP: &str = "writes";

/// A quick render of the embedded fog box with `extra` options.
fn render(extra: &[&str]) -> Output {
    let mut args = vec!["render", "--resolution", "8x8", "--threads", "1"];
    if !extra.contains(&"--spp") {
        args.extend_from_slice(&["--spp", "1"]);
    }
    args.extend_from_slice(extra);
    pathspace(&args)
}

#[test]
fn outputs_that_cannot_be_written_are_refused_before_the_render() {
    let dir = scratch(GROUP, "refused");
    let missing = dir.join("no-such-dir").join("x.exr");
    let out = render(&["-o", missing.to_str().unwrap(), "--spp", "100000"]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("does not exist"), "{e}");
    // refused before the work: no progress, no summary (100000 spp would take minutes)
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let wrong = dir.join("x.png");
    let out = render(&["-o", wrong.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("name it *.exr"), "{}", stderr(&out));
    let png = dir.join("x.jpg");
    let exr = dir.join("x.exr");
    let out = render(&["-o", exr.to_str().unwrap(), "--png", png.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("name it *.png"), "{}", stderr(&out));
    assert!(
        !exr.exists(),
        "nothing is written when an output is refused"
    );
}

/// Mounts a tmpfs of `size` at `dir` (the test runs as root, as CI does); false where it
/// cannot, and the caller skips its case, saying so.
fn mount_tmpfs(dir: &Path, options: &str) -> bool {
    std::fs::create_dir_all(dir).unwrap();
    Command::new("mount")
        .args(["-t", "tmpfs", "-o", options, "none", dir.to_str().unwrap()])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// A write that fails half-way (a full file system: a 64 KiB tmpfs that holds a 16x16 image
/// but not a 128x128 one) fails the command and leaves the earlier file as it was, with no
/// temporary file left behind.
#[test]
fn a_failed_write_keeps_the_earlier_file_and_fails_the_command() {
    let dir = scratch(GROUP, "kept");
    let small = dir.join("small");
    if !mount_tmpfs(&small, "size=64k") {
        eprintln!("skipped: this test cannot mount a tmpfs here");
        return;
    }
    let exr = small.join("img.exr");
    let e = exr.to_str().unwrap();
    let at = |size| pathspace(&["render", "--resolution", size, "--spp", "1", "-o", e]);
    let first = at("16x16");
    let old = std::fs::read(&exr);
    let second = at("128x128");
    let left: Vec<_> = std::fs::read_dir(&small)
        .unwrap()
        .map(|f| f.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    let now = std::fs::read(&exr);
    let _ = Command::new("umount").arg(&small).status();
    assert!(first.status.success(), "{}", stderr(&first));
    assert!(!second.status.success(), "a failed write must not exit 0");
    assert!(stderr(&second).contains("img.exr"), "{}", stderr(&second));
    assert!(now.unwrap() == old.unwrap(), "the earlier EXR was damaged");
    assert!(left.is_empty(), "{left:?}");
}

/// Two renders given the same `-o` at the same time both succeed, and the file is one of
/// them whole (each write has a temporary file of its own, renamed over the target).
#[test]
fn concurrent_renders_to_one_output_both_succeed() {
    let dir = scratch(GROUP, "concurrent");
    let exr = dir.join("same.exr");
    let e = exr.to_str().unwrap();
    for round in 0..8 {
        let spawn = |seed: &str| {
            std::process::Command::new(env!("CARGO_BIN_EXE_pathspace"))
                .args([
                    "render",
                    "--resolution",
                    "8x8",
                    "--threads",
                    "1",
                    "--spp",
                    "1",
                ])
                .args(["--seed", seed, "-o", e])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (a, b) = (spawn("1"), spawn("2"));
        for child in [a, b] {
            let out = child.wait_with_output().unwrap();
            assert!(out.status.success(), "round {round}: {}", stderr(&out));
        }
        let (_, meta) = pathspace::image_io::read_exr(&exr).unwrap();
        assert!(["1", "2"].contains(&meta.get("seed").unwrap()));
    }
}

/// A full disk is reported (the PNG is encoded in memory and written at once): `/dev/full`
/// fails every write with ENOSPC, where the system has it.
#[test]
fn a_full_disk_is_an_error() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    let dir = scratch(GROUP, "full");
    let exr = dir.join("x.exr");
    let out = render(&["-o", exr.to_str().unwrap(), "--png", "/dev/full"]);
    assert!(
        !out.status.success(),
        "a PNG written to a full disk exited 0"
    );
    assert!(stderr(&out).contains("/dev/full"), "{}", stderr(&out));
    assert!(!exr.exists(), "/dev/full was found only after the work");
}

/// Outputs that cannot hold the image are refused before the work, whatever the command:
/// `-o` or `--png` naming a directory or a device, and a directory on a read-only file system
/// (a tmpfs mounted read-only here, where the test may mount one).
#[test]
fn directories_devices_and_read_only_file_systems_are_refused_before_the_work() {
    let dir = scratch(GROUP, "targets");
    let exr = dir.join("x.exr");
    let e = exr.to_str().unwrap();
    let sub = dir.join("sub.exr");
    std::fs::create_dir(&sub).unwrap();
    let s = sub.to_str().unwrap();
    for (args, says) in [
        (vec!["-o", s], "is a directory"),
        (
            vec!["-o", e, "--png", dir.to_str().unwrap()],
            "is a directory",
        ),
        (vec!["-o", "/dev/full"], "no regular file"),
        (vec!["-o", e, "--png", "/dev/zero"], "no regular file"),
    ] {
        let out = render(&args);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr(&out).contains(says), "{args:?}: {}", stderr(&out));
        assert!(!exr.exists(), "{args:?}: refused only after the work");
    }
    let ro = dir.join("ro");
    std::fs::create_dir(&ro).unwrap();
    let mounted = Command::new("mount")
        .args([
            "-t",
            "tmpfs",
            "-o",
            "ro,size=1m",
            "none",
            ro.to_str().unwrap(),
        ])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped the read-only case: this test cannot mount a tmpfs here");
        return;
    }
    let target = ro.join("x.exr");
    let out = render(&["-o", target.to_str().unwrap()]);
    let _ = Command::new("umount").arg(&ro).status();
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("cannot write in") && err.contains("Read-only file system"),
        "{err}"
    );
}

/// The fog box of the repository, the scene of the `converge` cases.
fn fog_box() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fog-box.toml").to_string()
}

/// What the command said, stdout and stderr together.
fn said(out: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), stderr(out))
}

/// A 64 KiB tmpfs at `dir` holding `earlier` as `name`, then filled to the last byte, so that
/// the next write of `name` fails half-way; false where the test cannot mount one.
fn full_tmpfs_with(dir: &Path, name: &str, earlier: &[u8]) -> bool {
    if !mount_tmpfs(dir, "size=64k") {
        return false;
    }
    std::fs::write(dir.join(name), earlier).unwrap();
    use std::io::Write;
    let mut filler = std::fs::File::create(dir.join("filler")).unwrap();
    while filler.write_all(&[0u8; 1024]).is_ok() {}
    true
}

/// The names of the temporary files a failed write left in `dir`.
fn partial_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|f| f.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect()
}

/// `rooms -o` on a full disk fails and leaves the earlier scene file whole.
#[test]
fn rooms_on_a_full_disk_keeps_the_earlier_scene_file() {
    let dir = scratch(GROUP, "rooms-full").join("fs");
    let earlier = b"# the earlier scene\n";
    if !full_tmpfs_with(&dir, "rooms.toml", earlier) {
        eprintln!("skipped: this test cannot mount a tmpfs here");
        return;
    }
    let scene = dir.join("rooms.toml");
    let out = pathspace(&["rooms", "--n", "10", "-o", scene.to_str().unwrap()]);
    let now = std::fs::read(&scene);
    let left = partial_files(&dir);
    let _ = Command::new("umount").arg(&dir).status();
    assert!(!out.status.success(), "a failed write must not exit 0");
    assert!(stderr(&out).contains("rooms.toml"), "{}", stderr(&out));
    let now = now.unwrap();
    assert!(
        now == earlier,
        "the earlier scene file was damaged: {} bytes now",
        now.len()
    );
    assert!(left.is_empty(), "{left:?}");
}

/// A reference of the fog box at 8x8 in `dir`, for `converge`.
fn fog_reference(dir: &Path) -> String {
    let r = dir.join("ref.exr");
    let r = r.to_str().unwrap();
    let out = pathspace(&[
        "reference",
        &fog_box(),
        "--resolution",
        "8x8",
        "--spp",
        "2",
        "--threads",
        "1",
        "-o",
        r,
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    r.to_string()
}

/// A short `converge` of the fog box into `out` (with `extra` options).
fn converge(reference: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "converge".to_string(),
        fog_box(),
        "--reference".into(),
        reference.into(),
        "--resolution".into(),
        "8x8".into(),
        "--budget".into(),
        "0.1".into(),
        "--checkpoints".into(),
        "2".into(),
        "--threads".into(),
        "1".into(),
        "-o".into(),
        out.to_str().unwrap().into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    pathspace(&args)
}

/// `converge` on a full disk fails and leaves the earlier study's `convergence.csv` whole.
#[test]
fn converge_on_a_full_disk_keeps_the_earlier_csv() {
    let base = scratch(GROUP, "converge-full");
    let reference = fog_reference(&base);
    let dir = base.join("fs");
    let earlier = b"integrator,run\nearlier,0\n";
    if !full_tmpfs_with(&dir, "convergence.csv", earlier) {
        eprintln!("skipped: this test cannot mount a tmpfs here");
        return;
    }
    let out = converge(&reference, &dir, &[]);
    let now = std::fs::read(dir.join("convergence.csv"));
    let left = partial_files(&dir);
    let _ = Command::new("umount").arg(&dir).status();
    assert!(!out.status.success(), "a failed write must not exit 0");
    assert!(stderr(&out).contains("convergence.csv"), "{}", stderr(&out));
    let now = now.unwrap();
    assert!(
        now == earlier,
        "the earlier CSV was damaged: {}",
        String::from_utf8_lossy(&now)
    );
    assert!(left.is_empty(), "{left:?}");
}

/// A study whose files cannot be written is refused before the runs (no run is reported, no
/// budget spent): here `convergence.csv` is a directory.
#[test]
fn converge_refuses_unwritable_study_files_before_the_runs() {
    let base = scratch(GROUP, "converge-targets");
    let reference = fog_reference(&base);
    let out_dir = base.join("study");
    std::fs::create_dir_all(out_dir.join("convergence.csv")).unwrap();
    let out = converge(&reference, &out_dir, &[]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("is a directory"), "{}", stderr(&out));
    assert!(!said(&out).contains("run 0"), "{}", said(&out));
    assert!(
        !out_dir.join("study.toml").exists(),
        "refused only after the runs"
    );
}

/// `merge` of a study's shards refuses, before reading them, an output whose files cannot be
/// written (`study.toml` is a directory): no half of a study is written.
#[test]
fn merge_refuses_unwritable_study_files_before_the_work() {
    let base = scratch(GROUP, "merge-targets");
    let reference = fog_reference(&base);
    let shards: Vec<_> = (1..=2).map(|i| base.join(format!("shard{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        let shard = format!("{}/2", i + 1);
        let out = converge(&reference, s, &["--runs", "2", "--shard", &shard]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let merged = base.join("merged");
    std::fs::create_dir_all(merged.join("study.toml")).unwrap();
    let out = pathspace(&[
        "merge",
        shards[0].to_str().unwrap(),
        shards[1].to_str().unwrap(),
        "-o",
        merged.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("is a directory"), "{}", stderr(&out));
    assert!(
        !merged.join("convergence.csv").exists(),
        "half a study was written before the refusal"
    );
}

/// `diff --heatmap` naming a directory or a device is refused before the images are read
/// (the images here do not even exist).
#[test]
fn diff_refuses_a_heatmap_it_cannot_write_before_reading_the_images() {
    let dir = scratch(GROUP, "diff");
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    for (target, says) in [
        (dir.to_str().unwrap(), "is a directory"),
        ("/dev/zero", "no regular file"),
    ] {
        let out = pathspace(&[
            "diff",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--heatmap",
            target,
        ]);
        assert!(!out.status.success());
        assert!(stderr(&out).contains(says), "{target}: {}", stderr(&out));
    }
}

/// A directory on a read-only file system is refused before the work by every command that
/// writes there: `converge -o`, `render --strategy-images`, `rooms -o`, `diff --heatmap` and `assignment make --out`.
#[test]
fn every_command_refuses_a_read_only_file_system_before_the_work() {
    let base = scratch(GROUP, "read-only");
    let reference = fog_reference(&base);
    let ro = base.join("ro");
    if !mount_tmpfs(&ro, "ro,size=1m") {
        eprintln!("skipped: this test cannot mount a tmpfs here");
        return;
    }
    let at = |name: &str| ro.join(name).to_str().unwrap().to_string();
    let exr = base.join("x.exr");
    let e = exr.to_str().unwrap();
    let outs = [
        ("converge", converge(&reference, &ro, &[])),
        (
            "strategy images",
            render(&[
                "--integrator",
                "bdpt",
                "-o",
                e,
                "--strategy-images",
                &at(""),
            ]),
        ),
        (
            "rooms",
            pathspace(&["rooms", "--n", "2", "-o", &at("r.toml")]),
        ),
        (
            "diff",
            pathspace(&["diff", &reference, &reference, "--heatmap", &at("h.png")]),
        ),
        (
            "assignment",
            pathspace(&["assignment", "make", "uniform_triangle", "--out", &at("")]),
        ),
    ];
    let _ = Command::new("umount").arg(&ro).status();
    // every command's verdict, so that a failure names all the commands that fail
    let wrong: Vec<String> = outs
        .iter()
        .filter(|(_, out)| {
            let err = stderr(out);
            out.status.success()
                || !err.contains("cannot write in")
                || !err.contains("Read-only file system")
                || said(out).contains("run 0")
        })
        .map(|(what, out)| format!("{what}: {}", said(out)))
        .collect();
    assert!(wrong.is_empty(), "{wrong:#?}");
    assert!(!exr.exists(), "a render ran before its output was refused");
}

/// `--adjoint-output A.exr` writes `A.png` beside it: a directory of that name is refused
/// before the render, as the EXR is.
#[test]
fn the_adjoint_images_png_is_checked_before_the_render() {
    let dir = scratch(GROUP, "adjoint");
    let (exr, adj) = (dir.join("x.exr"), dir.join("adj.exr"));
    std::fs::create_dir(dir.join("adj.png")).unwrap();
    let out = render(&[
        "--integrator",
        "bdpt",
        "--adjoint-image",
        "-o",
        exr.to_str().unwrap(),
        "--adjoint-output",
        adj.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("is a directory"), "{}", stderr(&out));
    assert!(
        !exr.exists() && !adj.exists(),
        "refused only after the render"
    );
}

/// `--strategy-images` on a full disk fails the command and leaves an earlier strategy image
/// whole, with no temporary file left behind (each image is written beside its target and
/// renamed).
#[test]
fn strategy_images_on_a_full_disk_keep_the_earlier_files() {
    let base = scratch(GROUP, "strategies-full");
    let dir = base.join("fs");
    let earlier = b"an earlier strategy image";
    // the first image written (strategies go in the order of (s, t))
    if !full_tmpfs_with(&dir, "s0-t4.exr", earlier) {
        eprintln!("skipped: this test cannot mount a tmpfs here");
        return;
    }
    let exr = base.join("x.exr");
    let out = render(&[
        "--integrator",
        "bdpt",
        "-o",
        exr.to_str().unwrap(),
        "--strategy-images",
        dir.to_str().unwrap(),
    ]);
    let now = std::fs::read(dir.join("s0-t4.exr"));
    let left = partial_files(&dir);
    let _ = Command::new("umount").arg(&dir).status();
    assert!(!out.status.success(), "a failed write must not exit 0");
    assert!(
        stderr(&out).contains(dir.to_str().unwrap()),
        "{}",
        stderr(&out)
    );
    assert_eq!(
        now.unwrap(),
        earlier,
        "the earlier strategy image was damaged"
    );
    assert!(left.is_empty(), "{left:?}");
}

/// `assignment check` on a full disk: the claims that bind a student's copy to its target and
/// build directories fail with the file named, and no empty claim is left that would later
/// name no copy (a claim is written through a temporary file).
#[test]
fn assignment_claims_on_a_full_disk_leave_no_empty_claim() {
    let base = scratch(GROUP, "claims-full");
    let copy = base.join("copy");
    std::fs::create_dir_all(&copy).unwrap();
    std::fs::write(
        copy.join("Cargo.toml"),
        "[package]\nname = \"copy\"\nversion = \"0.1.0+copy.0123abcd\"\n",
    )
    .unwrap();
    // `check` reads the copy's course registry before it claims a directory
    std::fs::create_dir_all(copy.join("book")).unwrap();
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/book/course.toml"),
        copy.join("book/course.toml"),
    )
    .unwrap();
    let fs = base.join("fs");
    if !full_tmpfs_with(&fs, "earlier.txt", b"earlier") {
        eprintln!("skipped: this test cannot mount a tmpfs here");
        return;
    }
    let dir = |name: &str| fs.join(name).to_str().unwrap().to_string();
    let copy = copy.to_str().unwrap();
    let target = pathspace(&["assignment", "check", copy, "--target-dir", &dir("")]);
    let build = pathspace(&["assignment", "check", copy, "--build-dir", &dir("")]);
    let claims: Vec<String> = [
        fs.join("pathspace-assignment-copy.txt"),
        fs.join("pathspace-assignment-copies"),
    ]
    .iter()
    .filter(|p| p.is_file() || p.read_dir().is_ok_and(|mut d| d.next().is_some()))
    .map(|p| p.display().to_string())
    .collect();
    let left = partial_files(&fs);
    let _ = Command::new("umount").arg(&fs).status();
    for (what, out) in [("target", &target), ("build", &build)] {
        assert!(
            !out.status.success(),
            "{what}: a failed claim must not exit 0"
        );
        assert!(
            stderr(out).contains("pathspace-assignment-cop"),
            "{what}: {}",
            stderr(out)
        );
    }
    assert!(claims.is_empty(), "claims left: {claims:?}");
    assert!(left.is_empty(), "{left:?}");
}
