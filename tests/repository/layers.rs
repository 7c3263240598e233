//! The crate's layers: a module may use the layers below it, never one above. The order, from
//! the bottom: `math`, `spectrum`, `conventions` <- `geometry`, `medium`, `bsdf`, `film`,
//! `image_io`, `texture` <- `scene` <- `path` <- `bidir` <- `enlightened` <- `integrator` <- `render` <-
//! `measure`, `aov` <- `cli`, `figures` (the course is a workspace member of its own, `course/`). A lower layer that reaches up ties the house into one import
//! circle: a change to an integrator can then break the scene, and nobody can read the scene
//! without the integrators.
//!
//! The imports that still run upwards are listed in [`KNOWN_UPWARD`], each with the reason it is
//! there; the test fails on any other upward import, and on a listed one that is gone (so the
//! list only shrinks, and says what is left to untie).
//!
//! Inside a layer the same holds between its rooms: no two modules of one layer may import each
//! other, directly or round a longer circle, whether they are top-level modules of the layer
//! (`geometry` and `medium`) or the sub-modules of one (`scene::file` and `scene::mitsuba`). A
//! module's root file (`scene/mod.rs`) is its front door, not a room: a name it re-exports
//! (`scene::SceneError`) counts as an import of the sub-module that defines it, and its own items
//! (`scene::Scene`) are the layer's shared ground. The circles still standing are listed in
//! [`KNOWN_CIRCLES`] on the same terms as [`KNOWN_UPWARD`].

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The layer of a top-level module of `src/`.
fn layer(module: &str) -> Option<u32> {
    Some(match module {
        "math" | "spectrum" | "conventions" => 0,
        "geometry" | "medium" | "bsdf" | "film" | "image_io" | "texture" => 1,
        "scene" => 2,
        "path" => 3,
        "bidir" => 4,
        "enlightened" => 5,
        "integrator" => 6,
        "render" => 7,
        "measure" | "aov" => 8,
        "cli" | "figures" => 9,
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
                "src/{m}: give it a layer in tests/repository/layers.rs"
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

/// The circles inside a layer allowed to stand, each named as [`circles`] names it, with why it
/// is there: none. The test fails on any other circle and on a listed one that is gone.
const KNOWN_CIRCLES: [(&str, &str); 0] = [];

/// A module of `src/` as its path (`["scene", "file"]` for `src/scene/file.rs`,
/// `src/scene/file/mod.rs` and the files under `src/scene/file/`'s own path).
fn module_path(rel: &str) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .trim_end_matches(".rs")
        .split('/')
        .map(str::to_string)
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

/// The rooms of a top-level module: its sub-modules (files and folders of `src/TOP/`).
fn rooms(src: &Path, top: &str) -> BTreeSet<String> {
    let Ok(dir) = std::fs::read_dir(src.join(top)) else {
        return BTreeSet::new();
    };
    dir.map(|e| e.unwrap().path())
        .filter(|p| p.is_dir() || p.extension().is_some_and(|e| e == "rs"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .filter(|n| n != "mod")
        .collect()
}

/// The names a module's root file re-exports from its rooms: `pub use file::{A, B};` maps `A`
/// and `B` to `file`.
fn reexports(root_text: &str, rooms: &BTreeSet<String>) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for line in root_text.lines() {
        let Some(rest) = line.trim().strip_prefix("pub use ") else {
            continue;
        };
        let rest = rest.trim_end_matches(';');
        let Some((room, names)) = rest.split_once("::") else {
            continue;
        };
        if !rooms.contains(room) {
            continue;
        }
        let names = names.rsplit("::").next().unwrap();
        let names = names.trim_start_matches('{').trim_end_matches('}');
        for name in names.split(',') {
            let name = name.split(" as ").last().unwrap().trim();
            out.insert(name.to_string(), room.to_string());
        }
    }
    out
}

/// The first identifier of the path a text starts with (`a` of `a::b`), or of each item of a
/// group (`a` and `c` of `{a::b, c}`).
fn heads(text: &str) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let text = text.trim_start();
    let Some(group) = text.strip_prefix('{') else {
        return vec![ident(text)];
    };
    // the top-level items of the group, up to its closing brace
    let (mut depth, mut items, mut item) = (0, Vec::new(), String::new());
    for c in group.chars() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => break,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(std::mem::take(&mut item));
                continue;
            }
            _ => {}
        }
        item.push(c);
    }
    items.push(item);
    items.iter().map(|i| ident(i.trim())).collect()
}

