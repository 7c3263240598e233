//! Where the browser of `tests/repository/book_browser.rs` is, and whether this run must have it.

use std::path::PathBuf;

/// The variable that makes a missing Chromium a failure (`.ci/run` sets it); without it the
/// browser check is skipped with a notice and the rest of the suite runs.
pub const REQUIRE: &str = "PATHSPACE_REQUIRE_BROWSER";

/// `PATHSPACE_CHROMIUM` if set (a Chromium or Chrome binary), else `/usr/bin/chromium`, else
/// `chromium` on `PATH`.
pub fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("PATHSPACE_CHROMIUM") {
        let p = PathBuf::from(p);
        return p.exists().then_some(p);
    }
    let fixed = PathBuf::from("/usr/bin/chromium");
    if fixed.exists() {
        return Some(fixed);
    }
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|p| p.join("chromium"))
            .find(|p| p.exists())
    })
}

/// Whether this run must have the browser (`PATHSPACE_REQUIRE_BROWSER=1`).
pub fn required() -> bool {
    std::env::var(REQUIRE).as_deref() == Ok("1")
}

/// What the skipped check did not look at, and how to turn it on.
pub const NOT_CHECKED: &str =
    "tests/repository/book_browser.rs was SKIPPED: Chromium is not installed, \
so the book was not opened in a browser (its math typesetting, offline loading and links were \
NOT checked). Install it (Debian: `apt-get install -y chromium`) or name a Chromium binary in \
PATHSPACE_CHROMIUM; PATHSPACE_REQUIRE_BROWSER=1 (set by .ci/run) makes its absence a failure.";
