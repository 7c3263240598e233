//! Interrupted renders keep their samples: a render stopped after some passes and resumed from
//! its checkpoint gives the uninterrupted render's image bit for bit (path, light, bdpt, smc:
//! every stream is `Sampler::new(seed, pixel, pass)` and SMC's structure is saved), MLT's
//! resumed run is an independent run merged by sample count, and the command line stops on
//! SIGINT / SIGTERM after the pass in flight, writes the image and its checkpoint and exits with
//! 128 + the signal; a `kill -9` loses only what came after the last checkpoint.
//! Book: "Measuring a renderer", section "Interrupted renders".

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use pathspace::integrator::{IntegratorKind, Setup};
use pathspace::path::PLAIN;
use pathspace::render::checkpoint::{Checkpoint, Identity};
use pathspace::render::session::{self, Control, Job};
use pathspace::scene::SceneSource;

const SMC_TESTBED: &str = include_str!("../../../scenes/smc-testbed-albedo-0.8.toml");
const FOG_BOX: &str = include_str!("../../../scenes/fog-box.toml");

fn identity(kind: IntegratorKind, film: Option<(u32, u32)>) -> Identity {
    Identity {
        scene_hash: 1,
        inputs: Vec::new(),
        integrator: kind.name().into(),
        options: String::new(),
        seed: 5,
        film,
        meters: 0,
    }
}

/// The film sums after `spp` samples per pixel, rendered at once or as `first` spp, a
/// checkpoint (through its bytes), then the rest.
fn render(text: &str, kind: IntegratorKind, spp: u32, first: Option<u32>) -> Vec<[f32; 3]> {
    let text = text.replace("resolution = [32, 32]", "resolution = [12, 10]");
    let src = SceneSource::embedded("scene.toml", &text);
    let (mut scene, settings) = pathspace::integrator::settings::load(&src).unwrap();
    if let Some(cam) = &scene.camera {
        scene.camera = cam.with_resolution(12, 10);
    }
    let setup = Setup {
        scene: &scene,
        technique: &PLAIN,
        settings: &settings,
        seed: 5,
        max_depth: Some(6),
    };
    let job = |spp| Job {
        kind,
        setup,
        spp,
        time: None,
        first_pass: 0,
        progress: false,
    };
    let resume = first.map(|n| {
        let control = Control {
            identity: Some(identity(kind, Some((12, 10)))),
            ..Default::default()
        };
        let ended = session::render_with(&job(n), control).unwrap();
        let bytes = ended.checkpoint.unwrap().to_bytes();
        Checkpoint::from_bytes(&bytes, "test").unwrap()
    });
    let control = Control {
        resume,
        ..Default::default()
    };
    let ended = session::render_with(&job(spp), control).unwrap();
    assert_eq!(ended.result.spp, spp as u64);
    let image = ended.result.image.unwrap();
    image.pixels.iter().map(|p| p.to_array()).collect()
}

#[test]
fn a_resumed_render_is_the_uninterrupted_one_bit_for_bit() {
    let gaussian = FOG_BOX.replace("[camera]\n", "[camera]\nfilter = { type = \"gaussian\" }\n");
    assert_ne!(gaussian, FOG_BOX);
    for (kind, text) in [
        (IntegratorKind::Path, FOG_BOX),
        (IntegratorKind::Light, FOG_BOX),
        (IntegratorKind::Bdpt, FOG_BOX),
        (IntegratorKind::Smc, SMC_TESTBED),
        (IntegratorKind::Path, gaussian.as_str()),
        (IntegratorKind::Bdpt, gaussian.as_str()),
    ] {
        let whole = render(text, kind, 16, None);
        let resumed = render(text, kind, 16, Some(8));
        assert!(
            whole == resumed,
            "{}: the resumed image differs from the uninterrupted one",
            kind.name()
        );
        // and the comparison can fail: another split of the passes draws other streams
        let other = render(text, kind, 16, Some(6));
        assert!(
            whole != other,
            "{}: passes of other sizes cannot give the same image",
            kind.name()
        );
    }
}