/// The modules a file at `module` names, as absolute module paths of at most two segments
/// (`crate::scene::file::X` and, from `src/scene/build.rs`, `super::file::X`, are both
/// `scene::file`); names a root re-exports are resolved to their room.
fn named_modules(
    module: &[String],
    text: &str,
    rooms: &BTreeMap<String, BTreeSet<String>>,
    exports: &BTreeMap<String, BTreeMap<String, String>>,
) -> BTreeSet<Vec<String>> {
    let mut out = BTreeSet::new();
    let mut resolve = |top: &str, rest: &str| {
        for name in heads(rest) {
            let room = if rooms.get(top).is_some_and(|r| r.contains(&name)) {
                Some(name)
            } else {
                exports.get(top).and_then(|e| e.get(&name)).cloned()
            };
            // a name of the root itself is the module's shared ground, not a room
            out.insert([top.to_string()].into_iter().chain(room).collect());
        }
    };
    let mut i = 0;
    while let Some(k) = text[i..].find("crate::") {
        let after = &text[i + k + "crate::".len()..];
        let top: String = after
            .chars()
            .take_while(|c| c.is_ascii_lowercase() || *c == '_')
            .collect();
        let rest = after[top.len()..].strip_prefix("::").unwrap_or("");
        if !top.is_empty() {
            resolve(&top, rest);
        }
        i += k + "crate::".len();
    }
    let mut i = 0;
    while let Some(k) = text[i..].find("super::") {
        let start = i + k;
        let before = text[..start].chars().next_back();
        i = start + "super::".len();
        if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':') {
            continue; // the second `super` of `super::super::`
        }
        let mut ups = 1;
        let mut rest = &text[i..];
        while let Some(r) = rest.strip_prefix("super::") {
            (ups, rest) = (ups + 1, r);
        }
        // `super` of the module a file is, so the root when a room's own file says it
        if ups == module.len() - 1 {
            resolve(&module[0], rest);
        }
    }
    out
}

/// A source text without its comments: a doc link (`[`crate::scene::Scene`]`) names a module
/// for the reader, not for the compiler, and ties no circle.
fn code(text: &str) -> String {
    text.lines()
        .map(|l| l.find("//").map_or(l, |i| &l[..i]))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The circles inside the layers: each strongly connected set of two or more modules of one
/// layer, named `{a, b}` for top-level modules and `top::{a, b}` for rooms of one module.
fn circles() -> BTreeSet<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let tops: BTreeSet<String> = files
        .iter()
        .map(|f| module_path(&f.strip_prefix(&src).unwrap().to_string_lossy())[0].clone())
        .filter(|t| layer(t).is_some())
        .collect();
    let rooms: BTreeMap<String, BTreeSet<String>> =
        tops.iter().map(|t| (t.clone(), rooms(&src, t))).collect();
    let mut exports = BTreeMap::new();
    for top in &tops {
        for root in [src.join(top).join("mod.rs"), src.join(format!("{top}.rs"))] {
            if let Ok(text) = std::fs::read_to_string(root) {
                exports.insert(top.clone(), reexports(&text, &rooms[top]));
            }
        }
    }
    // edges between top-level modules of one layer, and between rooms of one module
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in &files {
        let rel = file
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let module = module_path(&rel);
        let Some(own) = layer(&module[0]) else {
            continue;
        };
        let text = code(&std::fs::read_to_string(file).unwrap());
        for target in named_modules(&module, &text, &rooms, &exports) {
            let (top, room) = (&target[0], target.get(1));
            if *top != module[0] && layer(top) == Some(own) {
                edges
                    .entry(module[0].clone())
                    .or_default()
                    .insert(top.clone());
            } else if *top == module[0] && module.len() > 1 {
                if let Some(room) = room.filter(|r| **r != module[1]) {
                    let from = format!("{}::{}", module[0], module[1]);
                    edges
                        .entry(from)
                        .or_default()
                        .insert(format!("{top}::{room}"));
                }
            }
        }
    }
    strongly_connected(&edges)
}

