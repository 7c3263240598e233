//! The `[render.smc]` keys, executable: a scene's keys become the SMC settings the renderer
//! starts from, the `--smc-*` options override them key by key, and every bad value is
//! reported at its file, line and key. Book: "SMC: experiments", section "Settings".

use pathspace::cli::render::SmcArgs;
use pathspace::conventions::OptionValue as _;
use pathspace::integrator::settings::{RenderOptions, Spelling};
use pathspace::integrator::smc::{EstimatorForm, EstimatorKind, SmcSettings, Variant};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer, Setup};
use pathspace::scene::{Scene, SceneError, SceneSource};

/// `base` with the `--smc-*` options `args` over it, as `pathspace render` applies them.
fn smc_flags(args: &SmcArgs, base: SmcSettings) -> Result<SmcSettings, String> {
    let (_, mut settings) = load("").unwrap();
    settings.smc = base;
    let flags = RenderOptions {
        smc: args.clone(),
        ..Default::default()
    };
    settings
        .apply(&flags, Spelling::Flag)
        .map_err(|e| e.message)?;
    Ok(settings.smc)
}

/// A valid scene of 17 lines ending in `[render.smc]`: a key appended is line 18.
const BASE: &str = r#"# base scene for the [render.smc] tests
[camera]
type = "pinhole"
eye = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov_deg = 40.0
resolution = [4, 4]

[media.fog]
type = "homogeneous"
sigma_a = 0.4
sigma_s = 1.6

[render]
integrator = "smc"

[render.smc]
"#;
const BASE_LINES: usize = 17;

fn load(extra: &str) -> Result<(Scene, RenderSettings), SceneError> {
    pathspace::integrator::settings::load(&SceneSource::embedded(
        "smc.toml",
        &format!("{BASE}{extra}"),
    ))
}

/// Expects the error at line `BASE_LINES + line` (1-based in `extra`) on `render.smc.KEY`,
/// with every one of `words` in the message.
#[track_caller]
fn expect_error(extra: &str, line: usize, key: &str, words: &[&str]) {
    let e = match load(extra) {
        Ok(_) => panic!("the scene loaded, but it should not have:\n{extra}"),
        Err(e) => e,
    };
    let key = format!("render.smc.{key}");
    assert_eq!(e.file, "smc.toml");
    assert_eq!(
        (e.line, e.key.as_str()),
        (Some(BASE_LINES + line), key.as_str()),
        "{e}"
    );
    for w in words {
        assert!(e.message.contains(w), "message of `{e}` lacks `{w}`");
    }
}

#[test]
fn base_has_the_stated_length_and_default_settings() {
    assert_eq!(BASE.lines().count(), BASE_LINES);
    assert_eq!(load("").unwrap().1.smc, SmcSettings::default());
}

#[test]
fn keys_become_the_settings() {
    let (_, settings) = load(
        "variant = \"is0_cv1\"\nthreshold = 12.5\ncache_budget = \"3MiB\"\nestimator = \"march\"\nstep = 0.25\n",
    )
    .unwrap();
    let want = SmcSettings {
        variant: Variant::parse("is0_cv1").unwrap(),
        threshold: 12.5,
        budget: 3 << 20,
        form: EstimatorForm::RayMarching { step: 0.25 },
    };
    assert_eq!(settings.smc, want);
    // an integer budget, and the distance form
    let (_, settings) = load("cache_budget = 5000000\nestimator = \"distance\"\n").unwrap();
    assert_eq!(settings.smc.budget, 5_000_000);
    assert_eq!(settings.smc.form, EstimatorForm::Distance);
    // the renderer starts from the scene's settings
    let (scene, settings) = load("variant = \"is0_cv2\"\nthreshold = 7\n").unwrap();
    let setup = Setup {
        scene: &scene,
        technique: &pathspace::path::PLAIN,
        settings: &settings,
        seed: 1,
        max_depth: None,
    };
    let r = Renderer::prepared(IntegratorKind::Smc, &setup).unwrap();
    let smc = r
        .engine::<pathspace::integrator::smc::Smc>()
        .expect("an smc renderer");
    assert_eq!(smc.settings.variant, Variant::parse("is0_cv2").unwrap());
    assert_eq!(smc.settings.threshold, 7.0);
}

