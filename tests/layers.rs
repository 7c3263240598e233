//! The crate's layers: a module may use the layers below it, never one above. The order, from
//! the bottom: `math`, `spectrum`, `conventions` <- `geometry`, `medium`, `bsdf`, `film`,
//! `image_io` <- `scene` <- `path` <- `enlightened` <- `integrator` <- `render` <- `measure`,
//! `aov` <- `cli`, `course`. A lower layer that reaches up ties the house into one import circle: a change to
//! an integrator can then break the scene, and nobody can read the scene without the
//! integrators.
//!
//! The imports that still run upwards are listed in [`KNOWN_UPWARD`], each with the reason it is
//! there; the test fails on any other upward import, and on a listed one that is gone (so the
//! list only shrinks, and says what is left to untie).

use std::collections::BTreeSet;
use std::path::Path;

/// The layer of a top-level module of `src/`.
fn layer(module: &str) -> Option<u32> {
    Some(match module {
        "math" | "spectrum" | "conventions" => 0,
        "geometry" | "medium" | "bsdf" | "film" | "image_io" => 1,
        "scene" => 2,
        "path" => 3,
        "enlightened" => 4,
        "integrator" => 5,
        "render" => 6,
        "measure" | "aov" => 7,
        "cli" | "course" => 8,
        _ => return None,
    })
}

/// (file under `src/`, module it reaches up to): the upward imports of today's house.
const KNOWN_UPWARD: [(&str, &str, &str); 0] = [];

/// Every `crate::module` a source file names, by module.
fn crate_paths(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut rest = text;
    while let Some(i) = rest.find("crate::") {
        let after = &rest[i + "crate::".len()..];
        let name: String = after
            .chars()
            .take_while(|c| c.is_ascii_lowercase() || *c == '_')
            .collect();
        if !name.is_empty() {
            out.insert(name);
        }
        rest = after;
    }
    out
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The upward imports of `src/` as (file, module) pairs.
fn upward_imports() -> BTreeSet<(String, String)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut out = BTreeSet::new();
    for file in files {
        let rel = file
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let top = rel.split('/').next().unwrap().trim_end_matches(".rs");
        let Some(own) = layer(top) else { continue }; // lib.rs, main.rs
        let text = std::fs::read_to_string(&file).unwrap();
        for module in crate_paths(&text) {
            if layer(&module).is_some_and(|l| l > own) {
                out.insert((rel.clone(), module));
            }
        }
    }
    out
}

#[test]
fn every_top_level_module_has_a_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs");
    let lib = std::fs::read_to_string(src).unwrap();
    for line in lib.lines() {
        if let Some(m) = line.strip_prefix("pub mod ") {
            let m = m.trim_end_matches(';');
            assert!(
                layer(m).is_some(),
                "src/{m}: give it a layer in tests/layers.rs"
            );
        }
    }
}

#[test]
fn imports_run_downwards_except_the_known_ones() {
    let found = upward_imports();
    let known: BTreeSet<(String, String)> = KNOWN_UPWARD
        .iter()
        .map(|(f, m, _)| (f.to_string(), m.to_string()))
        .collect();
    let new: Vec<_> = found.difference(&known).collect();
    assert!(
        new.is_empty(),
        "imports from a lower layer up to a higher one (move the code down, or pass what it needs \
         in): {new:?}"
    );
    let gone: Vec<_> = known.difference(&found).collect();
    assert!(
        gone.is_empty(),
        "untied (well done): remove these from KNOWN_UPWARD: {gone:?}"
    );
}

#[test]
fn the_scanner_sees_an_upward_import() {
    // the test above can fail: a `crate::integrator` path in a scene file is an upward import
    let names =
        crate_paths("use crate::integrator::bdpt::Bdpt;\nlet x = crate::math::Frame::new();");
    assert!(names.contains("integrator") && names.contains("math"));
    assert!(layer("integrator") > layer("scene"));
}

