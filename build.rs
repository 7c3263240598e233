//! With the feature `embed-source`, embeds the crate's own source tree (sources, tests, scenes,
//! golden files, the book, assets, benches) in the binary, so that `pathspace assignment make`
//! can write a student copy from an installed binary with no checkout at hand (book: "Course
//! use: assignments"). Without it (the default) the tree is empty and `assignment make` reads
//! the directory the binary was built from: embedding makes every edit of a test or a chapter
//! re-run this script, and Cargo then rebuilds the library too (see ARCHITECTURE.md).
//!
//! The generated `$OUT_DIR/source_tree.rs` is a list of `(relative path, include_bytes!(...))`
//! included by `src/main.rs` only.

use std::path::{Path, PathBuf};

include!("course/src/tree.rs");

/// Generated or pending files that are not part of the source.
fn skipped(rel: &str) -> bool {
    rel.starts_with("book/book/")
        || rel.split('/').any(|part| part == "target")
        || rel.ends_with(".snap.new")
        || rel.ends_with(".pending-snap")
        || rel.rsplit('/').next().is_some_and(|n| n.starts_with('.'))
}

fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        let rel = p
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        if skipped(&rel) {
            continue;
        }
        if p.is_dir() {
            walk(root, &p, out);
        } else {
            out.push(rel);
        }
    }
}

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap()).join("source_tree.rs");
    let header =
        "/// The crate's source tree at build time: (path relative to the crate root, bytes).\n\
                  pub static SOURCE_TREE: &[(&str, &[u8])] = &[\n";
    if std::env::var_os("CARGO_FEATURE_EMBED_SOURCE").is_none() {
        println!("cargo:rerun-if-changed=build.rs");
        println!("cargo:rerun-if-changed=course/src/tree.rs");
        std::fs::write(out, format!("{header}];\n")).unwrap();
        return;
    }
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let mut files: Vec<String> = FILES
        .iter()
        .filter(|f| root.join(f).is_file())
        .map(|f| f.to_string())
        .collect();
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap_or_default();
    for d in DIRS
        .iter()
        .map(|d| d.to_string())
        .chain(workspace_members(&manifest))
    {
        walk(&root, &root.join(&d), &mut files);
        println!("cargo:rerun-if-changed={d}");
    }
    for f in FILES {
        println!("cargo:rerun-if-changed={f}");
    }
    let mut code = String::from(header);
    for f in &files {
        let abs = root.join(f).to_string_lossy().to_string();
        code.push_str(&format!("    ({f:?}, include_bytes!({abs:?})),\n"));
    }
    code.push_str("];\n");
    std::fs::write(out, code).unwrap();
}
