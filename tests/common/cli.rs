//! Driving the `pathspace` binary from a test: run it, read its stderr, and give each test a
//! fresh scratch directory under Cargo's target directory.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `pathspace ARGS`, waited for, with stdout and stderr captured.
pub fn pathspace(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// What the binary said on stderr.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A fresh, empty directory `GROUP-NAME` under the target directory for one test.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{group}-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
