//! The option schema: every render option is declared once (`MltOptions`, `SmcOptions`), and
//! its scene-file key, its flag and the flag of earlier releases (a hidden alias) all set the
//! same setting.

use clap::{CommandFactory, Parser};
use pathspace::cli::{Cli, Command};
use pathspace::integrator::mlt::MltSettings;
use pathspace::integrator::settings::{load, RenderOptions, Spelling};
use pathspace::integrator::RenderSettings;
use pathspace::scene::{SceneSource, FOG_BOX};

use crate::common;

fn render_args(argv: &[&str]) -> pathspace::cli::render_args::RenderArgs {
    let mut full = vec!["pathspace", "render"];
    full.extend_from_slice(argv);
    match Cli::try_parse_from(full)
        .unwrap_or_else(|e| panic!("{e}"))
        .command
    {
        Some(Command::Render(args)) => args,
        other => panic!("not a render: {other:?}"),
    }
}

#[test]
fn old_and_prefixed_flags_are_the_same_option() {
    for (old, new, value) in [
        ("--chains", "--mlt-chains", "8"),
        ("--bootstrap", "--mlt-bootstrap", "2000"),
        ("--b-refine", "--mlt-b-refine", "0.5"),
        (
            "--mutation-weights",
            "--mlt-mutation-weights",
            "bidirectional=1,sensor=3",
        ),
        ("--cache-budget", "--smc-cache-budget", "64MiB"),
    ] {
        let a = render_args(&[old, value]);
        let b = render_args(&[new, value]);
        assert_eq!(a.options.mlt, b.options.mlt, "{old} vs {new}");
        assert_eq!(a.options.smc, b.options.smc, "{old} vs {new}");
        assert_ne!(*a.options, Default::default(), "{old} set nothing");
    }
}

#[test]
fn help_documents_the_prefixed_flags_only() {
    let mut cmd = Cli::command();
    let render = cmd.find_subcommand_mut("render").expect("render");
    let help = render.render_long_help().to_string();
    for flag in [
        "--mlt-chains",
        "--mlt-bootstrap",
        "--mlt-b-refine",
        "--mlt-mutation-weights",
        "--mlt-sensor-offset",
        "--smc-cache-budget",
        "--smc-variant",
        "--smc-step",
        "--guide-regions",
        "--adjoint-resolution",
    ] {
        assert!(help.contains(flag), "--help lacks {flag}");
    }
    assert!(
        !help.contains("--cache-budget <"),
        "the old spelling is shown"
    );
}

#[test]
fn a_key_and_its_flag_give_the_same_settings() {
    let text = pathspace::scene::FOG_BOX.replace(
        "seed = 1",
        "seed = 1\n\n[render.mlt]\nchains = 8\nsensor = 3.0\nlight_angle = [0.001, 0.2]",
    );
    let (_, file) =
        pathspace::integrator::settings::load(&SceneSource::embedded("k.toml", &text)).unwrap();
    let args = render_args(&[
        "--mlt-chains",
        "8",
        "--mlt-sensor",
        "3",
        "--mlt-light-angle",
        "0.001,0.2",
    ]);
    let mut flags = MltSettings::default();
    args.options.mlt.apply(&mut flags);
    assert_eq!(format!("{:?}", file.mlt), format!("{flags:?}"));
}

#[test]
fn guide_and_adjoint_keys_and_their_flags_give_the_same_settings() {
    let text = pathspace::scene::FOG_BOX.replace(
        "seed = 1",
        "seed = 1\n\n[render.guide]\nvertices = \"both\"\nmap = \"16x8\"\nregions = 64\n\
         particles = 1000\nweight = 0.25\nalpha = 3.0\nroulette = 0.5\nmin_depth = 2\n\
         sampler = \"metropolis\"\nsigma = 0.03\ndefensive = 0.2\n\n[render.adjoint]\n\
         resolution = [18, 9]\nsamples_per_cell = 3\nepsilon = 0.25\nestimator = \"metropolis\"",
    );
    let (scene, file) =
        pathspace::integrator::settings::load(&SceneSource::embedded("k.toml", &text)).unwrap();
    let args = render_args(&[
        "--guide",
        "both",
        "--guide-map",
        "16x8",
        "--guide-regions",
        "64",
        "--guide-particles",
        "1000",
        "--guide-weight",
        "0.25",
        "--guide-alpha",
        "3",
        "--guide-roulette",
        "0.5",
        "--guide-min-depth",
        "2",
        "--guide-sampler",
        "metropolis",
        "--guide-sigma",
        "0.03",
        "--guide-defensive",
        "0.2",
        "--adjoint-resolution",
        "18x9",
        "--adjoint-samples-per-cell",
        "3",
        "--adjoint-epsilon",
        "0.25",
        "--adjoint-estimator",
        "metropolis",
    ]);
    let defaults = pathspace::integrator::RenderSettings::for_scene(&scene);
    let guide = args.options.guide.apply_flags(defaults.guide).unwrap();
    assert_eq!(format!("{:?}", file.guide), format!("{guide:?}"));
    assert_ne!(format!("{guide:?}"), format!("{:?}", defaults.guide));
    let adjoint = args.options.adjoint.apply(defaults.adjoint).unwrap();
    assert_eq!(format!("{:?}", file.adjoint), format!("{adjoint:?}"));
    assert_ne!(format!("{adjoint:?}"), format!("{:?}", defaults.adjoint));
    // the flag of earlier releases is a visible alias
    let old = render_args(&["--adjoint-samples", "3"]);
    assert_eq!(old.options.adjoint.samples_per_cell, Some(3));
}

