//! Shards (`render|reference --shard I/N`): the N shards of a pass-based render hold the single
//! run's passes, each once, and merged equal it to float rounding (at most one f32 step per
//! pixel: each shard's EXR rounds its mean to f32, and the merge adds the shards' sums in
//! another order than the single run's film); an MLT shard is the independent run of its
//! chains; `merge` names a missing shard; what cannot be sharded is refused with the reason;
//! a stopped shard resumes from its checkpoint to the same image.
//! Book: "Measuring a renderer" (shards).

use std::path::{Path, PathBuf};

use pathspace::image_io;
use pathspace::integrator::{IntegratorKind, Setup};
use pathspace::measure::metrics::f32_steps;
use pathspace::path::PLAIN;
use pathspace::render::checkpoint::{Checkpoint, Identity};
use pathspace::render::provenance::format_streams;
use pathspace::render::session::{self, Control, Job};
use pathspace::render::shard::Shard;
use pathspace::scene::SceneSource;

use crate::common;
use common::cli::{pathspace, scratch, stderr};

const GROUP: &str = "shard";

/// Runs `pathspace ARGS -o dir/name` (with `--reproducible`), which must succeed; the EXR.
fn run(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut all = args.to_vec();
    all.extend_from_slice(&["--reproducible", "-o", out.to_str().unwrap()]);
    let done = pathspace(&all);
    assert!(done.status.success(), "{all:?}: {}", stderr(&done));
    out
}

/// Merges `inputs` into `dir/merged.exr`, which must succeed.
fn merge(dir: &Path, inputs: &[PathBuf]) -> PathBuf {
    let out = dir.join("merged.exr");
    let mut args = vec!["merge".to_string()];
    args.extend(inputs.iter().map(|p| p.display().to_string()));
    args.extend(["-o".into(), out.display().to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let done = pathspace(&args);
    assert!(done.status.success(), "merge: {}", stderr(&done));
    out
}

/// The image's channels and its header.
fn read(exr: &Path) -> (Vec<f32>, image_io::ImageMeta) {
    let (img, meta) = image_io::read_exr(exr).unwrap();
    (img.pixels.iter().flat_map(|p| p.to_array()).collect(), meta)
}

/// The largest distance in f32 steps between two images' channels.
fn largest_steps(a: &[f32], b: &[f32]) -> u64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| f32_steps(*x, *y))
        .max()
        .unwrap()
}

/// Renders `base` whole and as `n` shards, merges the shards; the merged and single images
/// and their headers.
fn whole_and_merged(dir: &Path, base: &[&str], n: u32) -> [(Vec<f32>, image_io::ImageMeta); 2] {
    let mut whole = base.to_vec();
    whole.extend_from_slice(&["--threads", "2"]);
    let single = run(dir, "single.exr", &whole);
    let shards: Vec<PathBuf> = (1..=n)
        .map(|i| {
            let s = format!("{i}/{n}");
            let mut args = base.to_vec();
            args.extend_from_slice(&["--threads", "1", "--shard", &s]);
            run(dir, &format!("shard{i}.exr"), &args)
        })
        .collect();
    [read(&merge(dir, &shards)), read(&single)]
}

#[test]
fn path_shards_merged_are_the_single_run_to_one_f32_step() {
    let dir = scratch(GROUP, "path");
    // 34 spp: 9 passes, the last of 2 spp; 4 shards of 2, 2, 2 and 3 passes
    let base = [
        "render",
        "--resolution",
        "16x12",
        "--spp",
        "34",
        "--seed",
        "7",
    ];
    let [(merged, mm), (single, sm)] = whole_and_merged(&dir, &base, 4);
    assert_eq!(largest_steps(&merged, &single), 1, "one f32 step at most");
    // the merged file holds the single run's samples, by its record
    for key in ["spp", "streams", "seed"] {
        assert_eq!(mm.get(key), sm.get(key), "{key}");
    }
    assert_eq!(sm.get("streams"), Some("7:0..9"));
    assert_eq!(mm.get("shard"), None, "the merge is no shard");
    // and the comparison can fail: another seed's shards are many steps away
    let other = scratch(GROUP, "path-other");
    let base7 = base.map(|a| if a == "7" { "8" } else { a });
    let [(merged8, _), _] = whole_and_merged(&other, &base7, 4);
    assert!(largest_steps(&merged8, &single) > 1000);
}

