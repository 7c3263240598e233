// What a student copy of the crate contains: shared by `build.rs` (which embeds it with the
// `embed-source` feature) and `course::read_tree`, through `include!`.

/// Top-level files of a student copy.
const FILES: [&str; 7] = [
    "Cargo.toml",
    "Cargo.lock",
    "build.rs",
    "README.md",
    "ARCHITECTURE.md",
    ".gitignore",
    ".ci/run",
];

/// Directories of a student copy, walked recursively.
const DIRS: [&str; 8] = [
    "src", "tests", "scenes", "golden", "book", "assets", "benches", "examples",
];
