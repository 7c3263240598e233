//! Builds are paid once: `cargo test --release` after `cargo run --release` must not rebuild a
//! crate the run built. Cargo rebuilds a shared crate when the test build turns on more of its
//! features (resolver 2 unifies the dev-dependencies' features into it), so every crate both
//! builds share must have the same features in both; `Cargo.toml` declares the ones the book's
//! builder adds. A dependency update that adds another such feature turns this red, with the
//! crate and the feature to declare.

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

/// Every package of the build with its features: `cargo tree` over the given edge kinds.
fn features(edges: &str) -> BTreeMap<String, BTreeSet<String>> {
    let out = Command::new(env!("CARGO"))
        .args([
            "tree",
            "--locked",
            "--offline",
            "--prefix",
            "none",
            "-f",
            "{p}|{f}",
            "-e",
            edges,
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut map: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Some((package, feats)) = line.split_once('|') else {
            continue;
        };
        // `name vX.Y.Z (path)`, and `(*)` where cargo elides a repeated subtree
        let key: String = package
            .split_whitespace()
            .take(2)
            .collect::<Vec<_>>()
            .join(" ");
        let entry = map.entry(key).or_default();
        entry.extend(
            feats
                .trim_end_matches(" (*)")
                .split(',')
                .filter(|f| !f.is_empty())
                .map(str::to_string),
        );
    }
    map
}

#[test]
fn the_test_build_turns_on_no_feature_the_run_build_lacks() {
    let run = features("normal,build");
    let test = features("normal,build,dev");
    assert!(run.len() > 50, "cargo tree listed {} packages", run.len());
    let added: Vec<String> = run
        .iter()
        .filter_map(|(package, feats)| {
            let more: Vec<&String> = test.get(package)?.difference(feats).collect();
            (!more.is_empty()).then(|| format!("{package}: {more:?}"))
        })
        .collect();
    assert!(
        added.is_empty(),
        "the dev-dependencies turn on features of crates `cargo run` builds too, so `cargo test` \
         rebuilds them; declare these in Cargo.toml's [dependencies] (or [build-dependencies] for \
         derive macros' crates):\n{}",
        added.join("\n")
    );
}