/// (layer, module, module): the import circles between the modules of one layer that are still
/// there, each to untie like the upward imports.
const KNOWN_CIRCLES: [(&str, &str, &str); 4] = [
    // `reference` is run by `render`'s steps, and `render` names `reference`'s defaults
    ("cli", "reference", "render"),
    ("cli", "reference", "resume"),
    // `--resume FILE` gives the recipe back to `render`'s parser, which `render` calls
    ("cli", "render", "resume"),
    // `file` dispatches `.xml` to the importer, which writes `file`'s types
    ("scene", "file", "mitsuba"),
];

/// The names `text` reaches through `prefix` (`super::a`, `super::{a, b::c}`), outside comments.
fn names_after(text: &str, prefix: &str) -> BTreeSet<String> {
    let word = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
            .collect()
    };
    let mut out = BTreeSet::new();
    for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
        for (i, _) in line.match_indices(prefix) {
            let after = &line[i + prefix.len()..];
            match after.strip_prefix('{') {
                Some(list) => out.extend(list.split(',').map(|s| word(s.trim()))),
                None => {
                    out.insert(word(after));
                }
            }
        }
    }
    out.retain(|n| !n.is_empty());
    out
}

/// The imports between the modules of each layer: (layer, module) -> modules of that layer it
/// names, through `crate::layer::module` or, in a file at the layer's top, `super::module`.
fn sibling_imports() -> std::collections::BTreeMap<(String, String), BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut out = std::collections::BTreeMap::new();
    for file in files {
        let rel = file
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let parts: Vec<&str> = rel.trim_end_matches(".rs").split('/').collect();
        if parts.len() < 2 || parts[1] == "mod" {
            continue;
        }
        let (top, own) = (parts[0].to_string(), parts[1].to_string());
        let text = std::fs::read_to_string(&file).unwrap();
        let mut names = names_after(&text, &format!("crate::{top}::"));
        // `super::` reaches the layer's modules from files directly under it (`a.rs`, `a/mod.rs`)
        if parts.len() == 2 || (parts.len() == 3 && parts[2] == "mod") {
            names.extend(names_after(&text, "super::"));
        }
        let sibling = |n: &String| {
            n != &own
                && (src.join(&top).join(format!("{n}.rs")).exists()
                    || src.join(&top).join(n).join("mod.rs").exists())
        };
        let names: BTreeSet<String> = names.into_iter().filter(|n| sibling(n)).collect();
        out.entry((top, own))
            .or_insert_with(BTreeSet::new)
            .extend(names);
    }
    out
}

/// The pairs of modules of one layer that reach each other, directly or through others.
fn circles() -> BTreeSet<(String, String, String)> {
    let edges = sibling_imports();
    let reaches = |layer: &str, from: &str, to: &str| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.to_string()];
        while let Some(m) = stack.pop() {
            for n in edges.get(&(layer.to_string(), m)).into_iter().flatten() {
                if n == to {
                    return true;
                }
                if seen.insert(n.clone()) {
                    stack.push(n.clone());
                }
            }
        }
        false
    };
    let mut out = BTreeSet::new();
    for ((layer, a), names) in &edges {
        for b in names {
            if a < b && reaches(layer, b, a) {
                out.insert((layer.clone(), a.clone(), b.clone()));
            }
        }
    }
    out
}

#[test]
fn no_import_circle_inside_a_layer_except_the_known_ones() {
    let found = circles();
    let known: BTreeSet<(String, String, String)> = KNOWN_CIRCLES
        .iter()
        .map(|(l, a, b)| (l.to_string(), a.to_string(), b.to_string()))
        .collect();
    let new: Vec<_> = found.difference(&known).collect();
    assert!(
        new.is_empty(),
        "modules of one layer that import each other (put what both need in one of them, or \
         below both): {new:?}"
    );
    let gone: Vec<_> = known.difference(&found).collect();
    assert!(
        gone.is_empty(),
        "untied: remove these from KNOWN_CIRCLES: {gone:?}"
    );
}

#[test]
fn the_scanner_sees_a_circle() {
    // the test above can fail: both spellings of a sibling import are read
    let names = names_after(
        "use super::{session::PASS_SPP, shard};\n// super::memory\nuse crate::render::plan;",
        "super::",
    );
    assert_eq!(names, ["session", "shard"].map(String::from).into());
    let names = names_after("use crate::render::plan::PASS_SPP;", "crate::render::");
    assert_eq!(names, ["plan"].map(String::from).into());
}