#[test]
fn help_lists_every_guide_and_adjoint_flag() {
    let mut cmd = Cli::command();
    let render = cmd.find_subcommand_mut("render").expect("render");
    let help = render.render_long_help().to_string();
    for flag in [
        "--guide <",
        "--guide-map",
        "--guide-regions",
        "--guide-particles",
        "--guide-weight",
        "--guide-alpha",
        "--guide-roulette",
        "--guide-min-depth",
        "--guide-sampler",
        "--guide-sigma",
        "--guide-defensive",
        "--adjoint-resolution",
        "--adjoint-samples-per-cell",
        "--adjoint-epsilon",
        "--adjoint-estimator",
    ] {
        assert!(help.contains(flag), "--help lacks {flag}");
    }
}

#[test]
fn converge_guide_overrides_are_the_guide_schema() {
    use pathspace::cli::converge::GuidedVariant;
    let long = GuidedVariant::parse("mlt+guide(vertices=volume,map=16x8,regions=64)").unwrap();
    let short = GuidedVariant::parse("mlt+guide:volume:16x8:64").unwrap();
    assert_eq!(long, short);
    let g = GuidedVariant::parse("bdpt+guide(sampler=metropolis,sigma=0.03,min_depth=2)")
        .unwrap()
        .guide
        .unwrap();
    assert_eq!(g.options.sigma, Some(0.03));
    assert_eq!(g.options.min_depth, Some(2));
    let e = GuidedVariant::parse("mlt+guide(colour=red)")
        .unwrap_err()
        .to_string();
    assert!(e.contains("colour"), "{e}");
    for bad in ["mlt+guide(vertices=all)", "mlt+guide:all"] {
        let e = GuidedVariant::parse(bad).unwrap_err().to_string();
        assert!(
            e.contains("vertices: unknown guide `all` (available: off, surface"),
            "{e}"
        );
    }
    let e = GuidedVariant::parse("mlt+guide(min_depth=99)")
        .unwrap_err()
        .to_string();
    assert!(e.contains("min_depth"), "{e}");
}

/// The settings without the record of the options that made them.
fn settings_of(s: &RenderSettings) -> String {
    let mut s = s.clone();
    s.given = RenderOptions::default();
    format!("{s:?}")
}

/// The fog box without its `[render]` table.
fn fog_box_without_render() -> String {
    let start = FOG_BOX.find("[render]").unwrap();
    let end = FOG_BOX.find("[camera]").unwrap();
    format!("{}{}", &FOG_BOX[..start], &FOG_BOX[end..])
}

#[test]
fn top_level_keys_and_their_flags_give_the_same_settings() {
    let text = format!(
        "[render]\nintegrator = \"bdpt\"\nspp = 3\nseed = 9\nmax_depth = 4\n\
         meter_samples = 100\nadjoint_image = true\ndistance = \"equiangular-mis\"\n\n{}",
        fog_box_without_render()
    );
    let (scene, file) = load(&SceneSource::embedded("k.toml", &text)).unwrap();
    let args = render_args(&[
        "--integrator",
        "bdpt",
        "--spp",
        "3",
        "--seed",
        "9",
        "--max-depth",
        "4",
        "--meter-samples",
        "100",
        "--adjoint-image",
        "--distance",
        "equiangular-mis",
    ]);
    let mut flags = RenderSettings::for_scene(&scene);
    flags.apply(&args.options, Spelling::Flag).unwrap();
    assert_eq!(settings_of(&file), settings_of(&flags));
    assert_ne!(
        settings_of(&flags),
        settings_of(&RenderSettings::for_scene(&scene))
    );
    // a flag given a value turns the file's key off again
    let off = render_args(&["--adjoint-image=false"]);
    flags.apply(&off.options, Spelling::Flag).unwrap();
    assert!(!flags.adjoint_image);
    // the bare flag takes no value: the scene after it stays the positional argument
    let bare = render_args(&["--adjoint-image", "scene.toml"]);
    assert_eq!(bare.options.adjoint_image, Some(true));
    assert_eq!(
        bare.scene.as_deref(),
        Some(std::path::Path::new("scene.toml"))
    );
}

