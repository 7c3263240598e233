//! The suite's last word: what this run of `cargo test` did not check, and why. Integration
//! tests run in the order of their names, so this one (`z_`) prints after all the others,
//! where a reader of the output looks. It checks nothing itself (no harness: it prints straight
//! to the terminal and exits 0); the checks it names fail on their own where a run requires
//! them (`PATHSPACE_REQUIRE_BROWSER=1`, set by `.ci/run`).

#[path = "common/browser.rs"]
mod browser;

fn main() {
    match browser::chromium() {
        Some(path) => println!(
            "every check of the suite ran (the book was read in {})",
            path.display()
        ),
        None if browser::required() => println!(
            "Chromium is missing and {}=1 requires it: tests/repository/book_browser.rs failed",
            browser::REQUIRE
        ),
        None => println!(
            "\n*** NOT CHECKED in this run ***\n*** {} ***\n",
            browser::NOT_CHECKED
        ),
    }
}
