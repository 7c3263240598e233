// What a student copy of the crate contains: shared by the renderer's `build.rs` (which embeds
// it with the `embed-source` feature) and `read_tree`, through `include!`.

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

/// Directories of a student copy, walked recursively; the workspace's members
/// ([`workspace_members`]) too, or the copy's workspace would not build.
const DIRS: [&str; 8] = [
    "src", "tests", "scenes", "golden", "book", "assets", "benches", "examples",
];

/// The directories named by `members = [...]` in the `[workspace]` table of a `Cargo.toml`
/// (a plain reading: one string per member, no globs).
#[allow(dead_code)]
fn workspace_members(cargo_toml: &str) -> Vec<String> {
    let mut in_workspace = false;
    let mut list = String::new();
    let mut collecting = false;
    for line in cargo_toml.lines() {
        let t = line.split('#').next().unwrap_or("").trim();
        if !collecting && t.starts_with('[') {
            in_workspace = t == "[workspace]";
            continue;
        }
        if in_workspace && !collecting {
            if let Some((k, v)) = t.split_once('=') {
                if k.trim() == "members" {
                    collecting = true;
                    list.push_str(v);
                }
            }
        } else if collecting {
            list.push_str(t);
        }
        if collecting && list.contains(']') {
            break;
        }
    }
    list.split(['[', ']', ','])
        .map(|m| m.trim().trim_matches('"').to_string())
        .filter(|m| !m.is_empty() && m != ".")
        .collect()
}