/// A render records the options it was given (the flags over the scene's keys) as a
/// `[render]` table; pasted into the scene, it gives the same settings again.
#[test]
fn the_recorded_options_render_the_same_settings_again() {
    let (scene, mut settings) = load(&SceneSource::embedded("fog.toml", FOG_BOX)).unwrap();
    let args = render_args(&[
        "--integrator",
        "mlt",
        "--spp",
        "5",
        "--mlt-chains",
        "3",
        "--mlt-mutation-weights",
        "bidirectional=1,sensor=2.5",
        "--mlt-light-angle",
        "0.001,0.2",
        "--smc-cache-budget",
        "64MiB",
        "--smc-step",
        "0.5",
        "--guide",
        "volume",
        "--guide-map",
        "16x8",
        "--guide-weight",
        "0.3",
        "--adjoint-image",
        "--adjoint-resolution",
        "8x4",
    ]);
    settings.apply(&args.options, Spelling::Flag).unwrap();
    let record = settings.given.to_toml();
    for key in [
        "seed = 1",
        "spp = 5",
        "chains = 3",
        "sensor=2.5",
        "64MiB",
        "16x8",
    ] {
        assert!(record.contains(key), "{key} missing from\n{record}");
    }
    let text = format!("{record}\n{}", fog_box_without_render());
    let (_, again) = load(&SceneSource::embedded("again.toml", &text))
        .unwrap_or_else(|e| panic!("{e}\n{record}"));
    assert_eq!(settings_of(&again), settings_of(&settings));
    assert_eq!(again.given, settings.given);
    assert_ne!(
        settings_of(&settings),
        settings_of(&RenderSettings::for_scene(&scene))
    );
    // --json shows the same record
    let json = settings.given.to_json();
    assert_eq!(json["mlt"]["chains"], 3);
    assert_eq!(json["spp"], 5);
    assert!(
        json.get("max_depth").is_none(),
        "absent options are left out: {json}"
    );
}

/// `render --help` groups its options under a heading per integrator (and the session's), in
/// the order of the schema, and lists the integrators `--integrator` takes, from the registry.
#[test]
fn help_groups_the_options_and_lists_the_integrators() {
    let mut cmd = Cli::command();
    let render = cmd.find_subcommand_mut("render").expect("render");
    let help = render.render_long_help().to_string();
    let at = |s: &str| {
        help.find(s)
            .unwrap_or_else(|| panic!("--help lacks `{s}`:\n{help}"))
    };
    let headings = [
        "Render (each also a [render] key",
        "MLT: Metropolis light transport",
        "SMC: sequential Monte Carlo",
        "Guiding (path, light, bdpt, mlt, pssmlt, mmlt;",
        "Adjoint image (bdpt, light, mlt",
        "Session: length, threads, output",
    ];
    let places: Vec<usize> = headings.iter().map(|h| at(h)).collect();
    assert!(
        places.windows(2).all(|w| w[0] < w[1]),
        "headings out of order: {places:?}"
    );
    // each flag under its heading
    for (flag, heading) in [
        ("--spp", 0),
        ("--mlt-chains", 1),
        ("--smc-variant", 2),
        ("--guide-regions", 3),
        ("--adjoint-resolution", 4),
        ("--checkpoint", 5),
    ] {
        let f = at(&format!("{flag} "));
        let next = places.get(heading + 1).copied().unwrap_or(usize::MAX);
        assert!(
            places[heading] < f && f < next,
            "{flag} is not under `{}`",
            headings[heading]
        );
    }
    // each integrator with its registration's doc, in the registry's order
    let listed: Vec<usize> = pathspace::integrator::IntegratorKind::ALL
        .iter()
        .map(|k| at(&format!("- {}:", k.name())))
        .collect();
    assert!(
        listed.windows(2).all(|w| w[0] < w[1]) && places[0] < listed[0],
        "the integrators are not listed under --integrator in order: {listed:?}"
    );
    // the guiding heading names the integrators that take the guide, in the registry's order
    let takers: Vec<&str> = pathspace::integrator::IntegratorKind::ALL
        .iter()
        .filter(|k| k.takes_guide())
        .map(|k| k.name())
        .collect();
    assert!(
        help.contains(&format!("Guiding ({}; [render.guide])", takers.join(", "))),
        "the guiding heading does not name {takers:?}"
    );
}

/// The progress line: spp of the target and samples per second for a fixed spp, and the
/// seconds left for a timed render.
#[test]
fn the_progress_line_shows_rate_and_what_is_left() {
    use pathspace::render::session::progress_message;
    assert_eq!(
        progress_message(8, Some(64), Some(1.5e6), None),
        "8/64 spp, 1.500e6 samples/s"
    );
    assert_eq!(
        progress_message(3, None, Some(2e5), Some(7.6)),
        "3 spp, 2.000e5 samples/s, 8 s left"
    );
    assert_eq!(
        progress_message(3, None, None, Some(-1.0)),
        "3 spp, 0 s left"
    );
}