#[test]
fn a_resumed_mlt_render_is_an_independent_run_merged_by_sample_count() {
    let kind = IntegratorKind::Mlt;
    let resumed = render(FOG_BOX, kind, 16, Some(8));
    let first = render(FOG_BOX, kind, 8, None);
    // the second half: a fresh run with the seed the resume announces
    let text = FOG_BOX.replace("resolution = [32, 32]", "resolution = [12, 10]");
    let src = SceneSource::embedded("scene.toml", &text);
    let (mut scene, settings) = pathspace::integrator::settings::load(&src).unwrap();
    scene.camera = scene.camera.as_ref().unwrap().with_resolution(12, 10);
    let setup = Setup {
        scene: &scene,
        technique: &PLAIN,
        settings: &settings,
        seed: Checkpoint::resume_seed(5, 1),
        max_depth: Some(6),
    };
    let job = Job {
        kind,
        setup,
        spp: 8,
        time: None,
        first_pass: 0,
        progress: false,
    };
    let second = session::render(&job).unwrap().image.unwrap();
    for ((r, a), b) in resumed.iter().zip(&first).zip(&second.pixels) {
        for c in 0..3 {
            let merged = ((8.0 * a[c] as f64 + 8.0 * b[c] as f64) / 16.0) as f32;
            assert_eq!(r[c], merged, "the resumed MLT image is not the merge");
        }
    }
}