/// The strongly connected sets of two or more nodes, each named by its nodes in order: `{a, b}`,
/// or `top::{a, b}` when they are rooms of one module.
fn strongly_connected(edges: &BTreeMap<String, BTreeSet<String>>) -> BTreeSet<String> {
    let reach = |from: &String| {
        let (mut seen, mut todo) = (BTreeSet::new(), vec![from.clone()]);
        while let Some(n) = todo.pop() {
            for m in edges.get(&n).into_iter().flatten() {
                if seen.insert(m.clone()) {
                    todo.push(m.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> =
        edges.keys().map(|n| (n, reach(n))).collect();
    let mut out = BTreeSet::new();
    for (n, r) in &reached {
        let set: BTreeSet<&String> = r
            .iter()
            .filter(|m| reached.get(m).is_some_and(|back| back.contains(*n)))
            .collect();
        if set.len() < 2 {
            continue;
        }
        let top = set.iter().next().unwrap().split_once("::").map(|(t, _)| t);
        let names: Vec<&str> = set
            .iter()
            .map(|m| m.split_once("::").map_or(m.as_str(), |(_, r)| r))
            .collect();
        let prefix = top.map_or(String::new(), |t| format!("{t}::"));
        out.insert(format!("{prefix}{{{}}}", names.join(", ")));
    }
    out
}

#[test]
fn no_circle_inside_a_layer_except_the_known_ones() {
    let found = circles();
    let known: BTreeSet<String> = KNOWN_CIRCLES.iter().map(|(c, _)| c.to_string()).collect();
    let new: Vec<_> = found.difference(&known).collect();
    assert!(
        new.is_empty(),
        "modules of one layer importing each other round a circle (move what both need into \
         one of them, or below both): {new:?}"
    );
    let gone: Vec<_> = known.difference(&found).collect();
    assert!(
        gone.is_empty(),
        "untied (well done): remove these from KNOWN_CIRCLES: {gone:?}"
    );
}

#[test]
fn the_scanner_sees_a_circle() {
    // the test above can fail: two rooms naming each other, through a re-export and `super`
    let rooms = BTreeMap::from([(
        "scene".to_string(),
        BTreeSet::from(["file".to_string(), "mitsuba".to_string()]),
    )]);
    let exports = BTreeMap::from([(
        "scene".to_string(),
        reexports("pub use file::{SceneError, SceneSource};", &rooms["scene"]),
    )]);
    let module = |m: &str| module_path(m);
    let from_file = named_modules(
        &module("scene/file.rs"),
        "return crate::scene::mitsuba::import(&name);",
        &rooms,
        &exports,
    );
    let from_mitsuba = named_modules(
        &module("scene/mitsuba/mod.rs"),
        "use super::{SceneError, mitsuba::X};",
        &rooms,
        &exports,
    );
    let pair = |m: &[&str]| m.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert!(from_file.contains(&pair(&["scene", "mitsuba"])));
    assert!(from_mitsuba.contains(&pair(&["scene", "file"])));
    let edges = BTreeMap::from([
        (
            "scene::file".to_string(),
            BTreeSet::from(["scene::mitsuba".to_string()]),
        ),
        (
            "scene::mitsuba".to_string(),
            BTreeSet::from(["scene::file".to_string()]),
        ),
        (
            "scene::build".to_string(),
            BTreeSet::from(["scene::file".to_string()]),
        ),
    ]);
    assert_eq!(
        strongly_connected(&edges),
        BTreeSet::from(["scene::{file, mitsuba}".to_string()])
    );
}

/// The integrator modules, which the interface module must not name.
const INTEGRATOR_MODULES: [&str; 6] = ["bdpt", "mlt", "mmlt", "path", "pssmlt", "smc"];

/// The lines of `src/integrator/mod.rs` outside its `integrators!` registration and its `mod`
/// declarations that still name an integrator module, each with the reason it is there: the
/// test fails on any other, and on a listed one that is gone (the list only shrinks).
const KNOWN_NAMED: [(&str, &str); 0] = [];

/// The lines of `text` (an interface module) outside the `integrators!` invocation and the
/// `mod` declarations that name one of `modules` as a path (`smc::`, not `crate::path::`).
fn naming_lines(text: &str, modules: &[&str]) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut in_registration = false;
    for line in text.lines() {
        let code = line.split("//").next().unwrap().trim();
        if code.starts_with("integrators! {") {
            in_registration = true;
        }
        if in_registration {
            in_registration = code != "}";
            continue;
        }
        if code.starts_with("pub mod ") || code.starts_with("mod ") {
            continue;
        }
        let names = modules.iter().any(|m| {
            code.match_indices(&format!("{m}::")).any(|(i, _)| {
                let before = code[..i].chars().next_back();
                !before.is_some_and(|c| c == ':' || c == '_' || c.is_ascii_alphanumeric())
            })
        });
        if names {
            out.insert(code.to_string());
        }
    }
    out
}

#[test]
fn the_integrator_interface_names_no_integrator_except_the_known_lines() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/integrator/mod.rs");
    let found = naming_lines(&std::fs::read_to_string(path).unwrap(), &INTEGRATOR_MODULES);
    let known: BTreeSet<String> = KNOWN_NAMED.iter().map(|(l, _)| l.to_string()).collect();
    let new: Vec<_> = found.difference(&known).collect();
    assert!(
        new.is_empty(),
        "the integrator interface names an integrator (declare it through `Facts` or the \
         `Integrator` trait in the integrator's module instead): {new:?}"
    );
    let gone: Vec<_> = known.difference(&found).collect();
    assert!(
        gone.is_empty(),
        "untied (well done): remove these from KNOWN_NAMED: {gone:?}"
    );
}

#[test]
fn the_interface_scanner_sees_a_named_integrator() {
    // the test above can fail: a name outside the registration counts, inside it and the
    // path layer's `crate::path::` do not
    let text = "integrators! {\n    Smc = \"smc\" => &smc::SmcFacts,\n}\n\
                use crate::path::PLAIN;\npub mod smc;\nfn f(r: &[smc::Record]) {}\n";
    assert_eq!(
        naming_lines(text, &INTEGRATOR_MODULES),
        BTreeSet::from(["fn f(r: &[smc::Record]) {}".to_string()])
    );
}
