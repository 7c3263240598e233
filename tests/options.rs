//! The option schema: every render option is declared once (`MltOptions`, `SmcOptions`), and
//! its scene-file key, its flag and the flag of earlier releases (a hidden alias) all set the
//! same setting.

use clap::{CommandFactory, Parser};
use pathspace::cli::{Cli, Command};
use pathspace::integrator::mlt::MltSettings;
use pathspace::scene::SceneSource;

fn render_args(argv: &[&str]) -> pathspace::cli::render::RenderArgs {
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
        assert_eq!(a.mlt, b.mlt, "{old} vs {new}");
        assert_eq!(a.smc, b.smc, "{old} vs {new}");
        assert_ne!(
            (a.mlt.as_ref(), a.smc.as_ref()),
            (&Default::default(), &Default::default()),
            "{old} set nothing"
        );
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
    args.mlt.apply(&mut flags);
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
    let guide = args.guide.apply_flags(defaults.guide).unwrap();
    assert_eq!(format!("{:?}", file.guide), format!("{guide:?}"));
    assert_ne!(format!("{guide:?}"), format!("{:?}", defaults.guide));
    let adjoint = args.adjoint.tuning.apply(defaults.adjoint).unwrap();
    assert_eq!(format!("{:?}", file.adjoint), format!("{adjoint:?}"));
    assert_ne!(format!("{adjoint:?}"), format!("{:?}", defaults.adjoint));
    // the flag of earlier releases is a visible alias
    let old = render_args(&["--adjoint-samples", "3"]);
    assert_eq!(old.adjoint.tuning.samples_per_cell, Some(3));
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
    let e = GuidedVariant::parse("mlt+guide(min_depth=99)")
        .unwrap_err()
        .to_string();
    assert!(e.contains("min_depth"), "{e}");
}