/// Each preprocessing stage is named on stderr when it starts and timed when it ends, in the
/// order they run (the summary follows on stdout); `--json` keeps stderr quiet.
#[test]
fn preprocessing_stages_are_named_as_they_run() {
    let dir = common::cli::scratch("options", "stages");
    let out = dir.join("mlt.exr");
    let args = |extra: &[&str]| {
        let mut a = vec![
            "render",
            "--integrator",
            "mlt",
            "--resolution",
            "8x8",
            "--spp",
            "1",
            "--mlt-bootstrap",
            "512",
            "--adjoint-image",
            "-o",
            out.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        common::cli::pathspace(&a)
    };
    let run = args(&[]);
    let err = common::cli::stderr(&run);
    assert!(run.status.success(), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    let at = |s: &str| lines.iter().position(|l| l.starts_with(s));
    let order = [
        at("preprocessing: adjoint image (BDPT pre-pass) ..."),
        at("preprocessing: adjoint image (BDPT pre-pass) done in"),
        at("preprocessing: mlt bootstrap (512 BDPT paths"),
        lines
            .iter()
            .position(|l| l.contains("bootstrap") && l.contains("done in")),
    ];
    assert!(order.iter().all(Option::is_some), "{order:?}\n{err}");
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{order:?}\n{err}");
    let quiet = args(&["--json"]);
    assert!(!common::cli::stderr(&quiet).contains("preprocessing"));
}

/// Every option with a closed set of values lists them in `--help` and refuses another value
/// on the command line, and each listed name is one its parser takes (the lists are the
/// parsers' own, so a name added to one and not the other turns this red).
#[test]
fn enumerated_options_list_exactly_the_values_their_parsers_take() {
    use pathspace::conventions::OptionValue;
    use pathspace::enlightened::adjoint::AdjointEstimator;
    use pathspace::enlightened::guide::{GuideKind, ParticleSampler};
    use pathspace::integrator::bdpt::MisHeuristic;
    use pathspace::integrator::path::DistanceSampling;
    use pathspace::integrator::smc::{estimator::Variant, EstimatorKind};
    use pathspace::scene::LightSelectionKind;
    /// A flag, the names it lists, and whether its parser takes a name.
    type Listed = (&'static str, Vec<String>, fn(&str) -> bool);
    fn typed<T: OptionValue>(flag: &'static str) -> Listed {
        (flag, T::names(), |s| T::parse(s).is_ok())
    }
    let lists: [Listed; 8] = [
        typed::<Variant>("--smc-variant"),
        typed::<EstimatorKind>("--smc-estimator"),
        typed::<GuideKind>("--guide"),
        typed::<ParticleSampler>("--guide-sampler"),
        typed::<AdjointEstimator>("--adjoint-estimator"),
        typed::<DistanceSampling>("--distance"),
        typed::<LightSelectionKind>("--light-selection"),
        typed::<MisHeuristic>("--mis-heuristic"),
    ];
    let mut cmd = Cli::command();
    let help = cmd
        .find_subcommand_mut("render")
        .unwrap()
        .render_long_help()
        .to_string();
    for (flag, names, parses) in lists {
        assert!(names.iter().all(|n| parses(n)), "{flag}: {names:?}");
        assert!(!parses("nonsense"), "{flag}");
        // the flag's entry: up to the next flag's line
        let at = help.find(&format!("{flag} ")).unwrap();
        let end = ["\n      --", "\n  -"]
            .iter()
            .filter_map(|n| help[at..].find(n))
            .min()
            .map_or(help.len(), |e| at + e);
        let entry = &help[at..end];
        // one line `[possible values: a, b]`, or (values with docs) one `- a: ...` line each
        let listed = format!("[possible values: {}]", names.join(", "));
        let lines: Vec<&str> = entry
            .lines()
            .filter_map(|l| l.trim().strip_prefix("- "))
            .map(|l| l.split(':').next().unwrap_or(l))
            .collect();
        assert!(
            entry.contains(&listed) || lines == names,
            "{flag} does not list {names:?}:\n{entry}"
        );
        let refused = Cli::try_parse_from(["pathspace", "render", flag, "nonsense"])
            .expect_err(&format!("{flag} nonsense parsed"))
            .to_string();
        assert!(
            refused.contains(&format!("[possible values: {}]", names.join(", "))),
            "{flag}: {refused}"
        );
    }
    // the variants' names are the six combinations, in the registry's order
    let built: Vec<String> = Variant::ALL.iter().map(|v| v.name()).collect();
    assert_eq!(built, Variant::NAMES);
}

/// `distance` (the path tracer's equiangular MIS, Kulla and Fajardo 2012): a bad value is
/// reported at its key, the flag is refused for the integrators that sample by free flight
/// only, and the path tracer refuses a scene with a marched medium, naming it.
#[test]
fn distance_sampling_is_checked_and_refused_where_it_does_not_apply() {
    let text = format!(
        "[render]\ndistance = \"sideways\"\n\n{}",
        fog_box_without_render()
    );
    let e = load(&SceneSource::embedded("d.toml", &text))
        .err()
        .expect("an unknown distance sampling is refused")
        .to_string();
    assert!(
        e.contains("distance") && e.contains("sideways") && e.contains("d.toml:2"),
        "{e}"
    );
    let dir = common::cli::scratch("options", "distance");
    let out = dir.join("x.exr");
    let run = common::cli::pathspace(&[
        "render",
        "--integrator",
        "bdpt",
        "--distance",
        "equiangular-mis",
        "--spp",
        "1",
        "--resolution",
        "4x4",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    let err = common::cli::stderr(&run);
    assert!(
        err.contains("--distance equiangular-mis applies to --integrator path"),
        "{err}"
    );
    // a marched medium: its collisions do not follow the density the MIS weights need
    let fixtures =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/agreement");
    let grid = std::fs::read_to_string(fixtures.join("grid.toml"))
        .unwrap()
        .replace("delta-tracking", "random-offset")
        .replace(
            "file = \"blob.grid\"",
            &format!("file = {:?}", fixtures.join("blob.grid")),
        );
    let marched = dir.join("marched.toml");
    std::fs::write(&marched, grid).unwrap();
    let run = common::cli::pathspace(&[
        "render",
        marched.to_str().unwrap(),
        "--integrator",
        "path",
        "--distance",
        "equiangular-mis",
        "--spp",
        "1",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    let err = common::cli::stderr(&run);
    assert!(
        err.contains("equiangular-mis") && err.contains("`blob` is marched"),
        "{err}"
    );
}

/// The settings of a fog box whose `[render]` table sets `key` to the string `value`, or the
/// message refusing it, which must name the key and the value at the file's line 2.
fn with_key(key: &str, value: &str) -> Result<RenderSettings, String> {
    let text = format!(
        "[render]\n{key} = \"{value}\"\n\n{}",
        fog_box_without_render()
    );
    match load(&SceneSource::embedded("k.toml", &text)) {
        Ok((_, settings)) => Ok(settings),
        Err(e) => {
            let e = e.to_string();
            assert!(
                e.contains(key) && e.contains(value) && e.contains("k.toml:2"),
                "{e}"
            );
            Err(e)
        }
    }
}

/// Asserts that `pathspace render` with `integrator` and `flag` fails with `message`.
fn flag_is_refused(integrator: &str, flag: [&str; 2], message: &str) {
    let dir = common::cli::scratch("options", flag[0].trim_start_matches('-'));
    let out = dir.join("x.exr");
    let mut args = vec!["render", "--integrator", integrator, flag[0], flag[1]];
    args.extend(["--spp", "1", "--resolution", "4x4"]);
    args.extend(["-o", out.to_str().unwrap()]);
    let run = common::cli::pathspace(&args);
    assert!(!run.status.success());
    let err = common::cli::stderr(&run);
    assert!(err.contains(message), "{err}");
}

/// `light_selection`: a bad value is refused at its line, the flag is the path tracer's (other
/// integrators refuse it by name), and a file's key takes effect.
#[test]
fn light_selection_is_checked_and_applied() {
    assert!(with_key("light_selection", "nearest").is_err());
    let settings = with_key("light_selection", "power").unwrap();
    assert_eq!(
        settings.light_selection,
        pathspace::scene::LightSelectionKind::Power
    );
    flag_is_refused(
        "bdpt",
        ["--light-selection", "tree"],
        "--light-selection applies to --integrator path",
    );
}

/// `pixel_samples`: an unknown value is refused at its line, `independent` is read, and the
/// flag is refused by name for an integrator that draws no film position per pixel (MLT).
#[test]
fn pixel_samples_is_read_checked_and_refused_where_unused() {
    assert!(with_key("pixel_samples", "sobol").is_err());
    let settings = with_key("pixel_samples", "independent").unwrap();
    assert_eq!(
        settings.pixel_samples,
        pathspace::integrator::PixelSamples::Independent
    );
    flag_is_refused(
        "mlt",
        ["--pixel-samples", "independent"],
        "--pixel-samples applies to --integrator path, bdpt or smc, not `mlt`",
    );
}

/// `mis_heuristic`: an unknown value is refused at its line, `power` is read, the flag is
/// refused by name where no strategies of a path are weighted against each other, and it
/// reaches BDPT's weights: the default is the balance heuristic, pixel for pixel, and the power
/// heuristic gives another image of the same scene.
#[test]
fn mis_heuristic_is_read_checked_applied_and_refused_where_unused() {
    assert!(with_key("mis_heuristic", "cutoff").is_err());
    let settings = with_key("mis_heuristic", "power").unwrap();
    assert_eq!(
        settings.mis_heuristic,
        pathspace::integrator::bdpt::MisHeuristic::Power
    );
    flag_is_refused(
        "path",
        ["--mis-heuristic", "power"],
        "--mis-heuristic applies to --integrator bdpt, pssmlt or mmlt, not `path`",
    );
    let dir = common::cli::scratch("options", "mis-heuristic");
    for integrator in ["bdpt", "pssmlt", "mmlt"] {
        let render = |name: &str, extra: &[&str]| {
            let out = dir.join(format!("{integrator}-{name}.exr"));
            let mut args = vec!["render", "--integrator", integrator, "--spp", "4"];
            args.extend(["--resolution", "8x8", "-o", out.to_str().unwrap()]);
            args.extend_from_slice(extra);
            assert!(common::cli::pathspace(&args).status.success());
            pathspace::image_io::read_exr(&out).unwrap().0.pixels
        };
        let default = render("default", &[]);
        let balance = render("balance", &["--mis-heuristic", "balance"]);
        assert_eq!(default, balance, "{integrator}");
        let power = render("power", &["--mis-heuristic", "power"]);
        assert_ne!(default, power, "{integrator}");
    }
}

/// The default scene rendered at 8x8 and 4 spp with the flags `extra` into `dir/name.exr`:
/// its pixels when the render succeeded, and the run.
fn small_render(
    dir: &std::path::Path,
    name: &str,
    extra: &[&str],
) -> (Option<Vec<pathspace::spectrum::Rgb>>, std::process::Output) {
    let out = dir.join(format!("{name}.exr"));
    let mut args = vec!["render", "--spp", "4", "--resolution", "8x8"];
    args.extend(["-o", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    let run = common::cli::pathspace(&args);
    let image = run
        .status
        .success()
        .then(|| pathspace::image_io::read_exr(&out).unwrap().0.pixels);
    (image, run)
}

/// `light_point`: a bad value is refused at its line; BDPT refuses the flag by name; the path
/// tracer's default is the solid-angle draw pixel for pixel and `area` gives another image;
/// with `distance = "equiangular-mis"` the draw is by area, and asking for the solid-angle
/// draw with it is refused with the reason.
#[test]
fn light_point_is_read_checked_applied_and_refused_where_unused() {
    use pathspace::scene::light::LightPointDraw;
    assert!(with_key("light_point", "nearest").is_err());
    let settings = with_key("light_point", "area").unwrap();
    assert_eq!(settings.light_point, LightPointDraw::Area);
    flag_is_refused(
        "bdpt",
        ["--light-point", "area"],
        "--light-point applies to --integrator path, not `bdpt`",
    );
    let dir = common::cli::scratch("options", "light-point");
    let render = |name: &str, extra: &[&str]| small_render(&dir, name, extra);
    let default = render("default", &[]).0.unwrap();
    let near = render("near", &["--light-point", "solid-angle-near"])
        .0
        .unwrap();
    assert_eq!(default, near);
    let area = render("area", &["--light-point", "area"]).0.unwrap();
    assert_ne!(default, area);
    let equiangular = ["--distance", "equiangular-mis"];
    let eq_default = render("eq-default", &equiangular).0.unwrap();
    let eq_area = render(
        "eq-area",
        &[&equiangular[..], &["--light-point", "area"]].concat(),
    );
    assert_eq!(Some(eq_default), eq_area.0);
    let near = ["--light-point", "solid-angle-near"];
    let (image, run) = render("eq-near", &[&equiangular[..], &near].concat());
    assert!(image.is_none());
    let err = common::cli::stderr(&run);
    assert!(
        err.contains("cannot go with distance") && err.contains("by area"),
        "{err}"
    );
}

/// `halo_cone`: a probability outside [0, 1) is refused at its line with the reason; BDPT
/// refuses the flag by name; the default is 0 and renders as `--halo-cone 0` does, pixel for
/// pixel, and 0.1 gives another image; with the guide guiding medium vertices a cone is
/// refused with the reason.
#[test]
fn halo_cone_is_read_checked_applied_and_refused_where_unused() {
    let read = |v: &str| {
        let text = format!("[render]\nhalo_cone = {v}\n\n{}", fog_box_without_render());
        load(&SceneSource::embedded("k.toml", &text)).map(|(_, settings)| settings)
    };
    assert_eq!(read("0.1").unwrap().halo_cone, 0.1);
    assert_eq!(read("0.0").unwrap().halo_cone, 0.0);
    for bad in ["1.0", "-0.1", "nan", "inf"] {
        let e = read(bad).unwrap_err().to_string();
        let ok = e.contains("halo_cone") && e.contains("k.toml:2") && e.contains("[0, 1)");
        assert!(ok, "{bad}: {e}");
    }
    flag_is_refused(
        "bdpt",
        ["--halo-cone", "0.1"],
        "--halo-cone applies to --integrator path, not `bdpt`",
    );
    let dir = common::cli::scratch("options", "halo-cone");
    let render = |name: &str, extra: &[&str]| small_render(&dir, name, extra);
    let default = render("default", &[]).0.unwrap();
    assert_eq!(
        Some(&default),
        render("zero", &["--halo-cone", "0"]).0.as_ref()
    );
    assert_ne!(
        Some(&default),
        render("cone", &["--halo-cone", "0.1"]).0.as_ref()
    );
    let guided = [
        "--guide",
        "volume",
        "--guide-particles",
        "2000",
        "--guide-regions",
        "8",
    ];
    let (image, run) = render("guided", &[&guided[..], &["--halo-cone", "0.1"]].concat());
    assert!(image.is_none());
    let err = common::cli::stderr(&run);
    assert!(err.contains("halo_cone") && err.contains("guide"), "{err}");
}

/// A guide option without guiding would change nothing: it is refused by name, on the command
/// line and in a file, and an explicit `off` keeps a file's guide table quiet.
#[test]
fn guide_options_without_guiding_are_refused() {
    let dir = common::cli::scratch("options", "guide-without-guiding");
    let out = dir.join("x.exr");
    let render = |extra: &[&str]| {
        let mut args = vec!["render", "--spp", "1", "--resolution", "4x4"];
        args.extend_from_slice(extra);
        args.extend(["-o", out.to_str().unwrap()]);
        common::cli::pathspace(&args)
    };
    let run = render(&["--guide-particles", "1000"]);
    assert!(!run.status.success());
    let err = common::cli::stderr(&run);
    assert!(
        err.contains("--guide-particles") && err.contains("without guiding"),
        "{err}"
    );
    let guided = ["--guide", "surface", "--guide-particles", "1000"];
    assert!(render(&guided).status.success());
    let scene = dir.join("g.toml");
    let text = format!(
        "[render.guide]\nweight = 0.3\n\n{}",
        fog_box_without_render()
    );
    std::fs::write(&scene, text).unwrap();
    let run = render(&[scene.to_str().unwrap()]);
    let err = common::cli::stderr(&run);
    assert!(
        !run.status.success() && err.contains("[render.guide] weight"),
        "{err}"
    );
    assert!(render(&[scene.to_str().unwrap(), "--guide", "off"])
        .status
        .success());
}

/// Each `[render]` key's default is written once (`RenderOptions::defaults`, what the settings
/// start from): the book's key table lists every key of the schema with that default, and the
/// key's flag states it in `--help`.
#[test]
fn the_book_and_the_help_state_each_render_default_of_the_schema() {
    use serde_json::Value;
    let defaults = serde_json::to_value(RenderOptions::defaults()).unwrap();
    let book = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/book/src/scenes.md"))
        .unwrap();
    let mut cmd = Cli::command();
    let help = cmd
        .find_subcommand_mut("render")
        .unwrap()
        .render_long_help()
        .to_string();
    let keys = defaults.as_object().unwrap();
    assert!(keys.len() >= 8, "{keys:?}");
    for (key, value) in keys {
        // the book's cell and the help's word for the default
        let (cell, word) = match value {
            Value::Null => ("unlimited".to_string(), "unlimited".to_string()),
            Value::String(s) => (format!("`\"{s}\"`"), s.clone()),
            v => (v.to_string(), v.to_string()),
        };
        let row = book
            .lines()
            .find(|l| l.starts_with(&format!("| `{key}` |")))
            .unwrap_or_else(|| panic!("the book's [render] table has no row for `{key}`"));
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(cells[3], cell, "the book's default of `{key}`");
        let flag = format!("--{}", key.replace('_', "-"));
        let at = [" ", "["]
            .iter()
            .find_map(|end| help.find(&format!("{flag}{end}")))
            .unwrap_or_else(|| panic!("no flag {flag} for `{key}`"));
        let end = help[at + 2..]
            .find("\n      --")
            .map_or(help.len(), |e| at + 2 + e);
        let entry = help[at..end]
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        assert!(
            [
                format!("(default {word}"),
                format!("(default: {word}"),
                format!("`{word}` (default"),
            ]
            .iter()
            .any(|p| entry.contains(p.as_str())),
            "{flag}'s help does not state the default {word}: {entry}"
        );
    }
}

/// The default a flag's help states (`(default X)`, `` `X` (default ``), as the flag takes it
/// (a fraction such as `1/32` as its value), or `None` when the entry states none.
fn stated_default(entry: &str) -> Option<String> {
    // `(default X)`, or `` `X` (default) `` / `` `X` (default: what it is) ``
    let at = entry.find("(default")?;
    let rest = &entry[at + "(default".len()..];
    let word = if rest.starts_with([')', ':']) && entry[..at].ends_with("` ") {
        entry[..at - 2].rsplit('`').next()?.to_string()
    } else {
        rest.trim_start_matches(':')
            .trim_start()
            .split([' ', ')', ';', ':'])
            .next()?
            .trim_end_matches(',')
            .to_string()
    };
    match word.split_once('/') {
        Some((a, b)) => Some((a.parse::<f64>().ok()? / b.parse::<f64>().ok()?).to_string()),
        None => Some(word),
    }
}

/// The defaults of the nested tables (`[render.mlt]`, `[render.smc]`, `[render.guide]`,
/// `[render.adjoint]`) are written once, in their settings' `Default`: the default each
/// flag's help states is checked against it here, by giving the flag that value and finding
/// every setting unchanged (so a help that drifts from the code fails, as does a book table
/// for the top-level keys above).
#[test]
fn every_default_a_flag_states_is_the_code_s() {
    // defaults that are no single value of the flag, with the reason
    let not_a_value = [
        (
            "--guide-alpha",
            "20 / scene radius: it depends on the scene",
        ),
        ("--max-depth", "unlimited: the absence of a limit"),
        (
            "--guide-roulette",
            "the ordinary roulette: the absence of a normalization",
        ),
    ];
    let scene = pathspace::scene::Scene::load(&SceneSource::embedded("fog.toml", FOG_BOX)).unwrap();
    let defaults = RenderSettings::for_scene(&scene);
    let mut cmd = Cli::command();
    let help = cmd
        .find_subcommand_mut("render")
        .unwrap()
        .render_long_help()
        .to_string();
    // the help's entries under the schema's headings: a line that names a flag, then its text
    let schema = ["Render (", "MLT:", "SMC:", "Guiding (", "Adjoint image ("];
    let mut entries: Vec<(String, String)> = Vec::new();
    let mut in_schema = false;
    for line in help.lines() {
        if !line.starts_with(' ') && line.ends_with(':') {
            in_schema = schema.iter().any(|h| line.starts_with(h));
            continue;
        }
        if !in_schema {
            continue;
        }
        let t = line.trim_start();
        let flag = t.split([',', ' ']).find(|w| w.starts_with("--"));
        match (line.starts_with("  ") && t.starts_with('-'), flag) {
            (true, Some(f)) => {
                let f = f.split(['[', '=', '<']).next().unwrap().to_string();
                entries.push((f, String::new()));
            }
            _ => {
                if let Some(e) = entries.last_mut() {
                    e.1.push(' ');
                    e.1.push_str(t);
                }
            }
        }
    }
    let mut checked = Vec::new();
    for (flag, text) in &entries {
        let Some(word) = stated_default(text) else {
            continue;
        };
        if not_a_value.iter().any(|(f, _)| f == flag) {
            continue;
        }
        let args = render_args(&[format!("{flag}={word}").as_str()]);
        let mut s = defaults.clone();
        s.apply(&args.options, Spelling::Flag)
            .unwrap_or_else(|e| panic!("{flag} {word}: {e}"));
        s.given = RenderOptions::default();
        assert_eq!(
            format!("{s:?}"),
            format!("{defaults:?}"),
            "{flag}'s help states the default {word}, the code's is another"
        );
        checked.push(flag.clone());
    }
    for table in ["--mlt-", "--smc-", "--guide-", "--adjoint-"] {
        let n = checked.iter().filter(|f| f.starts_with(table)).count();
        assert!(n >= 3, "only {n} defaults of {table}* checked: {checked:?}");
    }
}

/// `converge`'s `KIND(key=value, ...)` is the `[render]` schema: any key (a nested one
/// dotted) sets the line's settings as the scene file's key would, a bad key or value is
/// refused by its name, and the study's own keys are refused.
#[test]
fn converge_lines_take_any_option_of_the_schema() {
    use pathspace::measure::convergence::Variant;
    let scene = pathspace::scene::Scene::load(&SceneSource::embedded("fog.toml", FOG_BOX)).unwrap();
    let base = RenderSettings::for_scene(&scene);
    let adjoint = base.adjoint;
    let line = |s: &str| Variant::parse(s, adjoint).and_then(|v| v.settings(&base).map(|r| (v, r)));
    let (v, (s, _)) = line("path(distance=equiangular-mis)").unwrap();
    assert_eq!(v.name(), "path(distance=equiangular-mis)");
    let (_, (old, _)) = line("path+equiangular").unwrap();
    assert_eq!(format!("{:?}", s.distance), format!("{:?}", old.distance));
    let (_, (s, _)) = line("smc(smc.variant=is0_cv0, smc.threshold=8)").unwrap();
    let file = "[render.smc]\nvariant = \"is0_cv0\"\nthreshold = 8\n";
    let (_, from_file) = load(&SceneSource::embedded(
        "k.toml",
        &format!("{FOG_BOX}\n{file}"),
    ))
    .unwrap();
    assert_eq!(format!("{:?}", s.smc), format!("{:?}", from_file.smc));
    let (_, (_, a)) = line("bdpt(adjoint_image=true,adjoint.epsilon=0.25)").unwrap();
    assert_eq!(a.map(|a| a.epsilon), Some(0.25));
    for (bad, says) in [
        ("path(colour=red)", "colour"),
        ("smc(smc.threshold=-1)", "smc.threshold"),
        ("smc(guide.vertices=surface)", "guiding applies"),
        ("mlt(spp=4)", "the study's"),
        ("path(distance=equiangular", "`)`"),
    ] {
        let e = line(bad).map(|_| ()).unwrap_err().to_string();
        assert!(
            e.contains(bad.split('(').next().unwrap()) && e.contains(says),
            "{bad}: {e}"
        );
    }
}

// The modules of `src/integrator/settings/` (the layout: tests/repository/index.rs).
mod smc;
