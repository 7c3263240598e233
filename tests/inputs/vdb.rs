//! OpenVDB files that are cut, damaged or lie about their sizes: each is refused with an error
//! naming the file and what is wrong (never a panic, never an allocation the file cannot back),
//! and through a scene the error names the scene file and the medium's `file` key too.

use pathspace::medium::vdb::parse_vdb;
use pathspace::scene::{Scene, SceneError, SceneSource};
use std::path::PathBuf;

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/vdb")
}

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(fixtures().join(name)).unwrap()
}

/// `parse_vdb`'s message for `b`, which must be refused, containing every one of `words`.
#[track_caller]
fn refused(b: &[u8], words: &[&str]) -> String {
    let (loc, msg) = match parse_vdb(b, "density") {
        Ok(_) => panic!("accepted, but should be refused with {words:?}"),
        Err(e) => e,
    };
    let text = format!("{loc}: {msg}");
    for w in words {
        assert!(text.contains(w), "`{text}` lacks `{w}`");
    }
    text
}

/// Every prefix of every fixture is refused (cut anywhere: in the header, a mask, a
/// compressed array), naming a byte offset or the whole file.
#[test]
fn truncated_files_are_refused_at_every_length() {
    // every length of the Blosc files, every 7th of the others (a parse costs ~0.3 ms)
    for (name, step) in [
        ("blosc.vdb", 1),
        ("half.vdb", 1),
        ("zip.vdb", 7),
        ("none.vdb", 7),
    ] {
        let b = bytes(name);
        for n in (0..b.len() - 1).step_by(step) {
            let t = refused(&b[..n], &[]);
            assert!(!t.is_empty(), "{name} cut at {n}");
        }
    }
}

/// Every byte of the fixtures inverted in turn: read or refused, never a panic; what is read
/// is a valid lattice (finite densities >= 0, by `Grid::new`).
#[test]
fn damaged_bytes_are_read_or_refused_never_a_panic() {
    // every byte of OpenVDB's default (Blosc), every 5th of the zip and half files
    for (name, step) in [("blosc.vdb", 1), ("zip.vdb", 5), ("half.vdb", 5)] {
        let b = bytes(name);
        for i in (0..b.len()).step_by(step) {
            let mut d = b.clone();
            d[i] ^= 0xff;
            if let Ok(g) = parse_vdb(&d, "density") {
                assert!(g.grid.values.iter().all(|v| v.is_finite() && *v >= 0.0));
            }
        }
    }
}

#[test]
fn a_wrong_magic_number_is_not_an_openvdb_file() {
    let mut b = bytes("blosc.vdb");
    b[1] = b'X';
    refused(&b, &["byte offset 0", "not an OpenVDB file"]);
    refused(b"VOL\x03", &["not an OpenVDB file"]);
}

/// Sizes the file cannot back: a string of 4 GiB, a compressed array longer than the file, a
/// 4096^3 active region held by one tile in a 594-byte file (OpenVDB wrote it).
#[test]
fn huge_sizes_are_refused_before_they_are_allocated() {
    let b = bytes("blosc.vdb");
    // the first grid's name length, after the header (61 bytes) and the grid count
    let mut s = b.clone();
    s[65..69].copy_from_slice(&u32::MAX.to_le_bytes());
    refused(
        &s,
        &["byte offset 65", "a grid name needs 4294967295 bytes"],
    );
    let huge = bytes("huge.vdb");
    refused(&huge, &["span [4098, 4098, 4098]", "at most 1024"]);
}

#[test]
fn unsupported_grids_are_refused_with_the_reason() {
    refused(&bytes("rotated.vdb"), &["affine transform with rotation"]);
    let mut b = bytes("blosc.vdb");
    let at = b
        .windows(16)
        .position(|w| w == b"Tree_float_5_4_3")
        .unwrap();
    b[at + 5..at + 10].copy_from_slice(b"int32");
    refused(&b, &["type \"Tree_int32_5_4_3\"", "float grids"]);
    refused(&b, &["byte offset"]);
}

fn load(text: &str) -> Result<Scene, SceneError> {
    let mut src = SceneSource::embedded("smoke.toml", text);
    src.base_dir = fixtures();
    Scene::load(&src)
}

/// Through a scene: the scene file, the line and key of `file`, the `.vdb` and the reason.
#[test]
fn a_scene_names_the_vdb_file_and_its_key() {
    let text = |file: &str, grid: &str| {
        format!("[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 40.0\nresolution = [4, 4]\n\n[media.smoke]\ntype = \"vdb\"\nfile = \"{file}\"\n{grid}sigma_a = 0.1\nsigma_s = 1.0\n")
    };
    assert!(load(&text("blosc.vdb", "")).is_ok());
    let e = load(&text("huge.vdb", "")).err().unwrap();
    assert_eq!(
        (e.file.as_str(), e.line, e.key.as_str()),
        ("smoke.toml", Some(10), "media.smoke.file"),
        "{e}"
    );
    assert!(
        e.message.contains("huge.vdb") && e.message.contains("span"),
        "{e}"
    );
    let e = load(&text("two_grids.vdb", "grid = \"smoke\"\n"))
        .err()
        .unwrap();
    assert!(e.message.contains("no grid named \"smoke\""), "{e}");
    let e = load(&text("absent.vdb", "")).err().unwrap();
    assert!(
        e.message.contains("absent.vdb") && e.message.contains("cannot read"),
        "{e}"
    );
}
