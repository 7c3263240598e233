//! Bounded cost for every accepted input: each input whose cost once grew without a bound
//! (a grid header larger than its file, a march or a tracking walk through a medium far denser
//! than its step, SMC's march through one very thick channel, walks sized by `max_depth`, a
//! film larger than the machine) is now refused with its reason, or done with a bounded amount
//! of work, counted here (steps, vertices, bytes), never timed.
//! Book: "Scenes" (limits of media and grids), "Measuring a renderer" (memory).

use std::path::Path;

use pathspace::bidir::{Bdpt, Strategies, WalkLimits, MAX_SUBPATH_VERTICES};
use pathspace::integrator::smc::march::{self, MAX_MARCH_STEPS};
use pathspace::integrator::smc::{Smc, SmcError};
use pathspace::integrator::IntegratorKind;
use pathspace::integrator::RenderSettings;
use pathspace::math::Sampler;
use pathspace::medium::grid::{parse_text, LatticeError, MAX_GRID_VERTICES};
use pathspace::medium::heterogeneous::{MAX_MARCH_STEPS as MAX_MEDIUM_STEPS, MAX_TRACKING_DEPTH};
use pathspace::medium::{Grid, Medium};
use pathspace::path::technique::PLAIN;
use pathspace::render::memory::{self, FILM_BYTES_PER_PIXEL};
use pathspace::scene::{Scene, SceneError, SceneSource, FOG_BOX};

use crate::common;
use common::cli::{pathspace, scratch, stderr};

/// The prefix of this file's scratch directories.
const GROUP: &str = "bounds";

/// The fog box with its medium's coefficients replaced.
fn fog_box_with(medium: &str) -> String {
    let old = "type = \"homogeneous\"\nsigma_a = 0.1\nsigma_s = 0.4\n";
    assert!(FOG_BOX.contains(old), "the fog box's medium changed");
    FOG_BOX.replace(old, medium)
}

/// The fog box with an inhomogeneous medium of `keys` in place of its fog (a box of side 2).
fn fog_box_inhomogeneous(keys: &str) -> String {
    fog_box_with(&format!(
        "type = \"procedural\"\ndensity = \"constant\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\n{keys}\n"
    ))
}

fn load(text: &str) -> Result<(Scene, RenderSettings), SceneError> {
    pathspace::integrator::settings::load(&SceneSource::embedded("bounds.toml", text))
}

/// The error loading `text` gives.
fn load_error(text: &str) -> SceneError {
    match load(text) {
        Ok(_) => panic!("the scene loaded, but it should not have"),
        Err(e) => e,
    }
}

#[test]
fn a_grid_header_larger_than_its_file_is_refused_before_its_values_are_reserved() {
    // 512^3 is within the vertex limit: only the file's size can refuse it
    let (loc, msg) = parse_text("512 512 512").unwrap_err();
    assert_eq!(loc, "header");
    assert!(
        msg.contains("134217728 values") && msg.contains("11 bytes hold at most 6"),
        "{msg}"
    );
    // the 15-byte file of the issue: more vertices than any grid may have
    let (_, msg) = parse_text("1024 1024 1024\n").unwrap_err();
    assert!(msg.contains(&MAX_GRID_VERTICES.to_string()), "{msg}");
    assert!(matches!(
        Grid::new([1024, 1024, 1024], Vec::new()),
        Err(LatticeError::Resolution(_))
    ));
    // a grid the file can hold still loads
    let g = parse_text("2 2 2\n1 1 1 1 1 1 1 1").unwrap();
    assert_eq!(g.values.len(), 8);
}

#[test]
fn a_grid_file_that_cannot_hold_its_header_is_refused_at_its_key() {
    let dir = scratch(GROUP, "grid");
    std::fs::write(dir.join("big.txt"), "512 512 512 0 1").unwrap();
    let scene = fog_box_with(
        "type = \"grid\"\nfile = \"big.txt\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\nsigma_a = 0.1\nsigma_s = 0.4\n",
    );
    let path = dir.join("grid.toml");
    std::fs::write(&path, &scene).unwrap();
    let out = pathspace(&["info", path.to_str().unwrap()]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("grid.toml:"), "{e}");
    assert!(e.contains("media.fog.file"), "{e}");
    assert!(e.contains("big.txt") && e.contains("hold at most 8"), "{e}");
}

