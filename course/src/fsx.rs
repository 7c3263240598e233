//! The two file-system steps the course shares with the renderer's outputs, written here so
//! that the course needs nothing from the renderer: a directory checked before the work, and
//! a file written through a temporary file and renamed into place.

use std::path::Path;

use super::CourseError;

fn output_err(dir: &Path, message: String) -> CourseError {
    CourseError::Output(dir.display().to_string(), message)
}

/// Checks that `dir` is (or can be created as) a directory that can be written: a read-only
/// file system or a file in its place is found before the work, not after it.
pub fn check_output_dir(dir: &Path) -> Result<(), CourseError> {
    if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
        return Err(output_err(dir, "is not a directory".into()));
    }
    std::fs::create_dir_all(dir).map_err(|e| output_err(dir, format!("cannot create it: {e}")))?;
    let probe = dir.join(format!(".pathspace-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .and_then(|_| std::fs::remove_file(&probe))
        .map_err(|e| output_err(dir, format!("cannot write in it: {e}")))
}

/// Writes `bytes` to `path` through a temporary file beside it: a failed write (a full disk)
/// leaves an earlier file at `path` as it was, and never an empty one.
pub fn write_file_replacing(path: &Path, bytes: &[u8]) -> Result<(), CourseError> {
    let name = path
        .file_name()
        .ok_or_else(|| output_err(path, "is not a file name".into()))?;
    let tmp = path.with_file_name(format!(
        ".{}.{}.partial",
        name.to_string_lossy(),
        std::process::id()
    ));
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written.map_err(|e| CourseError::Write(path.display().to_string(), e))
}