#[test]
fn a_checkpoint_of_another_render_or_a_damaged_one_is_refused() {
    let c = Checkpoint {
        identity: identity(IntegratorKind::Path, None),
        recipe: None,
        progress: Default::default(),
        film: None,
        meters: Vec::new(),
        state: None,
        earlier: None,
    };
    let mut bytes = c.to_bytes();
    assert!(Checkpoint::from_bytes(&bytes, "f").is_ok());
    let other = Identity {
        seed: 6,
        ..identity(IntegratorKind::Path, None)
    };
    let e = c.check_identity(&other, "f").unwrap_err().to_string();
    assert!(e.contains("the seed differs"), "{e}");
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    let e = Checkpoint::from_bytes(&bytes, "f").unwrap_err().to_string();
    assert!(e.contains("damaged"), "{e}");
    let e = Checkpoint::from_bytes(b"not a checkpoint", "f")
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a pathspace checkpoint"), "{e}");
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pathspace-ckpt-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `pathspace render` of the fog box at 24x24 with seed 3, into `exr`.
fn command(exr: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_pathspace"));
    c.args([
        "render",
        "--resolution",
        "24x24",
        "--seed",
        "3",
        "--threads",
        "2",
    ])
    .args(["-o", exr.to_str().unwrap()])
    .args(extra)
    .stdout(Stdio::null())
    .stderr(Stdio::piped());
    c
}

/// Waits for the first checkpoint (passes are done), then sends `signal`; the output.
fn interrupt(exr: &Path, signal: &str) -> std::process::Output {
    let child = command(exr, &["--spp", "1000000", "--checkpoint", "0"])
        .spawn()
        .unwrap();
    let ckpt = exr.with_extension("checkpoint");
    while !ckpt.exists() {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args([signal, &pid])
        .status()
        .unwrap()
        .success());
    child.wait_with_output().unwrap()
}

fn spp_of(exr: &Path) -> u64 {
    let (_, meta) = pathspace::image_io::read_exr(exr).unwrap();
    assert_eq!(meta.get("complete"), Some("false"));
    meta.get("spp").unwrap().parse().unwrap()
}

/// Resumes the render of `exr` to `spp` and compares it with an uninterrupted one: the same
/// bytes, EXR (header included: `--reproducible` leaves the timings out) and PNG.
fn resume_matches_uninterrupted(dir: &Path, exr: &Path, spp: u64) {
    let n = spp.to_string();
    let ckpt = exr.with_extension("checkpoint");
    let resume = ["--resume", ckpt.to_str().unwrap()];
    let out = command(exr, &["--spp", &n, "--reproducible"])
        .args(resume)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let whole = dir.join("whole.exr");
    let mut run = command(&whole, &["--spp", &n, "--reproducible"]);
    assert!(run.status().unwrap().success());
    for ext in ["exr", "png"] {
        let read = |p: &Path| std::fs::read(p.with_extension(ext)).unwrap();
        assert!(read(exr) == read(&whole), "the resumed {ext} differs");
    }
}

#[test]
fn sigint_and_sigterm_stop_after_the_pass_and_the_render_resumes() {
    for (signal, code) in [("-INT", 130), ("-TERM", 143)] {
        let dir = scratch(&signal[1..]);
        let exr = dir.join("part.exr");
        let out = interrupt(&exr, signal);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{err}");
        assert!(err.contains("stopped by SIG"), "{err}");
        assert!(err.contains("part.checkpoint"), "{err}");
        let spp = spp_of(&exr);
        assert!(
            spp > 0 && spp.is_multiple_of(4),
            "{spp} spp: whole passes only"
        );
        resume_matches_uninterrupted(&dir, &exr, spp + 8);
    }
}

#[test]
fn kill_9_loses_only_what_followed_the_last_checkpoint() {
    let dir = scratch("kill9");
    let exr = dir.join("part.exr");
    let out = interrupt(&exr, "-KILL");
    assert_eq!(out.status.code(), None, "killed by the signal");
    let c = Checkpoint::read(&exr.with_extension("checkpoint")).unwrap();
    let spp = c.progress.spp;
    assert!(spp > 0);
    resume_matches_uninterrupted(&dir, &exr, spp + 4);
}

/// `pathspace render` exactly as a user types it, in `dir`; its output.
fn pathspace_in(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// `pathspace ARGS` in `dir`, stopped by SIGINT once `dir/checkpoint` exists (its first pass
/// is done); its stderr, after checking it was interrupted (exit 130).
fn interrupted_in(dir: &Path, args: &[&str], checkpoint: &str) -> String {
    let child = Command::new(env!("CARGO_BIN_EXE_pathspace"))
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    while !dir.join(checkpoint).exists() {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .unwrap()
        .success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(130), "not interrupted: {err}");
    err
}

/// The render the user asked for, interrupted by SIGINT after its first checkpoint: the scene
/// given by a path relative to `dir`, a target of 512 spp (about a second on one thread, many
/// passes after the first checkpoint).
fn interrupted_long_render(dir: &Path) -> String {
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::write(dir.join("scenes/fog-box.toml"), FOG_BOX).unwrap();
    let args = [
        "render",
        "scenes/fog-box.toml",
        "--spp",
        "512",
        "--seed",
        "7",
        "--resolution",
        "48x48",
        "--threads",
        "1",
        "--reproducible",
        "--checkpoint",
        "0",
        "--aovs",
        "variance,depth",
        "-o",
        "long.exr",
    ];
    interrupted_in(dir, &args, "long.checkpoint")
}

/// The command the interrupted render prints, `--resume long.checkpoint` and nothing else,
/// finishes it: the same target, seed, resolution, options and layers (`--aovs`), taken from
/// the checkpoint, and the same bytes as the uninterrupted render; the finished render removes
/// its checkpoint.
#[test]
fn resume_alone_finishes_the_interrupted_render_bit_for_bit() {
    let dir = scratch("alone");
    let err = interrupted_long_render(&dir);
    assert!(
        err.contains("continue with --resume long.checkpoint"),
        "{err}"
    );
    let out = pathspace_in(&dir, &["render", "--resume", "long.checkpoint"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("removed long.checkpoint"), "{err}");
    assert!(!dir.join("long.checkpoint").exists());
    let out = pathspace_in(
        &dir,
        &[
            "render",
            "scenes/fog-box.toml",
            "--spp",
            "512",
            "--seed",
            "7",
            "--resolution",
            "48x48",
            "--threads",
            "2",
            "--reproducible",
            "--aovs",
            "variance,depth",
            "-o",
            "whole.exr",
        ],
    );
    assert!(out.status.success());
    for ext in ["exr", "png"] {
        let read = |name: &str| std::fs::read(dir.join(name).with_extension(ext)).unwrap();
        assert!(read("long") == read("whole"), "the resumed {ext} differs");
    }
}

/// A flag that contradicts the checkpoint's render is refused and named (the seed, the
/// resolution, the integrator); `--spp` may change the target, and says so.
#[test]
fn resume_refuses_a_contradicting_flag_and_announces_a_new_target() {
    let dir = scratch("contradict");
    interrupted_long_render(&dir);
    let resume = ["render", "--resume", "long.checkpoint"];
    for (flag, value, named) in [
        ("--seed", "8", "`seed` is 8 now but 7"),
        (
            "--resolution",
            "32x32",
            "--resolution is 32x32 now but 48x48",
        ),
        (
            "--integrator",
            "bdpt",
            "`integrator` is \"bdpt\" now but not given",
        ),
    ] {
        let out = pathspace_in(&dir, &[&resume[..], &[flag, value]].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(named),
            "{flag}: {err}"
        );
    }
    let out = pathspace_in(
        &dir,
        &[&resume[..], &["--seed", "7", "--spp", "516"]].concat(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("the target is now 516 spp"), "{err}");
    let (_, meta) = pathspace::image_io::read_exr(&dir.join("long.exr")).unwrap();
    assert_eq!(meta.get("spp"), Some("516"));
}

/// A periodic checkpoint that cannot be written (here a directory stands where the file goes)
/// is a warning, not the end of the render: the render goes on and its image is the
/// uninterrupted one.
#[test]
fn a_failed_periodic_checkpoint_warns_and_the_render_goes_on() {
    let dir = scratch("unwritable");
    let exr = dir.join("part.exr");
    std::fs::create_dir_all(exr.with_extension("checkpoint").join("occupied")).unwrap();
    let out = command(
        &exr,
        &["--spp", "12", "--checkpoint", "0", "--reproducible"],
    )
    .output()
    .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: cannot write") && err.contains("goes on"),
        "{err}"
    );
    let whole = dir.join("whole.exr");
    assert!(command(&whole, &["--spp", "12", "--reproducible"])
        .status()
        .unwrap()
        .success());
    assert!(std::fs::read(&exr).unwrap() == std::fs::read(&whole).unwrap());
}

/// A checkpoint whose checksum was recomputed over forged sums (NaN, infinity, or a mean
/// beyond an image's range) is refused, never resumed into a NaN or infinite image; a device
/// named as a checkpoint is refused before it is read.
#[test]
fn forged_sums_and_devices_are_refused() {
    let mut c = Checkpoint {
        identity: identity(IntegratorKind::Path, Some((2, 1))),
        recipe: None,
        progress: Default::default(),
        film: Some(pathspace::film::Film::new(2, 1)),
        meters: Vec::new(),
        state: None,
        earlier: None,
    };
    c.film.as_mut().unwrap().spp = 4;
    assert!(Checkpoint::from_bytes(&c.to_bytes(), "f").is_ok());
    for forged in [f64::NAN, f64::INFINITY, 1e300] {
        let mut bad = c.clone();
        bad.film.as_mut().unwrap().sum[1][2] = forged;
        let e = Checkpoint::from_bytes(&bad.to_bytes(), "f")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not finite"), "{forged}: {e}");
    }
    let e = Checkpoint::read(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a regular file"), "{e}");
}

/// A render's identity covers the files its scene reads: a mesh changed between a checkpoint
/// and `--resume` is refused, naming the file (the scene text itself is the same).
#[test]
fn a_file_the_scene_reads_changed_before_resume_is_refused_by_name() {
    let dir = scratch("inputs");
    let cube = std::fs::read_to_string("tests/fixtures/cube.obj").unwrap();
    std::fs::write(dir.join("cube.obj"), &cube).unwrap();
    let scene = format!(
        "{FOG_BOX}\n[[shapes]]\ntype = \"mesh\"\nobj = \"cube.obj\"\nmaterial = \"white\"\n"
    );
    assert!(
        FOG_BOX.contains("[materials.white]"),
        "the fog box's white material moved"
    );
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    let args = [
        "render",
        "scene.toml",
        "--resolution",
        "24x24",
        "--spp",
        "1000000",
        "--checkpoint",
        "0",
        "-o",
        "part.exr",
    ];
    interrupted_in(&dir, &args, "part.checkpoint");
    std::fs::write(dir.join("cube.obj"), format!("{cube}\n# edited\n")).unwrap();
    let out = pathspace_in(&dir, &["render", "--resume", "part.checkpoint"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("a file the scene reads differs") && err.contains("cube.obj"),
        "{err}"
    );
}

/// SMC's octree of radiance caches comes back from a checkpoint only with finite
/// coefficients: a forged one (here a coefficient set beyond f32, read back as infinity,
/// the checksum recomputed) is refused when SMC takes its state back.
#[test]
fn a_forged_smc_cache_is_refused() {
    let src = SceneSource::embedded("scene.toml", SMC_TESTBED);
    let (mut scene, settings) = pathspace::integrator::settings::load(&src).unwrap();
    scene.camera = scene.camera.as_ref().unwrap().with_resolution(6, 5);
    let setup = Setup {
        scene: &scene,
        technique: &PLAIN,
        settings: &settings,
        seed: 5,
        max_depth: Some(6),
    };
    let job = Job {
        kind: IntegratorKind::Smc,
        setup,
        spp: 8,
        time: None,
        first_pass: 0,
        progress: false,
    };
    let control = Control {
        identity: Some(identity(IntegratorKind::Smc, Some((6, 5)))),
        ..Default::default()
    };
    let c = session::render_with(&job, control)
        .unwrap()
        .checkpoint
        .unwrap();
    assert!(Checkpoint::from_bytes(&c.to_bytes(), "smc").is_ok());
    // the state is SMC's own bytes: forged through its octree's serialized form
    let octree: pathspace::integrator::smc::octree::Octree =
        postcard::from_bytes(c.state.as_deref().expect("SMC keeps its structure")).unwrap();
    let mut json = serde_json::to_value(&octree).unwrap();
    let coefficient = json
        .pointer_mut("/caches/0/coefficients/c/0/0")
        .expect("the layout of SMC's state moved");
    *coefficient = serde_json::json!(1e300);
    let forged: pathspace::integrator::smc::octree::Octree = serde_json::from_value(json).unwrap();
    let mut c = Checkpoint::from_bytes(&c.to_bytes(), "smc").unwrap();
    c.state = Some(postcard::to_stdvec(&forged).unwrap());
    let read = Checkpoint::from_bytes(&c.to_bytes(), "smc").unwrap();
    let control = Control {
        identity: Some(identity(IntegratorKind::Smc, Some((6, 5)))),
        resume: Some(read),
        ..Default::default()
    };
    let e = match session::render_with(&job, control) {
        Ok(_) => panic!("a forged SMC structure was resumed"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("SMC's octree is inconsistent"), "{e}");
}

/// A checkpoint of another format version is refused with a message that names the versions,
/// not as a file that is no checkpoint.
#[test]
fn a_checkpoint_of_another_version_is_refused_by_name() {
    let mut bytes = b"pathspace checkpoint v3\n".to_vec();
    bytes.extend_from_slice(&[0; 32]);
    let e = Checkpoint::from_bytes(&bytes, "old.checkpoint")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("another version") && e.contains("v3") && e.contains("v4"),
        "{e}"
    );
    let e = Checkpoint::from_bytes(b"not a checkpoint", "x")
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a pathspace checkpoint"), "{e}");
}
