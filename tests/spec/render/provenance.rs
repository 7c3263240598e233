//! Provenance and an honest merge: every EXR records its scene, integrator, settings and sample
//! streams; `merge` refuses inputs that are not independent renders of one image (another scene,
//! integrator or settings, a file twice, the same samples twice, no record) unless `--force`,
//! which warns; a merged file records its sources, the sum of their samples and seconds, and a
//! merge of merges is checked too. The same scene, seed and settings give the same bytes at any
//! thread count (`--reproducible`).
//! Book: "Measuring a renderer" (provenance, merging, determinism).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use pathspace::image_io::{self, ImageMeta};
use pathspace::integrator::{IntegratorKind, Setup};
use pathspace::path::PLAIN;
use pathspace::render::checkpoint::{Checkpoint, Identity};
use pathspace::render::provenance::{self, Conflict, Provenance, Streams};
use pathspace::render::session::{self, Control, Job};
use pathspace::scene::SceneSource;

use crate::common;
use common::cli::{pathspace, scratch, stderr};

/// The prefix of this file's scratch directories.
const GROUP: &str = "provenance";

const FOG_BOX: &str = include_str!("../../../scenes/fog-box.toml");

/// Renders the fog box (or `scene`) at 12x12 into `dir/name` with `extra` options.
fn render_scene(dir: &Path, name: &str, scene: Option<&Path>, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["render", "--resolution", "12x12", "--threads", "1"];
    if let Some(s) = scene {
        args.push(s.to_str().unwrap());
    }
    if !extra.contains(&"--spp") {
        args.extend_from_slice(&["--spp", "4"]);
    }
    args.extend_from_slice(extra);
    args.extend_from_slice(&["-o", out.to_str().unwrap()]);
    let run = pathspace(&args);
    assert!(run.status.success(), "{}", stderr(&run));
    out
}

fn render(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    render_scene(dir, name, None, extra)
}

