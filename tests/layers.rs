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
const KNOWN_UPWARD: [(&str, &str, &str); 2] = [
    (
        "integrator/mod.rs",
        "render",
        "the trait's checkpoint state and the checkpoint error, moved with the checkpoint",
    ),
    (
        "integrator/smc/mod.rs",
        "render",
        "SMC's octree as its checkpoint state",
    ),
];

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
