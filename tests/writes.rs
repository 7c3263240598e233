//! Writes that cannot destroy: outputs that cannot be written are refused before the render
//! starts, a failed write is an error with a nonzero exit, and it leaves an earlier file at the
//! path as it was (images go to a temporary file beside the target, renamed once complete).

use std::path::Path;
use std::process::{Command, Output};

mod common;
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
