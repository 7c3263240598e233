//! `medium::vdb`: OpenVDB float grids read into the density lattice, checked against what the
//! OpenVDB library itself reads from the same files (`tests/fixtures/vdb/NAME.vol`, written by
//! `scripts/make_vdb_fixtures.py` from OpenVDB's accessor), and a VDB medium rendering bit for
//! bit like the same lattice given as a `.vol`.

use pathspace::integrator::{IntegratorKind, Renderer};
use pathspace::medium::grid::{parse_vol, read_grid_file};
use pathspace::medium::vdb::parse_vdb;
use pathspace::scene::{Scene, SceneSource};
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vdb")
}

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(fixtures().join(name)).unwrap()
}

/// Every compression OpenVDB writes (Blosc-LZ4, zip, none; floats and halves; a file of two
/// grids) reads into the lattice OpenVDB's own accessor gives, value for value, with its box.
#[test]
fn openvdb_files_read_as_openvdb_reads_them() {
    for name in ["blosc", "zip", "none", "half", "two_grids"] {
        let got = parse_vdb(&bytes(&format!("{name}.vdb")), "density")
            .unwrap_or_else(|e| panic!("{name}.vdb: {e:?}"));
        let want = read_grid_file(&fixtures().join(format!("{name}.vol"))).unwrap();
        assert_eq!(got.grid.res, want.grid.res, "{name}: lattice");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&got.grid.values),
            bits(&want.grid.values),
            "{name}: values"
        );
        assert_eq!(got.bounds, want.bounds, "{name}: box");
    }
}

/// The fixtures exercise what they claim: leaf values, the tile, an inactive value that is not
/// the background, and half floats that differ from the floats.
#[test]
fn the_fixtures_hold_tiles_inactive_values_and_halves() {
    let f = parse_vol(&bytes("blosc.vol")).unwrap().grid;
    let h = parse_vol(&bytes("half.vol")).unwrap().grid;
    let at = |g: &pathspace::medium::Grid, ijk: [usize; 3]| {
        // lattice vertex (0,0,0) is voxel (-1,-1,-1)
        let [x, y, z] = ijk.map(|c| c + 1);
        g.values[x + g.res[0] * (y + g.res[1] * z)]
    };
    assert_eq!(f.res, [18, 10, 10]);
    assert_eq!(at(&f, [12, 4, 4]), 0.7, "the tile");
    assert_eq!(at(&f, [2, 2, 2]), 0.3, "an inactive voxel's value");
    assert_eq!(at(&f, [1, 1, 1]), 0.0, "an inactive background voxel");
    assert_ne!(
        at(&f, [7, 7, 7]),
        at(&h, [7, 7, 7]),
        "half floats are rounded"
    );
}

/// Another grid of the file is read by name; an unknown name is refused listing the grids.
#[test]
fn grids_are_found_by_name() {
    let b = bytes("two_grids.vdb");
    let t = parse_vdb(&b, "temperature").unwrap();
    assert_eq!(t.grid.res, [6, 6, 6]);
    assert_eq!(t.grid.values.iter().copied().fold(0.0, f32::max), 2.0);
    let (_, msg) = parse_vdb(&b, "smoke").err().unwrap();
    assert!(
        msg.contains("\"temperature\"") && msg.contains("\"density\""),
        "{msg}"
    );
}

fn load(dir: &Path, text: &str) -> Scene {
    let src = SceneSource {
        name: "vdb.toml".into(),
        text: text.into(),
        base_dir: dir.to_path_buf(),
        origin: None,
        inputs: Default::default(),
    };
    Scene::load(&src).unwrap_or_else(|e| panic!("{e}"))
}

fn image_bits(scene: &Scene, kind: IntegratorKind) -> Vec<[u32; 3]> {
    let mut r = Renderer::new(scene, kind, 7, None);
    r.pass(4, &|| {});
    let img = r.film.as_ref().unwrap().image();
    img.pixels
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

/// A `.vdb` medium renders bit for bit like the `.vol` of the same values and box (path
/// tracing with delta tracking and BDPT): the reader feeds the grid medium and its majorant
/// exactly what a `.vol` does.
#[test]
fn a_vdb_medium_renders_bit_for_bit_like_the_same_vol() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/agreement");
    let vdb = std::fs::read_to_string(dir.join("vdb.toml")).unwrap();
    let vol = vdb.replace(
        "type = \"vdb\"\nfile = \"../vdb/blosc.vdb\"",
        "type = \"grid\"\nfile = \"../vdb/blosc.vol\"",
    );
    assert_ne!(vol, vdb);
    let (a, b) = (load(&dir, &vdb), load(&dir, &vol));
    for kind in [IntegratorKind::Path, IntegratorKind::Bdpt] {
        let (ia, ib) = (image_bits(&a, kind), image_bits(&b, kind));
        assert!(ia.iter().any(|p| p[0] != 0), "{kind:?}: a lit image");
        assert_eq!(ia, ib, "{kind:?}: vdb and vol images differ");
    }
}
