//! The book's diagrams are drawn by `pathspace::figures` from the code they illustrate; the
//! committed SVGs under `book/src/figures/diagrams/` must be exactly what it draws now, so a
//! change to the sampling code that moves a figure fails here until the figure is regenerated
//! (`cargo run --release --example figures -- book/src/figures/diagrams`). Every diagram a
//! chapter names must be one of them, and every core chapter must show at least one.

use std::collections::BTreeSet;
use std::path::Path;

use pathspace::figures::{self, figure_2_path, multichain_seed, mutation_proposal, Scenes};
use pathspace::integrator::mlt::mutation::{MutationKind, Workspace};
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::path::{characteristic, VertexKind, PLAIN};

const REGENERATE: &str = "cargo run --release --example figures -- book/src/figures/diagrams";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn scenes() -> Scenes {
    Scenes::load(root()).unwrap()
}

/// The chapters the course is built on: each must show a diagram drawn from the code.
const CORE_CHAPTERS: [&str; 11] = [
    "transport-equations.md",
    "table1-homogeneous.md",
    "table1-inhomogeneous.md",
    "neumann-series.md",
    "path-space.md",
    "bdpt.md",
    "mlt.md",
    "smc-cache.md",
    "smc-estimators.md",
    "enlightened-adjoint.md",
    "enlightened-guiding.md",
];

/// The diagram file names a chapter's markdown names (`figures/diagrams/NAME.svg`).
fn diagrams_named(markdown: &str) -> BTreeSet<String> {
    const KEY: &str = "figures/diagrams/";
    let mut out = BTreeSet::new();
    let mut rest = markdown;
    while let Some(i) = rest.find(KEY) {
        rest = &rest[i + KEY.len()..];
        let end = rest.find(".svg").map_or(0, |e| e + 4);
        out.insert(rest[..end].to_string());
    }
    out
}

#[test]
fn committed_diagrams_are_what_the_code_draws() {
    let dir = root().join("book/src/figures/diagrams");
    let all = figures::all(&scenes()).unwrap();
    assert!(!all.is_empty());
    for f in all {
        let committed =
            std::fs::read_to_string(dir.join(f.name)).unwrap_or_else(|e| panic!("{}: {e}", f.name));
        assert!(
            committed == f.svg,
            "book/src/figures/diagrams/{} differs from what pathspace::figures draws; \
             regenerate with `{REGENERATE}`",
            f.name
        );
    }
}

/// Every diagram a chapter names is drawn by the code, every drawn one is used, and every
/// core chapter shows one.
#[test]
fn chapters_name_only_drawn_diagrams_and_each_core_chapter_has_one() {
    let drawn: BTreeSet<String> = figures::all(&scenes())
        .unwrap()
        .iter()
        .map(|f| f.name.to_string())
        .collect();
    let mut used = BTreeSet::new();
    for entry in std::fs::read_dir(root().join("book/src")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "md") {
            continue;
        }
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let named = diagrams_named(&std::fs::read_to_string(&path).unwrap());
        for d in &named {
            assert!(
                drawn.contains(d),
                "{name} names {d}, which `{REGENERATE}` does not draw"
            );
        }
        if CORE_CHAPTERS.contains(&name.as_str()) {
            assert!(!named.is_empty(), "core chapter {name} shows no diagram");
        }
        used.extend(named);
    }
    let unused: Vec<_> = drawn.difference(&used).collect();
    assert!(unused.is_empty(), "diagrams no chapter shows: {unused:?}");
}

/// The drawn path is the one the caption names: light, surface, medium, camera (l = 11).
#[test]
fn the_figure_2_path_has_characteristic_eleven() {
    let s = scenes();
    let path = figure_2_path(&s.fog_box).expect("a path of characteristic 11");
    assert_eq!(characteristic(&path), 0b1011);
    assert!(matches!(path[0].kind, VertexKind::Light { .. }));
    assert!(matches!(path[1].kind, VertexKind::Surface { .. }));
    assert!(path[2].is_medium() && path[3].is_sensor());
}

/// Each mutation's figure shows a proposal its mutation can make from x: T(x -> y) > 0
/// by the mutation's own transition density, and y differs from x.
#[test]
fn each_mutation_figure_shows_a_proposal_of_that_mutation() {
    let s = scenes();
    for kind in MutationKind::ALL {
        let (scene, x) = match kind {
            MutationKind::MultiChain => (&s.sds, multichain_seed(&s.sds)),
            _ => (&s.fog_box, figure_2_path(&s.fog_box)),
        };
        let x = x.unwrap_or_else(|| panic!("{}: no path x", kind.name()));
        let y = mutation_proposal(scene, kind, &x)
            .unwrap_or_else(|| panic!("{}: no proposal", kind.name()));
        let mlt = Mlt::new(scene, &PLAIN, MltSettings::default(), figures::SEED, None).unwrap();
        let m = mlt.mutations.get(kind);
        let t = m.transition_density(scene, &PLAIN, &x, &y, &mut Workspace::default());
        assert!(t > 0.0, "{}: T(x -> y) = {t}", kind.name());
        let moved = x.len() != y.len() || x.iter().zip(&y).any(|(a, b)| a.p != b.p);
        assert!(moved, "{}: y = x", kind.name());
    }
}