#[test]
fn bdpt_reference_shards_merged_are_the_single_reference_to_one_f32_step() {
    let dir = scratch(GROUP, "bdpt");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fog-box.toml");
    let base = [
        "reference",
        scene,
        "--integrator",
        "bdpt",
        "--spp",
        "12",
        "--seed",
        "3",
    ];
    // 3 passes, one per shard; BDPT's light-tracing strategies splat into the film
    let [(merged, mm), (single, sm)] = whole_and_merged(&dir, &base, 3);
    // the reference's own resolution is 32x32: small enough
    assert_eq!(largest_steps(&merged, &single), 1, "one f32 step at most");
    assert_eq!(mm.get("streams"), sm.get("streams"));
    assert_eq!(mm.get("reference"), Some("true"));
}

#[test]
fn a_shard_records_its_passes_and_merge_names_a_missing_or_overlapping_one() {
    let dir = scratch(GROUP, "missing");
    let base = [
        "render",
        "--resolution",
        "8x8",
        "--spp",
        "32",
        "--seed",
        "5",
    ];
    let shard = |i: u32, n: u32| {
        let s = format!("{i}/{n}");
        let mut args = base.to_vec();
        args.extend_from_slice(&["--shard", &s]);
        run(&dir, &format!("s{i}of{n}.exr"), &args)
    };
    let quarters: Vec<PathBuf> = (1..=4).map(|i| shard(i, 4)).collect();
    let (_, meta) = read(&quarters[2]);
    assert_eq!(meta.get("streams"), Some("5:4..6"), "shard 3/4 of 8 passes");
    assert_eq!(meta.get("spp"), Some("8"));
    assert_eq!(meta.get("shard"), Some("3/4"));
    let refused = |inputs: &[&PathBuf], says: &[&str]| {
        let mut args = vec!["merge".to_string()];
        args.extend(inputs.iter().map(|p| p.display().to_string()));
        args.extend(["-o".into(), dir.join("m.exr").display().to_string()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = pathspace(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        for s in says {
            assert!(err.contains(s), "{s:?} not in: {err}");
        }
    };
    let [q1, q2, q3, q4] = [&quarters[0], &quarters[1], &quarters[2], &quarters[3]];
    refused(
        &[q1, q2, q4],
        &["seed 5 are incomplete", "missing: 3/4 (passes 4..6)"],
    );
    // the first half (passes 0..4) holds the second quarter's passes 2..4
    let half = shard(1, 2);
    refused(
        &[&half, q2, q3, q4],
        &[
            "hold the same samples (seed 5, passes 0..4 and 2..4)",
            "2/2 (passes 4..8)",
        ],
    );
    merge(&dir, &quarters);
}

#[test]
fn what_cannot_be_sharded_is_refused_with_the_reason() {
    let fog = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fog-box.toml");
    let smc = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/smc-testbed.toml");
    let cases: [(&[&str], &str); 10] = [
        (
            &["render", "--shard", "0/4"],
            "shards are numbered from 1 to 4",
        ),
        (&["render", "--shard", "5/4"], "there are only 4 shards"),
        (&["render", "--shard", "a/b"], "\"a/b\" is not I/N"),
        (&["render", "--shard", "4"], "\"4\" is not I/N"),
        (&["render", "--shard", "1/0"], "\"1/0\" is not I/N"),
        (
            &["reference", fog, "--shard", "2/2", "--time", "5"],
            "cannot split a --time render",
        ),
        (
            &["render", smc, "--integrator", "smc", "--shard", "1/2"],
            "radiance cache",
        ),
        (
            &["render", "--spp", "8", "--shard", "1/3"],
            "only 2 passes of 4 spp",
        ),
        (
            &[
                "render",
                "--integrator",
                "mlt",
                "--mlt-chains",
                "16",
                "--shard",
                "1/3",
            ],
            "--mlt-chains (16) must be a multiple of 3",
        ),
        (
            &[
                "render",
                "--integrator",
                "mlt",
                "--spp",
                "6",
                "--shard",
                "1/4",
            ],
            "--spp (mutations per pixel) (6) must be a multiple of 4",
        ),
    ];
    for (args, says) in cases {
        let out = pathspace(args);
        let err = stderr(&out);
        assert!(!out.status.success(), "{args:?} was accepted");
        assert!(err.contains(says), "{args:?}: {says:?} not in {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn an_mlt_shard_is_the_independent_run_of_its_chains() {
    let dir = scratch(GROUP, "mlt");
    let base = [
        "render",
        "--integrator",
        "mlt",
        "--resolution",
        "12x12",
        "--mlt-bootstrap",
        "2000",
    ];
    let shard = run(
        &dir,
        "shard.exr",
        &with(
            &base,
            &[
                "--mlt-chains",
                "8",
                "--spp",
                "8",
                "--seed",
                "11",
                "--shard",
                "2/2",
            ],
        ),
    );
    // the second half of the chains and mutations, with a seed of its own
    let seed = Shard { index: 2, count: 2 }.mlt_seed(11).to_string();
    let alone = with(&base, &["--mlt-chains", "4", "--spp", "4", "--seed", &seed]);
    let run_alone = run(&dir, "alone.exr", &alone);
    let ((a, ma), (b, mb)) = (read(&shard), read(&run_alone));
    assert!(a == b, "the shard is not the run of its 4 chains and 4 spp");
    assert_eq!(ma.get("streams"), Some(format!("{seed}:0..1").as_str()));
    assert_eq!(ma.get("streams"), mb.get("streams"));
    assert_eq!(ma.get("shard_seed"), Some("11"));
}

/// `base` followed by `more`.
fn with<'a>(base: &[&'a str], more: &[&'a str]) -> Vec<&'a str> {
    [base, more].concat()
}

/// The film of shard `first_pass`.. of `spp` samples of the fog box at 12x10, rendered at
/// once or stopped after its first checkpoint (one pass) and resumed.
fn shard_film(first_pass: u64, spp: u32, stop_once: bool) -> (Vec<[f32; 3]>, String) {
    let src = SceneSource::embedded("fog.toml", include_str!("../../../scenes/fog-box.toml"));
    let (mut scene, settings) = pathspace::integrator::settings::load(&src).unwrap();
    scene.camera = scene.camera.as_ref().unwrap().with_resolution(12, 10);
    let setup = Setup {
        scene: &scene,
        technique: &PLAIN,
        settings: &settings,
        seed: 5,
        max_depth: Some(6),
    };
    let job = Job {
        kind: IntegratorKind::Path,
        setup,
        spp,
        time: None,
        first_pass,
        progress: false,
    };
    let identity = Identity {
        scene_hash: 1,
        inputs: Vec::new(),
        integrator: "path".into(),
        options: String::new(),
        seed: 5,
        film: Some((12, 10)),
        meters: 0,
    };
    let mut resume = None;
    if stop_once {
        let stop = std::sync::atomic::AtomicUsize::new(0);
        let mut on_checkpoint = |_: &session::RenderResult, _: &Checkpoint| {
            stop.store(15, std::sync::atomic::Ordering::SeqCst);
            Ok(())
        };
        let control = Control {
            stop: Some(&stop),
            every: Some(0.0),
            identity: Some(identity.clone()),
            on_checkpoint: Some(&mut on_checkpoint),
            ..Default::default()
        };
        let ended = session::render_with(&job, control).unwrap();
        assert_eq!((ended.stopped_by, ended.result.spp), (Some(15), 4));
        let bytes = ended.checkpoint.unwrap().to_bytes();
        resume = Some(Checkpoint::from_bytes(&bytes, "test").unwrap());
    }
    let control = Control {
        resume,
        ..Default::default()
    };
    let r = session::render_with(&job, control).unwrap().result;
    let pixels = r
        .image
        .unwrap()
        .pixels
        .iter()
        .map(|p| p.to_array())
        .collect();
    (pixels, format_streams(&r.streams))
}

#[test]
fn a_stopped_shard_resumes_from_its_checkpoint_to_the_same_image() {
    let whole = shard_film(3, 12, false);
    let resumed = shard_film(3, 12, true);
    assert_eq!(whole.1, "5:3..6");
    assert!(whole == resumed, "the resumed shard differs");
    // and the comparison can fail: the shard of passes 2..5 is another image
    assert!(shard_film(2, 12, false).0 != whole.0);
}

/// A convergence study split by run (`converge --shard I/N`) and merged (`merge DIR... -o DIR`)
/// is the study one process writes: the same rows, run for run, each run with its seed in the
/// whole study. With a budget below one pass every run stops after its first pass, so its row
/// (samples, relMSE) depends only on its seed and can be compared exactly; the timings cannot.
#[test]
fn a_convergence_study_split_by_run_merges_into_the_whole_study() {
    use pathspace::measure::study::read_csv;
    let dir = scratch(GROUP, "converge");
    let scene = dir.join("small.toml");
    let text = include_str!("../../../scenes/fog-box.toml").replace("[256, 256]", "[12, 12]");
    std::fs::write(&scene, text).unwrap();
    let s = scene.to_str().unwrap();
    let reference = run(&dir, "ref.exr", &["reference", s, "--spp", "16"]);
    let study = |out: &str, extra: &[&str]| {
        let o = dir.join(out);
        let mut args = vec!["converge", s, "--reference", reference.to_str().unwrap()];
        args.extend_from_slice(&["--integrators", "path,bdpt", "--budget", "0.000001"]);
        args.extend_from_slice(&[
            "--checkpoints",
            "2",
            "--runs",
            "5",
            "-o",
            o.to_str().unwrap(),
        ]);
        args.extend_from_slice(extra);
        let done = pathspace(&args);
        assert!(done.status.success(), "{args:?}: {}", stderr(&done));
        o
    };
    let whole = study("whole", &[]);
    let shards: Vec<PathBuf> = (1..=3)
        .map(|i| study(&format!("s{i}"), &["--shard", &format!("{i}/3")]))
        .collect();
    let merged = dir.join("merged");
    let mut args = vec!["merge".to_string()];
    args.extend(shards.iter().rev().map(|p| p.display().to_string()));
    args.extend(["-o".into(), merged.display().to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let done = pathspace(&args);
    assert!(done.status.success(), "merge: {}", stderr(&done));
    let key = |p: &Path| -> Vec<(String, usize, usize, u64, String)> {
        read_csv(&p.join("convergence.csv"))
            .unwrap()
            .into_iter()
            .map(|r| {
                (
                    r.integrator,
                    r.run,
                    r.checkpoint,
                    r.samples,
                    format!("{:e}", r.relmse),
                )
            })
            .collect()
    };
    let rows = key(&whole);
    assert_eq!(
        rows.len(),
        10,
        "two lines of five runs, one row each: {rows:?}"
    );
    assert_eq!(key(&merged), rows);
    // a missing shard, a shard twice, and a shard of another study are named
    let refused = |dirs: &[&PathBuf], says: &str| {
        let mut args = vec!["merge".to_string()];
        args.extend(dirs.iter().map(|p| p.display().to_string()));
        args.extend(["-o".into(), dir.join("bad").display().to_string()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let done = pathspace(&args);
        assert!(!done.status.success());
        assert!(stderr(&done).contains(says), "{}", stderr(&done));
    };
    refused(&[&shards[0], &shards[2]], "shard 2/3 is missing");
    refused(&[&shards[0], &shards[0], &shards[1]], "are both shard 1/3");
    let other = study("other", &["--shard", "2/3", "--seed", "9"]);
    refused(&[&shards[0], &other, &shards[2]], "(the seed differs)");
    refused(&[&whole], "is no shard of a study");
    let too_many = pathspace(&[
        "converge",
        s,
        "--reference",
        reference.to_str().unwrap(),
        "--budget",
        "1",
        "--runs",
        "2",
        "--shard",
        "1/3",
        "-o",
        dir.join("x").to_str().unwrap(),
    ]);
    assert!(stderr(&too_many).contains("2 runs cannot give each of 3 shards a run"));
}