fn merge(inputs: &[&Path], out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["merge"];
    args.extend(inputs.iter().map(|p| p.to_str().unwrap()));
    args.extend_from_slice(&["-o", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    pathspace(&args)
}

fn meta(p: &Path) -> ImageMeta {
    image_io::read_exr(p).unwrap().1
}

/// `merge` of `inputs` fails, writes nothing, and its message says each of `says`.
fn refused(inputs: &[&Path], says: &[&str]) {
    let out = inputs[0].with_file_name("refused.exr");
    let run = merge(inputs, &out, &[]);
    let err = stderr(&run);
    assert!(!run.status.success(), "merged: {err}");
    assert!(!out.exists(), "a refused merge wrote {}", out.display());
    for s in says {
        assert!(err.contains(s), "`{s}` not in: {err}");
    }
}

#[test]
fn every_render_records_its_provenance() {
    let dir = scratch(GROUP, "record");
    let a = render(&dir, "a.exr", &["--seed", "7"]);
    let m = meta(&a);
    assert_eq!(m.get("streams"), Some("7:0..1"), "one pass of 4 spp");
    assert_eq!(m.get("seed"), Some("7"));
    assert_eq!(m.get("spp"), Some("4"));
    assert_eq!(m.get("complete"), Some("true"));
    assert_eq!(m.get("integrator"), Some("path"));
    assert_eq!(m.get("scene_hash").map(str::len), Some(16));
    assert!(m.get("render_options").unwrap().contains("seed = 7"));
    assert!(m.get("seconds").is_some());
    // counts and times are numbers in the header itself, the rest strings
    let header = exr::meta::MetaData::read_from_file(&a, false).unwrap();
    let other = &header.headers[0].own_attributes.other;
    let value = |k: &str| other.get(&exr::meta::attribute::Text::from(k)).unwrap();
    use exr::meta::attribute::AttributeValue as V;
    assert_eq!(value("spp"), &V::I32(4));
    assert_eq!(value("nan_count"), &V::I32(0));
    assert!(matches!(value("seconds"), V::F64(s) if *s >= 0.0));
    assert!(
        matches!(value("seed"), V::Text(_)),
        "seed lists a merge's seeds"
    );
    assert!(matches!(value("scene_hash"), V::Text(_)));
}

#[test]
fn a_number_that_does_not_fit_its_type_stays_text() {
    let dir = scratch(GROUP, "numbers");
    let mut m = ImageMeta::default();
    m.set("spp", 1u64 << 40)
        .set("seconds", "NaN")
        .set("nan_count", 3);
    let p = dir.join("n.exr");
    image_io::write_exr(&p, &image_io::Image::new(1, 1), &m).unwrap();
    assert_eq!(
        meta(&p),
        m,
        "the text of every attribute reads back as written"
    );
}

/// A fresh directory `name` with a render of the fog box with seed 1 in it (`a.exr`).
fn first(name: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(GROUP, name);
    let a = render(&dir, "a.exr", &["--seed", "1"]);
    (dir, a)
}

#[test]
fn merge_refuses_a_file_given_twice() {
    let (_, a) = first("twice");
    refused(&[&a, &a], &["a.exr is given twice"]);
}

#[test]
fn merge_refuses_renders_that_hold_the_same_samples() {
    let (dir, a) = first("same-samples");
    let again = render(&dir, "again.exr", &["--seed", "1", "--spp", "8"]);
    refused(
        &[&a, &again],
        &[
            "a.exr and ",
            "again.exr hold the same samples",
            "seed 1",
            "0..1 and 0..2",
        ],
    );
}

#[test]
fn merge_refuses_another_integrator() {
    let (dir, a) = first("integrator");
    let mlt = render(&dir, "mlt.exr", &["--seed", "2", "--integrator", "mlt"]);
    refused(
        &[&a, &mlt],
        &["mlt.exr were rendered by different integrators (path and mlt)"],
    );
}

#[test]
fn merge_refuses_other_settings() {
    let (dir, a) = first("settings");
    let depth = render(&dir, "depth1.exr", &["--seed", "3", "--max-depth", "1"]);
    refused(
        &[&a, &depth],
        &["depth1.exr were rendered with different settings: max_depth: not given and 1"],
    );
}

#[test]
fn merge_refuses_another_scene_file() {
    let (dir, a) = first("scene");
    let scene = dir.join("fog-box-copy.toml");
    std::fs::write(&scene, format!("{FOG_BOX}\n# another file\n")).unwrap();
    let other = render_scene(&dir, "other.exr", Some(&scene), &["--seed", "4"]);
    refused(
        &[&a, &other],
        &["other.exr are renders of different scene files"],
    );
}

#[test]
fn merge_refuses_an_image_without_provenance() {
    let (dir, a) = first("bare");
    let bare = dir.join("bare.exr");
    let (img, _) = image_io::read_exr(&a).unwrap();
    let mut m = ImageMeta::default();
    m.set("spp", 4);
    image_io::write_exr(&bare, &img, &m).unwrap();
    refused(&[&a, &bare], &["bare.exr records no `streams`"]);
}

#[test]
fn force_merges_and_warns_what_it_let_through() {
    let dir = scratch(GROUP, "force");
    let a = render(&dir, "a.exr", &["--seed", "1"]);
    let mlt = render(&dir, "mlt.exr", &["--seed", "2", "--integrator", "mlt"]);
    let out = dir.join("forced.exr");
    let run = merge(&[&a, &mlt], &out, &["--force"]);
    let err = stderr(&run);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("warning: merge --force:") && err.contains("different integrators"),
        "{err}"
    );
    let forced = meta(&out);
    assert!(
        forced
            .get("merge_forced")
            .is_some_and(|f| f.contains("mlt.exr")),
        "{forced:?}"
    );
    // what was forced stays on record through a merge of merges
    let b = render(&dir, "b.exr", &["--seed", "5"]);
    let twice = dir.join("twice.exr");
    let run = merge(&[&out, &b], &twice, &["--force"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(meta(&twice)
        .get("merge_forced")
        .unwrap()
        .contains("mlt.exr"));
}

fn seconds(m: &ImageMeta) -> f64 {
    m.get("seconds").unwrap().parse().unwrap()
}

#[test]
fn disjoint_renders_merge_with_their_samples_seconds_and_sources_summed() {
    let dir = scratch(GROUP, "disjoint");
    let a = render(&dir, "a.exr", &["--seed", "1"]);
    // b takes long enough that its time is not 0.000 s
    let b = render(&dir, "b.exr", &["--seed", "2", "--spp", "64"]);
    let ab = dir.join("ab.exr");
    let run = merge(&[&a, &b], &ab, &[]);
    assert!(run.status.success(), "{}", stderr(&run));
    let (ma, mb, m) = (meta(&a), meta(&b), meta(&ab));
    assert_eq!(m.get("spp"), Some("68"));
    assert_eq!(m.get("seed"), Some("1,2"));
    assert_eq!(m.get("streams"), Some("1:0..1,2:0..16"));
    assert!(seconds(&mb) > 0.0);
    // milliseconds in every header, so the sum is exact to the print
    let sum = seconds(&ma) + seconds(&mb);
    assert!((seconds(&m) - sum).abs() < 1e-9, "{} vs {sum}", seconds(&m));
    let merged = Provenance::read("ab.exr", &m).unwrap();
    let files: Vec<(&str, u64, &str)> = merged
        .sources
        .iter()
        .map(|s| (s.file.as_str(), s.spp, s.streams.as_str()))
        .collect();
    let (fa, fb) = (a.display().to_string(), b.display().to_string());
    assert_eq!(
        files,
        [
            (format!("ab.exr > {fa}").as_str(), 4, "1:0..1"),
            (format!("ab.exr > {fb}").as_str(), 64, "2:0..16"),
        ]
    );

    // a merge of merges is checked against every source, and records them all
    let c = render(&dir, "c.exr", &["--seed", "3"]);
    let abc = dir.join("abc.exr");
    let run = merge(&[&ab, &c], &abc, &[]);
    assert!(run.status.success(), "{}", stderr(&run));
    let m = meta(&abc);
    assert_eq!(m.get("spp"), Some("72"));
    assert_eq!(m.get("streams"), Some("1:0..1,2:0..16,3:0..1"));
    assert_eq!(Provenance::read("abc", &m).unwrap().sources.len(), 3);
    refused(
        &[&ab, &a],
        &["ab.exr and ", "a.exr hold the same samples", "seed 1"],
    );
}

fn record(file: &str, streams: &str) -> Provenance {
    let mut m = ImageMeta::default();
    m.set("scene_hash", "00000000000000aa")
        .set("integrator", "path")
        .set("render_options", "[render]\nspp = 8\n")
        .set("spp", 8)
        .set("streams", streams);
    Provenance::read(file, &m).unwrap()
}

#[test]
fn disjoint_parts_of_one_run_merge_and_overlapping_parts_do_not() {
    // passes 0..4 and 4..8 of seed 9 (shards, or a run and its continuation) are one run
    let parts = [record("p0", "9:0..4"), record("p1", "9:4..8")];
    assert_eq!(provenance::conflicts(&parts), []);
    let m = provenance::merged_record(&parts, &ImageMeta::default(), &[]);
    assert_eq!(m.get("streams"), Some("9:0..8"));
    let overlapping = [record("p0", "9:0..4"), record("p1", "9:3..8")];
    assert!(matches!(
        provenance::conflicts(&overlapping)[..],
        [Conflict::Overlap { seed: 9, .. }]
    ));
    let s = |seed, first, end| Streams { seed, first, end };
    assert!(!s(1, 0, 4).overlaps(&s(2, 0, 4)), "other seeds");
    assert!(s(1, 0, 4).overlaps(&s(1, 0, 1)));
}

/// Two renders with `extra` at 1 and 2 threads give the same EXR and PNG bytes.
fn same_bytes_across_threads(name: &str, extra: &[&str]) {
    let dir = scratch(GROUP, name);
    let file = |t: &str, ext: &str| dir.join(format!("t{t}.{ext}"));
    for t in ["1", "2"] {
        let (exr, png) = (file(t, "exr"), file(t, "png"));
        let mut args = vec![
            "render",
            "--resolution",
            "16x16",
            "--spp",
            "8",
            "--seed",
            "4",
        ];
        args.extend_from_slice(&["--reproducible", "--threads", t]);
        args.extend_from_slice(&["-o", exr.to_str().unwrap(), "--png", png.to_str().unwrap()]);
        args.extend_from_slice(extra);
        let run = pathspace(&args);
        assert!(run.status.success(), "{}", stderr(&run));
    }
    assert_eq!(meta(&file("1", "exr")).get("seconds"), None, "a timing");
    for ext in ["exr", "png"] {
        let (a, b) = (file("1", ext), file("2", ext));
        let same = Command::new("cmp").arg(&a).arg(&b).status().unwrap();
        assert!(
            same.success(),
            "{name}: {} and {} differ",
            a.display(),
            b.display()
        );
    }
}

#[test]
fn the_same_seed_gives_the_same_bytes_at_any_thread_count() {
    same_bytes_across_threads("bytes-path", &[]);
    same_bytes_across_threads("bytes-bdpt", &["--integrator", "bdpt"]);
    same_bytes_across_threads("bytes-mlt", &["--integrator", "mlt"]);
}

/// The streams a render of the fog box at 8x8 records after `spp`, resumed from a checkpoint
/// after `first` when given.
fn streams_of(kind: IntegratorKind, spp: u32, first: Option<u32>) -> Vec<Streams> {
    let src = SceneSource::embedded("fog-box.toml", FOG_BOX);
    let (mut scene, settings) = pathspace::integrator::settings::load(&src).unwrap();
    scene.camera = scene.camera.as_ref().unwrap().with_resolution(8, 8);
    let setup = Setup {
        scene: &scene,
        technique: &PLAIN,
        settings: &settings,
        seed: 5,
        max_depth: Some(4),
    };
    let job = |spp| Job {
        kind,
        setup,
        spp,
        time: None,
        first_pass: 0,
        progress: false,
    };
    let identity = Identity {
        scene_hash: 1,
        inputs: Vec::new(),
        integrator: kind.name().into(),
        options: String::new(),
        seed: 5,
        film: Some((8, 8)),
        meters: 0,
    };
    let resume = first.map(|n| {
        let control = Control {
            identity: Some(identity),
            ..Default::default()
        };
        let ended = session::render_with(&job(n), control).unwrap();
        ended.checkpoint.unwrap()
    });
    let control = Control {
        resume,
        ..Default::default()
    };
    session::render_with(&job(spp), control)
        .unwrap()
        .result
        .streams
}

#[test]
fn a_resumed_render_records_its_runs() {
    let s = |seed, first, end| Streams { seed, first, end };
    // path continues its passes: the resumed render holds the uninterrupted one's streams
    assert_eq!(streams_of(IntegratorKind::Path, 16, None), [s(5, 0, 4)]);
    assert_eq!(streams_of(IntegratorKind::Path, 16, Some(8)), [s(5, 0, 4)]);
    // a resumed MLT run is an independent run with a seed of its own
    let second = Checkpoint::resume_seed(5, 1);
    assert_eq!(
        streams_of(IntegratorKind::Mlt, 16, Some(8)),
        [s(5, 0, 2), s(second, 0, 2)]
    );
}

#[test]
fn merge_checks_its_output_before_reading_the_inputs() {
    let dir = scratch(GROUP, "output");
    let run = merge(&[&dir.join("missing.exr")], &dir.join("out.png"), &[]);
    let err = stderr(&run);
    assert!(!run.status.success());
    assert!(err.contains("out.png: is written as EXR"), "{err}");
}

/// `path` rewritten with `change` applied to its image and header (a forged or damaged file).
fn forge(
    path: &Path,
    name: &str,
    change: impl FnOnce(&mut image_io::Image, &mut ImageMeta),
) -> PathBuf {
    let (mut img, mut m) = image_io::read_exr(path).unwrap();
    change(&mut img, &mut m);
    let out = path.with_file_name(name);
    image_io::write_exr(&out, &img, &m).unwrap();
    out
}

/// `merge` trusts nothing it reads: a shard of a billion-shard render is refused with the
/// missing shards as one range (not a billion entries), sample counts that overflow and a
/// pixel that is not finite are refused naming the file.
#[test]
fn merge_bounds_its_work_and_refuses_forged_counts_and_pixels() {
    let dir = scratch(GROUP, "forged");
    let a = render(
        &dir,
        "a.exr",
        &["--seed", "1", "--spp", "8", "--shard", "1/2"],
    );
    let huge = forge(&a, "huge.exr", |_, m| {
        m.set("shard", "1/1000000000");
    });
    let out = dir.join("m.exr");
    let run = merge(&[&huge], &out, &[]);
    let err = stderr(&run);
    assert!(!run.status.success() && !out.exists(), "{err}");
    assert!(
        err.contains("2/1000000000 to 1000000000/1000000000 (999999999 shards)"),
        "{err}"
    );
    assert!(err.len() < 2_000, "{} bytes of error", err.len());
    let b = render(&dir, "b.exr", &["--seed", "2"]);
    let c = render(&dir, "c.exr", &["--seed", "3"]);
    // the passes of the forged record could hold that many samples: only the sum overflows
    let max = forge(&c, "max.exr", |_, m| {
        m.set("spp", u64::MAX);
        m.set("streams", format!("3:0..{}", u64::MAX));
    });
    refused(&[&b, &max], &["add up beyond 2^64"]);
    let nan = forge(&c, "nan.exr", |img, _| img.pixels[13].y = f32::NAN);
    refused(&[&b, &nan], &["nan.exr: the pixel (1, 1) is not finite"]);
}

/// A sample count its passes cannot hold (`spp` against `streams`: 1 to 4 samples a pass) is
/// refused, whether forged high or low; a file whose record and pixels agree merges.
#[test]
fn merge_refuses_a_sample_count_its_streams_cannot_hold() {
    let dir = scratch(GROUP, "spp-streams");
    let b = render(&dir, "b.exr", &["--seed", "2", "--spp", "6"]);
    let c = render(&dir, "c.exr", &["--seed", "3", "--spp", "6"]);
    for (name, spp) in [("high.exr", 1u64 << 30), ("nine.exr", 9), ("one.exr", 1)] {
        let forged = forge(&c, name, |_, m| {
            m.set("spp", spp);
        });
        let says = format!("{name}: `spp` = {spp} cannot come from the 2 passes");
        refused(&[&b, &forged], &[&says]);
    }
    for spp in [2u64, 8] {
        let edge = forge(&c, "edge.exr", |_, m| {
            m.set("spp", spp);
        });
        let run = merge(&[&b, &edge], &dir.join("m.exr"), &[]);
        assert!(run.status.success(), "spp {spp}: {}", stderr(&run));
    }
}

/// Every byte of a render's file after its header is covered by the checksums pathspace writes
/// (`checksum`: the record and R, G, B; `checksum_layers`: the layers of `--aovs`): changing
/// the lowest bit of any one of them, which gives a finite value a little off where it lands in
/// a pixel, makes `merge` refuse the file as damaged, naming it, where before it merged it
/// (or changes no value read).
#[test]
fn a_changed_byte_anywhere_in_the_data_is_refused_as_damage() {
    let dir = scratch(GROUP, "flipped");
    let b = render(&dir, "b.exr", &["--seed", "2"]);
    // a noisy image does not compress: its chunks are stored raw, where a changed bit is a
    // changed value that no decompressor can notice
    let c = render(&dir, "c.exr", &["--seed", "3"]);
    let d = render(&dir, "d.exr", &["--seed", "4", "--aovs", "albedo,depth"]);
    let flipped = dir.join("flipped.exr");
    for file in [&c, &d] {
        let refused_at = changed_bytes_are_found(file, &flipped);
        if file == &c {
            let bytes = std::fs::read(file).unwrap();
            let mut damaged = bytes.clone();
            damaged[refused_at.expect("no byte of the raw chunks was found by a checksum")] ^= 1;
            std::fs::write(&flipped, &damaged).unwrap();
            refused(&[&b, &flipped], &["flipped.exr: the file is damaged"]);
            // a changed record is damage too, even one that still parses (4 samples read as 5)
            let mut damaged = bytes.clone();
            let spp = find(&damaged, b"spp\0int\0").unwrap() + 8 + 4;
            damaged[spp] ^= 1;
            std::fs::write(&flipped, &damaged).unwrap();
            refused(&[&b, &flipped], &["flipped.exr: the file is damaged"]);
        }
    }
}

/// Flips the lowest bit of each byte of `file` after its header in turn (into `flipped`): none
/// may read as other values; returns the first byte a checksum found.
fn changed_bytes_are_found(file: &Path, flipped: &Path) -> Option<usize> {
    let bytes = std::fs::read(file).unwrap();
    let read_all = |p: &Path| (image_io::read_exr(p), image_io::read_exr_channels(p));
    let (Ok(expected), Ok(layers)) = read_all(file) else {
        panic!("{} cannot be read", file.display())
    };
    let (mut wrong, mut refused_at) = (Vec::new(), None);
    for at in header_length(&bytes)..bytes.len() {
        let mut damaged = bytes.clone();
        damaged[at] ^= 1;
        std::fs::write(flipped, &damaged).unwrap();
        match read_all(flipped) {
            // a byte no value depends on (the deflate stream's unused bits) changes nothing
            (Ok(m), Ok(l)) if m.0.pixels == expected.0.pixels && l == layers => {}
            (Ok(_), Ok(_)) => wrong.push(at),
            // a value changed (not the file's structure, which the reader finds itself)
            (Err(e), _) | (_, Err(e)) if e.to_string().contains("damaged") => {
                refused_at = refused_at.or(Some(at))
            }
            _ => {}
        }
    }
    assert!(
        wrong.is_empty(),
        "{}: read wrong values with {} byte(s) changed, the first {:?}",
        file.display(),
        wrong.len(),
        &wrong[..wrong.len().min(8)]
    );
    refused_at
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The length of a single-part EXR's header and offset table (where its chunks start): the
/// attributes, each `name\0type\0size value`, end with an empty name, and the offsets of
/// the chunks follow, 8 bytes each.
fn header_length(bytes: &[u8]) -> usize {
    let mut at = 8;
    let nul = |from: usize| from + bytes[from..].iter().position(|&b| b == 0).unwrap();
    while bytes[at] != 0 {
        let type_end = nul(nul(at) + 1);
        let size = i32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap());
        at = type_end + 5 + size as usize;
    }
    let first_chunk = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap());
    first_chunk as usize
}

/// `merge` refuses two renders of one scene text whose mesh file differed between them, naming
/// the file; renders of the same files merge.
#[test]
fn merge_refuses_renders_whose_scene_read_another_file_content() {
    let dir = scratch(GROUP, "inputs");
    let cube = std::fs::read_to_string("tests/fixtures/cube.obj").unwrap();
    std::fs::write(dir.join("cube.obj"), &cube).unwrap();
    let fog = include_str!("../../../scenes/fog-box.toml");
    let scene = dir.join("scene.toml");
    let mesh = "[[shapes]]\ntype = \"mesh\"\nobj = \"cube.obj\"\nmaterial = \"white\"\n";
    std::fs::write(&scene, format!("{fog}\n{mesh}")).unwrap();
    let a = render_scene(&dir, "a.exr", Some(&scene), &["--seed", "1"]);
    let b = render_scene(&dir, "b.exr", Some(&scene), &["--seed", "2"]);
    assert!(meta(&a)
        .get("scene_inputs")
        .unwrap()
        .starts_with("cube.obj="));
    assert!(merge(&[&a, &b], &dir.join("ab.exr"), &[]).status.success());
    std::fs::write(dir.join("cube.obj"), format!("{cube}\n# edited\n")).unwrap();
    let c = render_scene(&dir, "c.exr", Some(&scene), &["--seed", "3"]);
    refused(&[&a, &c], &["whose file cube.obj differs"]);
}

/// The same for an environment map: its EXR is hashed as the scene reads it, and `merge`
/// names it when it changed between two renders.
#[test]
fn merge_refuses_renders_whose_environment_map_changed() {
    let dir = scratch(GROUP, "map");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let scene = dir.join("envmap.toml");
    std::fs::copy(root.join("envmap.toml"), &scene).unwrap();
    let map = dir.join("envmap-sky.exr");
    std::fs::copy(root.join("envmap-sky.exr"), &map).unwrap();
    let a = render_scene(&dir, "a.exr", Some(&scene), &["--seed", "1"]);
    assert!(meta(&a)
        .get("scene_inputs")
        .unwrap()
        .starts_with("envmap-sky.exr="));
    let (mut sky, m) = image_io::read_exr(&map).unwrap();
    sky.pixels[0].x += 1.0;
    image_io::write_exr(&map, &sky, &m).unwrap();
    let b = render_scene(&dir, "b.exr", Some(&scene), &["--seed", "2"]);
    refused(&[&a, &b], &["whose file envmap-sky.exr differs"]);
}

/// Every kind of file a scene reads is in its identity, not only OBJ meshes and environment
/// maps: a PLY mesh, a text density grid and a Mitsuba `.vol` grid changed between two renders
/// of one scene text make `merge` refuse them, naming the file.
#[test]
fn merge_refuses_a_change_to_a_ply_mesh_a_text_grid_or_a_vol_grid() {
    use pathspace::medium::grid::{encode_vol, Grid};
    let dir = scratch(GROUP, "input-kinds");
    let grid_scene = include_str!("../../fixtures/agreement/grid.toml");
    let blob = include_str!("../../fixtures/agreement/blob.grid");
    let ply = |z: f32| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
             end_header\n0 0 {z}\n1 0 {z}\n0 1 {z}\n3 0 1 2\n"
        )
        .into_bytes()
    };
    let mesh = "[[shapes]]\ntype = \"mesh\"\nobj = \"tri.ply\"\nmaterial = \"white\"\n";
    let vol = |v: f32| {
        encode_vol(
            &Grid::bake(4, |_| v),
            glam::Vec3::splat(-0.8),
            glam::Vec3::splat(0.8),
        )
    };
    let cases: [(&str, String, Vec<u8>, Vec<u8>); 3] = [
        ("tri.ply", format!("{FOG_BOX}\n{mesh}"), ply(0.0), ply(0.5)),
        (
            "blob.grid",
            grid_scene.to_string(),
            blob.into(),
            format!("{blob}\n# edited\n").into(),
        ),
        (
            "blob.vol",
            grid_scene.replace("blob.grid", "blob.vol"),
            vol(0.5),
            vol(0.6),
        ),
    ];
    for (file, text, before, after) in cases {
        let case = dir.join(file.replace('.', "-"));
        std::fs::create_dir_all(&case).unwrap();
        let scene = case.join("scene.toml");
        std::fs::write(&scene, text).unwrap();
        std::fs::write(case.join(file), before).unwrap();
        let a = render_scene(&case, "a.exr", Some(&scene), &["--seed", "1"]);
        std::fs::write(case.join(file), after).unwrap();
        let b = render_scene(&case, "b.exr", Some(&scene), &["--seed", "2"]);
        refused(&[&a, &b], &[&format!("whose file {file} differs")]);
    }
}
