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
