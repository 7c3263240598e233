//! The book's diagrams are drawn by `pathspace::figures` from the code they illustrate; the
//! committed SVGs under `book/src/figures/diagrams/` must be exactly what it draws now, so a
//! change to the sampling code that moves a figure fails here until the figure is regenerated
//! (`cargo run --release --example figures -- book/src/figures/diagrams`).

use std::path::Path;

use pathspace::figures::{self, figure_2_path};
use pathspace::path::{characteristic, VertexKind};
use pathspace::scene::{Scene, SceneSource};

fn load(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    Scene::load(&SceneSource::read(&path).unwrap()).unwrap()
}

#[test]
fn committed_diagrams_are_what_the_code_draws() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("book/src/figures/diagrams");
    let all = figures::all(&load("fog-box.toml"), &load("cloud.toml")).unwrap();
    assert!(!all.is_empty());
    for f in all {
        let committed =
            std::fs::read_to_string(dir.join(f.name)).unwrap_or_else(|e| panic!("{}: {e}", f.name));
        assert!(
            committed == f.svg,
            "book/src/figures/diagrams/{} differs from what pathspace::figures draws; \
             regenerate with `cargo run --release --example figures -- book/src/figures/diagrams`",
            f.name
        );
    }
}

/// The drawn path is the one the caption names: light, surface, medium, camera (l = 11).
#[test]
fn the_figure_2_path_has_characteristic_eleven() {
    let path = figure_2_path(&load("fog-box.toml")).expect("a path of characteristic 11");
    assert_eq!(characteristic(&path), 0b1011);
    assert!(matches!(path[0].kind, VertexKind::Light { .. }));
    assert!(matches!(path[1].kind, VertexKind::Surface { .. }));
    assert!(path[2].is_medium() && path[3].is_sensor());
}