#[test]
fn a_march_step_too_small_for_its_box_is_refused_at_the_step_key() {
    let e = load_error(&fog_box_inhomogeneous(
        "sigma_a = 0.1\nsigma_s = 0.4\npropagation = \"equidistant\"\nstep = 1e-9",
    ));
    assert_eq!(e.key, "media.fog.step", "{e}");
    assert!(e.line.is_some(), "{e}");
    assert!(e.message.contains("limit 1e5"), "{e}");
    // the default step's march takes a bounded number of steps across the box
    let (scene, _) = load(&fog_box_inhomogeneous(
        "sigma_a = 0.1\nsigma_s = 0.4\npropagation = \"equidistant\"",
    ))
    .unwrap();
    let Medium::Heterogeneous(h) = &scene.media[0] else {
        panic!("the medium is inhomogeneous")
    };
    // diagonal 2 sqrt(3) over Delta = 2 / 64, plus the last partial step
    assert_eq!(h.march_steps(), (64.0 * 3f32.sqrt()).ceil() + 1.0);
    assert!(h.march_steps() <= MAX_MEDIUM_STEPS);
}

#[test]
fn a_medium_too_dense_for_tracking_is_refused_at_its_coefficient() {
    let e = load_error(&fog_box_inhomogeneous(
        "sigma_a = [1e9, 0.1, 0.1]\nsigma_s = 0.4\npropagation = \"delta-tracking\"",
    ));
    assert_eq!(e.key, "media.fog.sigma_a", "{e}");
    assert!(e.message.contains("limit 1e5"), "{e}");
    let (scene, _) = load(&fog_box_inhomogeneous(
        "sigma_a = 1.0\nsigma_s = 4.0\npropagation = \"delta-tracking\"",
    ))
    .unwrap();
    let Medium::Heterogeneous(h) = &scene.media[0] else {
        panic!("the medium is inhomogeneous")
    };
    // sigma_t 5 x density 1 x diagonal 2 sqrt(3) tentative collisions expected at most
    assert!((h.tracking_depth() - 10.0 * 3f32.sqrt()).abs() < 1e-3);
    assert!(h.tracking_depth() <= MAX_TRACKING_DEPTH);
}

#[test]
fn smc_refuses_a_march_with_more_steps_than_its_limit() {
    // one very thick channel: steps of one mean free path of the channel mean are 3e-9 long
    let (scene, settings) = load(&fog_box_with(
        "type = \"homogeneous\"\nsigma_a = [1e9, 0.1, 0.1]\nsigma_s = 0.4\n",
    ))
    .unwrap();
    match Smc::new(&scene, settings.smc, None) {
        Err(SmcError::MarchSteps { steps, limit, .. }) => {
            assert_eq!(limit, MAX_MARCH_STEPS);
            assert!(steps > 1e9, "{steps}");
        }
        other => panic!("accepted, or refused for another reason: {:?}", other.err()),
    }
    // the fog box's march: 0.5 per unit x diagonal 2 sqrt(3) / 1 mfp, plus the last step
    let (fog, settings) = load(FOG_BOX).unwrap();
    assert_eq!(march::max_steps(&fog.media[0], 1.0, 2.0 * 3f32.sqrt()), 3.0);
    assert!(Smc::new(&fog, settings.smc, None).is_ok());
}

