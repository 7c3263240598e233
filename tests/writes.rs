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

#[test]
fn a_failed_write_keeps_the_earlier_file_and_fails_the_command() {
    let dir = scratch(GROUP, "kept");
    let exr = dir.join("img.exr");
    let png = dir.join("img.png");
    let (e, p) = (exr.to_str().unwrap(), png.to_str().unwrap());
    let first = render(&["-o", e, "--png", p, "--seed", "1"]);
    assert!(first.status.success(), "{}", stderr(&first));
    let (old_exr, old_png) = (std::fs::read(&exr).unwrap(), std::fs::read(&png).unwrap());
    // the temporary files cannot be created (directories hold their names): both writes fail
    std::fs::create_dir(dir.join(".img.exr.partial")).unwrap();
    std::fs::create_dir(dir.join(".img.png.partial")).unwrap();
    let second = render(&["-o", e, "--png", p, "--seed", "2"]);
    assert!(!second.status.success(), "a failed write must not exit 0");
    assert!(stderr(&second).contains("img.exr"), "{}", stderr(&second));
    assert_eq!(
        std::fs::read(&exr).unwrap(),
        old_exr,
        "the earlier EXR was damaged"
    );
    std::fs::remove_dir(dir.join(".img.exr.partial")).unwrap();
    let third = render(&["-o", e, "--png", p, "--seed", "3"]);
    assert!(
        !third.status.success(),
        "a failed PNG write must not exit 0"
    );
    assert!(stderr(&third).contains("img.png"), "{}", stderr(&third));
    assert_eq!(
        std::fs::read(&png).unwrap(),
        old_png,
        "the earlier PNG was damaged"
    );
    assert_ne!(std::fs::read(&exr).unwrap(), old_exr, "the EXR was written");
    // a successful write leaves no temporary file behind
    std::fs::remove_dir(dir.join(".img.png.partial")).unwrap();
    assert!(render(&["-o", e, "--png", p]).status.success());
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|f| f.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
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