#[test]
fn options_override_the_keys() {
    let (_, settings) = load("variant = \"is0_cv1\"\nthreshold = 12.5\nstep = 0.25\n").unwrap();
    let base = settings.smc;
    // no option: the scene's settings
    let none = SmcArgs::default();
    assert_eq!(smc_flags(&none, base), Ok(base));
    // one option replaces one key; the scene's march step carries over
    let args = SmcArgs {
        threshold: Some(99.0),
        estimator: Some(EstimatorKind::March),
        ..Default::default()
    };
    let s = smc_flags(&args, base).unwrap();
    assert_eq!(s.threshold, 99.0);
    assert_eq!(s.variant, base.variant);
    assert_eq!(s.form, EstimatorForm::RayMarching { step: 0.25 });
    let args = SmcArgs {
        variant: Some(Variant::parse("is1_cv0").unwrap()),
        estimator: Some(EstimatorKind::Distance),
        ..Default::default()
    };
    let s = smc_flags(&args, base).unwrap();
    assert_eq!(s.variant, Variant::parse("is1_cv0").unwrap());
    assert_eq!(s.form, EstimatorForm::Distance);
    assert_eq!(s.threshold, 12.5);
    // --smc-step on a scene whose estimator is distance
    let distance = load("estimator = \"distance\"\n").unwrap().1.smc;
    let args = SmcArgs {
        step: Some(0.5),
        ..Default::default()
    };
    let e = smc_flags(&args, distance).unwrap_err();
    assert!(e.contains("march"), "{e}");
    // and on the default (march) form it applies
    let s = smc_flags(&args, SmcSettings::default()).unwrap();
    assert_eq!(s.form, EstimatorForm::RayMarching { step: 0.5 });
}

#[test]
fn bad_variant() {
    expect_error(
        "threshold = 4\nvariant = \"is3_cv9\"\n",
        2,
        "variant",
        &["is3_cv9", "is1_cv2"],
    );
}

#[test]
fn bad_threshold() {
    expect_error("threshold = 0\n", 1, "threshold", &["positive"]);
    expect_error("threshold = -3.5\n", 1, "threshold", &["positive"]);
}

#[test]
fn bad_cache_budget() {
    expect_error(
        "cache_budget = \"12 parsecs\"\n",
        1,
        "cache_budget",
        &["unit"],
    );
    expect_error("cache_budget = -1\n", 1, "cache_budget", &["byte count"]);
    expect_error("cache_budget = 16\n", 1, "cache_budget", &["root cache"]);
}

#[test]
fn bad_estimator_and_step() {
    expect_error("estimator = \"walk\"\n", 1, "estimator", &["walk", "march"]);
    expect_error("step = 0.0\n", 1, "step", &["positive"]);
    expect_error(
        "estimator = \"distance\"\nstep = 0.5\n",
        2,
        "step",
        &["march", "distance"],
    );
}

#[test]
fn unknown_key_is_named() {
    let Err(e) = load("varient = \"is1_cv2\"\n") else {
        panic!("an unknown key was accepted")
    };
    assert_eq!(e.line, Some(BASE_LINES + 1), "{e}");
    assert!(e.to_string().contains("varient"), "{e}");
}

/// SMC's control variates are warned against in strongly anisotropic media (their residual
/// grows with the phase function's departure from isotropy), and only there: not for the
/// variants without a control variate, not for isotropic or mildly anisotropic media.
#[test]
fn control_variates_are_warned_against_in_anisotropic_media() {
    use pathspace::integrator::smc::{anisotropy_warning, CONTROL_VARIATE_ANISOTROPY};
    let with_phase = |phase: &str| {
        let text = pathspace::scene::FOG_BOX.replace("type = \"isotropic\"", phase);
        Scene::load(&SceneSource::embedded("fog-box", &text)).unwrap()
    };
    let iso = Scene::load(&SceneSource::embedded("fog-box", pathspace::scene::FOG_BOX)).unwrap();
    let forward = with_phase("type = \"hg\", g = 0.9");
    let backward = with_phase("type = \"hg\", g = -0.5");
    let mild = with_phase(&format!(
        "type = \"hg\", g = {}",
        CONTROL_VARIATE_ANISOTROPY * 0.5
    ));
    for v in Variant::ALL {
        let cv = v.name().ends_with("cv1") || v.name().ends_with("cv2");
        let w = anisotropy_warning(&forward, v);
        assert_eq!(w.is_some(), cv, "{}: {w:?}", v.name());
        if let Some(w) = w {
            assert!(w.contains("0.9") && w.contains(&v.name()), "{w}");
        }
        assert_eq!(
            anisotropy_warning(&backward, v).is_some(),
            cv,
            "{}",
            v.name()
        );
        assert!(anisotropy_warning(&iso, v).is_none(), "{}", v.name());
        assert!(anisotropy_warning(&mild, v).is_none(), "{}", v.name());
    }
}