#[test]
fn smc_refusals_name_the_step_and_the_limit_on_the_command_line() {
    let exr = scratch(GROUP, "smc").join("x.exr");
    let out = pathspace(&[
        "render",
        "--integrator",
        "smc",
        "--smc-step",
        "1e-9",
        "--resolution",
        "8x8",
        "--spp",
        "1",
        "--threads",
        "1",
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("--smc-step") && e.contains("limit 4096"), "{e}");
    assert!(e.contains("estimator = \"distance\""), "{e}");
}

#[test]
fn walks_are_bounded_by_their_cap_not_by_max_depth() {
    // the fog box closed by a front wall, without roulette: only the cap ends the walk
    let front = "\n[[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, 1.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nmaterial = \"white\"\n";
    let (scene, _) = load(&format!("{FOG_BOX}{front}")).unwrap();
    let bdpt = Bdpt::new(&PLAIN, Some(100_000), Strategies::All);
    let no_cap = WalkLimits {
        roulette: false,
        max_vertices: usize::MAX,
    };
    let mut path = Vec::new();
    let mut longest = 0;
    for i in 0..16 {
        let mut sampler = Sampler::new(1, i, 0);
        bdpt.light_subpath(&scene, no_cap, &mut sampler, &mut path);
        longest = longest.max(path.len());
    }
    assert_eq!(longest, MAX_SUBPATH_VERTICES);
    assert!(
        path.capacity() <= 2 * MAX_SUBPATH_VERTICES,
        "{}",
        path.capacity()
    );
}

#[test]
fn walk_limits_passed_by_the_caller_cap_the_walk_and_switch_roulette() {
    // the closed fog box again; without roulette a cap of n vertices cuts the walk the same
    // random numbers draw without it after its n-th vertex (eye and light walks alike)
    let front = "\n[[shapes]]\ntype = \"quad\"\norigin = [-1.0, -1.0, 1.0]\nu = [2.0, 0.0, 0.0]\nv = [0.0, 2.0, 0.0]\nmaterial = \"white\"\n";
    let (scene, _) = load(&format!("{FOG_BOX}{front}")).unwrap();
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let raster = glam::Vec2::new(128.0, 128.0);
    let walks = |limits: WalkLimits, i: u64| {
        let (mut light, mut eye) = (Vec::new(), Vec::new());
        let mut sampler = Sampler::new(2, i, 0);
        bdpt.light_subpath(&scene, limits, &mut sampler, &mut light);
        let mut sampler = Sampler::new(3, i, 0);
        bdpt.camera_subpath(&scene, raster, limits, &mut sampler, &mut eye);
        let points = |p: Vec<pathspace::path::Vertex>| p.iter().map(|v| v.p).collect::<Vec<_>>();
        (points(light), points(eye))
    };
    let uncapped = WalkLimits::at_most(usize::MAX);
    let mut reached = 0;
    for i in 0..32 {
        let (light, eye) = walks(uncapped, i);
        for n in [2, 5, 64] {
            let (light_n, eye_n) = walks(WalkLimits::at_most(n), i);
            assert_eq!(
                light_n,
                light[..n.min(light.len())],
                "light walk {i}, cap {n}"
            );
            assert_eq!(eye_n, eye[..n.min(eye.len())], "eye walk {i}, cap {n}");
            reached += usize::from(n == 64 && light_n.len() == 64);
        }
    }
    assert!(
        reached > 0,
        "no light walk without roulette reached 64 vertices"
    );
    // with BDPT's own limits Russian roulette ends the same walks earlier
    let longest = (0..32).map(|i| walks(WalkLimits::BDPT, i).0.len()).max();
    assert!(longest < Some(64), "{longest:?}");
}

#[test]
fn mlt_length_sampling_is_bounded_by_its_tail_not_by_max_depth() {
    use pathspace::integrator::mlt::mutation::bidirectional::Bidirectional;
    // u = 1 is past every partial sum: the walk stops at the tail, not at max_depth's cap
    let k = Bidirectional::sample_addition(1.0, 1, 10_000_002, 3);
    assert!(k <= 3 + 64, "{k}");
}

#[test]
fn the_estimate_holds_the_film_exactly() {
    let (mut scene, settings) = load(FOG_BOX).unwrap();
    scene.camera = scene.camera.as_ref().unwrap().with_resolution(300, 200);
    let e = memory::estimate(&scene, IntegratorKind::Path, &settings, 2);
    let film = pathspace::film::Film::new(300, 200);
    let bytes = (film.sum.len() + film.sum_sq.len() + film.splat.len()) * size_of::<[f64; 3]>();
    let part = e.parts.iter().find(|p| p.0 == "film").unwrap().1;
    assert_eq!(part, bytes as u64);
    assert_eq!(part, 300 * 200 * FILM_BYTES_PER_PIXEL);
}

#[test]
fn a_render_larger_than_max_memory_is_refused_with_the_figure() {
    let exr = scratch(GROUP, "max-memory").join("x.exr");
    let out = pathspace(&[
        "render",
        "--resolution",
        "16384x16384",
        "--spp",
        "1",
        "--threads",
        "1",
        "--max-memory",
        "4",
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    // 268 million pixels: the film alone is 18 GiB
    assert!(
        e.contains("the render needs about") && e.contains("film 18 GiB"),
        "{e}"
    );
    assert!(e.contains("more than --max-memory 4.0 GiB"), "{e}");
    assert!(out.stdout.is_empty());
    let out = pathspace(&["render", "--max-memory", "0", "--spp", "1"]);
    assert!(stderr(&out).contains("--max-memory 0 must be a positive number"));
}

#[test]
fn the_estimate_is_within_a_factor_of_the_peak_memory() {
    let dir = scratch(GROUP, "memory");
    let exr = dir.join("m.exr");
    let out = pathspace(&[
        "render",
        "--resolution",
        "768x768",
        "--spp",
        "4",
        "--threads",
        "2",
        "--json",
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let estimate = j["memory"]["estimate"].as_u64().unwrap() as f64;
    let peak = j["memory"]["peak_resident"].as_u64().unwrap() as f64;
    // conservative, and not by more than a factor of two
    assert!(
        peak <= estimate && estimate <= 2.0 * peak,
        "estimate {estimate}, peak {peak}"
    );
    let info = pathspace(&["info", "scenes/fog-box.toml"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("memory: about"), "{text}");
}

#[test]
fn the_estimate_covers_the_records_of_a_long_smc_march() {
    // one thick channel: about 1160 steps across the box, each leaving a record
    let dir = scratch(GROUP, "smc-memory");
    let scene = dir.join("thick.toml");
    std::fs::write(
        &scene,
        fog_box_with("type = \"homogeneous\"\nsigma_a = [1e3, 0.1, 0.1]\nsigma_s = 0.4\n"),
    )
    .unwrap();
    let exr = dir.join("m.exr");
    let out = pathspace(&[
        "render",
        scene.to_str().unwrap(),
        "--integrator",
        "smc",
        "--resolution",
        "32x32",
        "--spp",
        "4",
        "--threads",
        "2",
        "--json",
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let m = &j["memory"];
    // the octree's budget is a bound it does not reach here: without it the estimate still
    // covers the peak
    let budget = m["parts"]["smc cache"].as_u64().unwrap();
    let estimate = m["estimate"].as_u64().unwrap() - budget;
    let peak = m["peak_resident"].as_u64().unwrap();
    assert!(
        peak <= estimate,
        "estimate {estimate} without the budget, peak {peak}"
    );
    assert!(
        peak > 64 << 20,
        "the march's records are the bulk: peak {peak}"
    );
}

/// A grid or a mesh that is a device (`/dev/zero` never ends) or longer than its stated limit is
/// refused at its key without being read, and a scene file that never ends is refused after one
/// byte more than its limit, instead of being read until memory runs out.
#[cfg(unix)]
#[test]
fn an_endless_or_overlong_grid_mesh_or_scene_file_is_refused_at_its_limit() {
    use pathspace::conventions::read_at_most;
    let dir = scratch(GROUP, "endless");
    let long = dir.join("long.txt");
    std::fs::write(&long, [b'1'; 1001]).unwrap();
    let e = read_at_most(&long, 1000).unwrap_err();
    assert!(e.to_string().contains("more than 1000 bytes"), "{e}");
    assert_eq!(read_at_most(&long, 1001).unwrap().len(), 1001);
    let e = read_at_most(Path::new("/dev/zero"), u64::MAX).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let grid = fog_box_with(
        "type = \"grid\"\nfile = \"/dev/zero\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\nsigma_a = 0.1\nsigma_s = 0.4\n",
    );
    let mesh = format!(
        "{FOG_BOX}\n[[shapes]]\ntype = \"mesh\"\nobj = \"/dev/zero\"\nmaterial = \"white\"\n"
    );
    for (name, text, key) in [
        ("grid", grid, "media.fog.file"),
        ("mesh", mesh, "shapes[7].obj"),
    ] {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = pathspace(&["info", path.to_str().unwrap()]);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{e}");
        assert!(e.contains(key) && e.contains("not a regular file"), "{e}");
    }
    let out = pathspace(&["info", "/dev/zero"]);
    let e = stderr(&out);
    assert!(
        e.starts_with("error: /dev/zero: the scene file has more than"),
        "{e}"
    );
}

/// `--time` counts the preprocessing: a guided render whose guide alone takes longer than the
/// budget (1 ms cannot hold 5000 particle paths) says so and renders one pass, not a budget of
/// passes after it.
#[test]
fn time_counts_the_preprocessing() {
    let out = pathspace(&[
        "render",
        "--integrator",
        "bdpt",
        "--guide",
        "both",
        "--guide-particles",
        "5000",
        "--resolution",
        "8x8",
        "--threads",
        "1",
        "--time",
        "0.001",
        "--json",
        "-o",
        scratch(GROUP, "time").join("t.exr").to_str().unwrap(),
    ]);
    let e = stderr(&out);
    assert!(out.status.success(), "{e}");
    assert!(
        e.contains("of the 0.001 s of --time: one pass follows"),
        "{e}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(out.stdout.trim_ascii()).expect("one JSON object");
    assert_eq!(json["spp"], 1, "{json}");
}
