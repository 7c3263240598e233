//! The agreement matrix: every integrator and variant on small scenes that together cover every
//! feature of the scene format, each cell compared with an unbiased reference, or refused with
//! an error naming what the integrator cannot handle, or warned about at render time where an
//! integrator cannot reach some light paths. A silent wrong image is the one outcome not
//! allowed.
//!
//! Statistics. Every cell renders `k` independent runs (seeds `seed + r`); a run gives a few
//! functionals (the mean of each image quadrant per channel, each meter per channel). The mean
//! of the k runs is compared with the reference's by Welch's t test, whose standard errors come
//! from the spread of the runs themselves, so MLT's correlated mutations and SMC's adapting
//! predicates need no model of their own. A scene's comparisons form one Holm family
//! (`tests/common/stats.rs`). References: the path tracer with delta tracking (the scene's
//! marching strategies switched off), BDPT where the path tracer cannot reach some light paths
//! (a delta light behind glass), or a closed form (the white furnace).
//!
//! Marching. Equidistant, stratified and random-offset marching are biased by design; their
//! cells use a step of 1/32 of the box, where the chapter's bound on the optical-depth error of
//! the midpoint rule (Delta^2 / 24 times the density's second derivative, per unit length) is
//! far below the cells' resolution, and are compared with the delta-tracking reference.
//! Book: "Measuring a renderer", section "The agreement matrix".

use crate::common;

use common::stats::{runs_mean, Family};
use pathspace::enlightened::{AdjointSettings, Enlightened, GuideKind};
use pathspace::geometry::Primitive;
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::integrator::mmlt::multiplexed_target;
use pathspace::integrator::path::DistanceSampling;
use pathspace::integrator::pssmlt::{bdpt_target, Pssmlt, PssmltSettings};
use pathspace::integrator::smc::{EstimatorForm, SmcSettings, Variant};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer, Setup};
use pathspace::path::{LocalSampling, PLAIN};
use pathspace::scene::light::{Light, LightPointDraw};
use pathspace::scene::{LightSelectionKind, Scene, SceneSource};

/// Where the scenes live.
fn fixture_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/agreement")
}

fn load(name: &str, text: &str) -> (Scene, RenderSettings) {
    let source = SceneSource {
        name: name.to_string(),
        text: text.to_string(),
        base_dir: fixture_dir(),
        origin: None,
        inputs: Default::default(),
    };
    pathspace::integrator::settings::load(&source).unwrap_or_else(|e| panic!("{e}"))
}

fn fixture(name: &str) -> String {
    std::fs::read_to_string(fixture_dir().join(name)).unwrap()
}

/// One column of the matrix.
#[derive(Clone, Copy, Debug)]
enum Config {
    Plain(IntegratorKind),
    Smc(Variant, EstimatorForm),
    Guided(IntegratorKind),
    Adjoint(IntegratorKind),
    /// The path tracer with `distance = "equiangular-mis"` (Kulla and Fajardo 2012).
    Equiangular,
    /// The path tracer with `light_selection = "power"` (the plain column and the reference
    /// select by the light tree, the default).
    PathPower,
    /// The path tracer with `light_point = "area"` (the plain column and the reference draw
    /// a near quad light's points by solid angle, the default).
    PathArea,
    /// The path tracer with `halo_cone = 0.3` (the plain column and the reference draw
    /// directions from the phase function and the BSDFs alone, the default).
    PathHalo,
}

impl Config {
    fn name(self) -> String {
        match self {
            Config::Plain(k) => k.name().to_string(),
            Config::Smc(v, f) => format!("smc:{}:{}", v.name(), f.name()),
            Config::Guided(k) => format!("{}+guide", k.name()),
            Config::Adjoint(k) => format!("{}+adjoint", k.name()),
            Config::Equiangular => "path+equiangular".into(),
            Config::PathPower => "path+power".into(),
            Config::PathArea => "path+area".into(),
            Config::PathHalo => "path+halo".into(),
        }
    }

    /// Samples per pixel of this column relative to a row's `spp`: what each integrator needs
    /// for a similar resolution at a similar cost (the path tracer is noisy where the camera
    /// sees a small light, BDPT and light tracing splat it, and cost three to five times more
    /// per sample).
    fn spp_factor(self) -> f64 {
        match self.kind() {
            IntegratorKind::Path => 2.0,
            IntegratorKind::Light => 0.5,
            IntegratorKind::Bdpt => 1.0 / 3.0,
            IntegratorKind::Mlt => 2.0,
            IntegratorKind::Pssmlt => 0.5,
            IntegratorKind::Mmlt => 1.0,
            IntegratorKind::Smc => 1.5,
        }
    }

    fn kind(self) -> IntegratorKind {
        match self {
            Config::Plain(k) | Config::Guided(k) | Config::Adjoint(k) => k,
            Config::Smc(..) => IntegratorKind::Smc,
            Config::Equiangular | Config::PathPower | Config::PathArea | Config::PathHalo => {
                IntegratorKind::Path
            }
        }
    }

    /// The path tracer's option columns, which change the estimator only on scenes with what
    /// the option acts on ([`option_acts`]).
    fn is_path_option(self) -> bool {
        matches!(
            self,
            Config::PathPower | Config::PathArea | Config::PathHalo
        )
    }

    /// The columns of a row: every column, or with [`SmcColumns::Proposed`] SMC's proposed
    /// method alone (marched and in the distance form).
    fn of(row: &Row) -> Vec<Config> {
        Config::all()
            .into_iter()
            .filter(|c| match (c, row.smc) {
                (Config::Smc(v, _), SmcColumns::Proposed) => *v == Variant::SMC,
                _ => true,
            })
            .collect()
    }

    /// Every column.
    fn all() -> Vec<Config> {
        use IntegratorKind::*;
        let mut v = vec![
            Config::Plain(Path),
            Config::PathPower,
            Config::PathArea,
            Config::PathHalo,
            Config::Equiangular,
            Config::Guided(Path),
            Config::Plain(Light),
            Config::Plain(Bdpt),
            Config::Plain(Mlt),
            Config::Plain(Pssmlt),
            Config::Plain(Mmlt),
        ];
        // every variant in the default form (the march), and the distance form for plain Monte
        // Carlo and the full method
        for variant in Variant::ALL {
            v.push(Config::Smc(
                variant,
                EstimatorForm::RayMarching { step: 1.0 },
            ));
        }
        for variant in [Variant::ALL[0], Variant::SMC] {
            v.push(Config::Smc(variant, EstimatorForm::Distance));
        }
        for k in [Light, Bdpt, Mlt] {
            v.push(Config::Guided(k));
            v.push(Config::Adjoint(k));
        }
        v
    }
}

/// The small MLT of the matrix: a short pre-pass and few chains (each run pays for its own).
fn mlt_settings(bootstrap: u64) -> MltSettings {
    MltSettings {
        bootstrap,
        chains: 4,
        ..MltSettings::default()
    }
}

/// Builds the technique a column needs: the guide or the adjoint image (or neither).
fn prepare(
    scene: &Scene,
    settings: &RenderSettings,
    config: Config,
    max_depth: Option<u32>,
) -> Result<Enlightened, String> {
    let mut technique = Enlightened::default();
    match config {
        Config::Guided(_) => {
            let mut g = settings.guide;
            g.kind = GuideKind::Both;
            g.particles = 4000;
            g.regions.regions = 32;
            g.cols = 8;
            g.rows = 4;
            technique.install_guide(scene, &g, 0x6775_6964);
        }
        Config::Adjoint(_) => {
            let settings = AdjointSettings {
                resolution: (8, 8),
                samples_per_cell: 4,
                ..AdjointSettings::default()
            };
            technique.install_adjoint(scene, &settings, 0x0061_646a, max_depth)?;
        }
        _ => {}
    }
    Ok(technique)
}

/// The functionals of one run, per channel (`channels` = 1 for grey scenes, whose channels are
/// identical): the image mean, the difference of the left and right halves' means and that of
/// the top and bottom halves (a splat in the wrong place or an error in one part of the image
/// shows there), then every meter.
fn functionals(r: &Renderer, channels: usize) -> Vec<f64> {
    let mut out = Vec::new();
    if let Some(film) = r.film.as_ref() {
        // quadrants 0 1 / 2 3: left = 0 + 2, top = 0 + 1
        let q = common::quadrant_means(&film.image());
        for c in 0..channels {
            let at = |i: usize| q[i * 3 + c];
            out.push((at(0) + at(1) + at(2) + at(3)) / 4.0);
            out.push((at(0) + at(2) - at(1) - at(3)) / 2.0);
            out.push((at(0) + at(1) - at(2) - at(3)) / 2.0);
        }
    }
    for m in r.meter_estimates() {
        for c in 0..channels {
            out.push(m.value[c] as f64);
        }
    }
    out
}

/// `k` runs of a column with its technique: each run's functionals, or the refusal.
fn runs(
    (scene, technique, settings): (&Scene, &dyn LocalSampling, &RenderSettings),
    config: Config,
    k: u64,
    spp: u32,
    max_depth: Option<u32>,
    channels: usize,
    bootstrap: u64,
) -> Result<Vec<Vec<f64>>, String> {
    let mut out = Vec::new();
    for run in 0..k {
        let seed = 1000 + run;
        let setup = Setup {
            scene,
            technique,
            settings,
            seed,
            max_depth,
        };
        let mut r = Renderer::prepared(config.kind(), &setup)?;
        if let Config::Smc(variant, form) = config {
            let smc = SmcSettings {
                variant,
                form,
                ..SmcSettings::default()
            };
            r = r.with_settings(&RenderSettings {
                smc,
                ..settings.clone()
            })?;
        }
        if config.kind() == IntegratorKind::Mlt {
            r.integrator = Box::new(Mlt::new(
                scene,
                technique,
                mlt_settings(bootstrap),
                seed,
                max_depth,
            )?);
        }
        if let kind @ (IntegratorKind::Pssmlt | IntegratorKind::Mmlt) = config.kind() {
            let settings = PssmltSettings {
                bootstrap,
                chains: 4,
                ..PssmltSettings::default()
            };
            let target = match kind {
                IntegratorKind::Mmlt => multiplexed_target,
                _ => bdpt_target,
            };
            r.integrator = Box::new(Pssmlt::with_target(
                scene,
                technique,
                settings,
                seed,
                max_depth,
                (kind.name(), target),
            )?);
        }
        if config.kind() == IntegratorKind::Smc {
            // SMC adapts between passes: the CLI's passes of 4 samples per pixel
            for _ in 0..spp.div_ceil(4) {
                r.pass(4, &|| {});
            }
        } else {
            r.pass(spp, &|| {});
        }
        out.push(functionals(&r, channels));
    }
    Ok(out)
}

/// The reference a row is compared with.
#[derive(Clone, Copy)]
enum Reference {
    /// An integrator with delta tracking (2 x the runs, 2 x the samples of a cell).
    Integrator(IntegratorKind),
    /// A closed form, the same for every functional.
    Exact(f64),
}

/// Which of SMC's columns a row runs.
#[derive(Clone, Copy, PartialEq, Debug)]
enum SmcColumns {
    /// The six variants marched and two in the distance form: rows that change the medium, its
    /// emission or the lights, what the variants' cache sampling and control variates read.
    Every,
    /// The proposed method (is1_cv2) marched and in the distance form: rows that change only
    /// surfaces or the camera. The variants differ only in the direction and the control
    /// variate drawn at a medium vertex; whatever the drawn ray then meets, each variant's
    /// estimate is unbiased for any cache, so a surface cannot tell them apart.
    Proposed,
}

/// A row of the matrix.
struct Row {
    name: &'static str,
    text: String,
    /// Channels compared (1 for grey scenes).
    channels: usize,
    max_depth: Option<u32>,
    runs: u64,
    spp: u32,
    /// MLT's pre-pass per run (each run pays for its own).
    mlt_bootstrap: u64,
    reference: Reference,
    smc: SmcColumns,
    /// Columns that must refuse the scene, with a word their error must contain (patterns:
    /// `mlt*` a prefix, `*+adjoint` a suffix, otherwise the exact name; the first match wins).
    refuse: &'static [(&'static str, &'static str)],
    /// Columns that must warn that they cannot reach some light paths, with a word of the
    /// warning; they are not compared. Every other column must not warn.
    warn: &'static [(&'static str, &'static str)],
}

fn matches(pattern: &str, name: &str) -> bool {
    if let Some(prefix) = pattern.strip_suffix('*') {
        name.starts_with(prefix)
    } else if let Some(suffix) = pattern.strip_prefix('*') {
        name.ends_with(suffix)
    } else {
        pattern == name
    }
}

fn expected<'a>(list: &'a [(&'static str, &'static str)], name: &str) -> Option<&'a str> {
    list.iter().find(|(p, _)| matches(p, name)).map(|(_, w)| *w)
}

/// Renders every column of `row` into `fam`.
fn check_row(fam: &mut Family, row: &Row) {
    let reference = match row.reference {
        Reference::Integrator(kind) => {
            let (scene, settings) = load(row.name, &delta_tracking(&row.text));
            let config = Config::Plain(kind);
            Some(
                runs(
                    (&scene, &PLAIN, &settings),
                    config,
                    row.runs * REFERENCE_RUNS,
                    row.spp * REFERENCE_SPP,
                    row.max_depth,
                    row.channels,
                    row.mlt_bootstrap,
                )
                .unwrap(),
            )
        }
        Reference::Exact(_) => None,
    };
    let (scene, plain) = load(row.name, &row.text);
    for config in Config::of(row) {
        let name = config.name();
        let t0 = std::time::Instant::now();
        let warning = pathspace::integrator::reach::unreachable_paths(&scene, config.kind());
        match (expected(row.warn, &name), &warning) {
            (Some(word), Some(w)) => {
                assert!(
                    w.contains(word),
                    "{}: {name} warns `{w}`, expected `{word}`",
                    row.name
                );
                continue;
            }
            (Some(word), None) => panic!(
                "{}: {name} gives no warning, expected one about `{word}`",
                row.name
            ),
            (None, Some(w)) => panic!("{}: {name} warns unexpectedly: {w}", row.name),
            (None, None) => {}
        }
        let spp = ((row.spp as f64 * config.spp_factor()).round() as u32).max(1);
        let mut settings = plain.clone();
        if let Config::Equiangular = config {
            settings.distance = DistanceSampling::EquiangularMis;
        }
        if let Config::PathPower = config {
            settings.light_selection = LightSelectionKind::Power;
        }
        if let Config::PathArea = config {
            settings.light_point = LightPointDraw::Area;
        }
        if let Config::PathHalo = config {
            settings.halo_cone = 0.3;
        }
        if config.is_path_option() && !option_acts(&scene, config) {
            assert!(
                same_as_path(&scene, (&settings, &plain), row),
                "{}: {name} changes the image of a scene its option does not act on",
                row.name
            );
            eprintln!("{}: {name}: the same image as path, bit for bit", row.name);
            continue;
        }
        let outcome = prepare(&scene, &settings, config, row.max_depth).and_then(|technique| {
            let (k, depth, ch) = (row.runs, row.max_depth, row.channels);
            runs(
                (&scene, &technique, &settings),
                config,
                k,
                spp,
                depth,
                ch,
                row.mlt_bootstrap,
            )
        });
        eprintln!(
            "{}: {name}: {spp} spp: {:.2} s",
            row.name,
            t0.elapsed().as_secs_f64()
        );
        let cell = match (expected(row.refuse, &name), outcome) {
            (None, Ok(cell)) => cell,
            (None, Err(e)) => panic!("{}: {name} refused the scene: {e}", row.name),
            (Some(word), Err(e)) => {
                assert!(
                    e.contains(word),
                    "{}: {name} refused with `{e}`, expected a reason naming `{word}`",
                    row.name
                );
                continue;
            }
            (Some(word), Ok(_)) => panic!(
                "{}: {name} rendered the scene, expected a refusal naming `{word}`",
                row.name
            ),
        };
        let mut worst = (0.0f64, 0usize);
        for i in 0..cell[0].len() {
            let a: Vec<f64> = cell.iter().map(|r| r[i]).collect();
            let what = format!("{} {name} functional {i}", row.name);
            let (ma, sa, _) = runs_mean(&a);
            let z = match (&reference, row.reference) {
                (Some(reference), _) => {
                    let b: Vec<f64> = reference.iter().map(|r| r[i]).collect();
                    let (mb, sb, _) = runs_mean(&b);
                    fam.runs_agree(&what, &a, &b);
                    (ma - mb) / (sa * sa + sb * sb).sqrt()
                }
                (None, Reference::Exact(value)) => {
                    // a constant image: every mean is the value, every half difference zero
                    let truth = if i % 3 == 0 { value } else { 0.0 };
                    fam.runs_are(&what, &a, truth);
                    (ma - truth) / sa
                }
                _ => unreachable!(),
            };
            if z.is_nan() || z.abs() > worst.0.abs() {
                worst = (z, i);
            }
        }
        // what this cell can see: the first functional's detectable relative error at the
        // family's first Holm threshold (for tuning samples; no assertion)
        let a: Vec<f64> = cell.iter().map(|r| r[0]).collect();
        let (ma, sa, da) = runs_mean(&a);
        let (sb, db, mb) = match &reference {
            Some(reference) => {
                let b: Vec<f64> = reference.iter().map(|r| r[0]).collect();
                let (mb, sb, db) = runs_mean(&b);
                (sb, db, mb)
            }
            None => (0.0, 1e9, ma),
        };
        let t = common::stats::student_quantile(
            common::stats::TEST_ALPHA / (Config::all().len() * cell[0].len()) as f64,
            da.min(db) + da.max(db).min(da),
        );
        eprintln!(
            "   worst {:+.2} se at functional {}; resolves {:.1}% of the mean",
            worst.0,
            worst.1,
            100.0 * t * (sa * sa + sb * sb).sqrt() / mb.abs().max(1e-30)
        );
        let _ = ma;
    }
}

/// Whether an option column's option acts on the scene: light selection needs two lights or
/// emitters, the solid-angle draw a quad or triangle lamp (`Light::sample_li`), the halo cone an
/// area light (point, spot and infinite lights have no halo).
fn option_acts(scene: &Scene, config: Config) -> bool {
    let area = |l: &Light| matches!(l, Light::Area { .. });
    let flat = |l: &Light| match l {
        Light::Area { prims, .. } => prims.iter().any(|&i| {
            matches!(
                scene.prims[i as usize],
                Primitive::Quad(_) | Primitive::Triangle(_)
            )
        }),
        _ => false,
    };
    match config {
        Config::PathPower => scene.lights.len() + scene.emitters.emitters.len() >= 2,
        Config::PathArea => scene.lights.iter().any(flat),
        Config::PathHalo => scene.lights.iter().any(area),
        _ => true,
    }
}

/// Whether one short run of the path tracer with an option column's settings gives the
/// functionals of the plain column bit for bit (a row skips an option column whose option
/// does not act on its scene, and checks this instead: the option must then change nothing).
fn same_as_path(
    scene: &Scene,
    (option, plain): (&RenderSettings, &RenderSettings),
    row: &Row,
) -> bool {
    let once = |settings: &RenderSettings| {
        let setup = (scene, &PLAIN as &dyn LocalSampling, settings);
        let config = Config::Plain(IntegratorKind::Path);
        runs(setup, config, 1, 4, row.max_depth, row.channels, 0).unwrap()
    };
    let (a, b) = (once(option), once(plain));
    a[0].iter()
        .zip(&b[0])
        .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The scene with every medium switched to delta tracking (the unbiased reference).
fn delta_tracking(text: &str) -> String {
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with("propagation =") {
                "propagation = \"delta-tracking\"".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn with_propagation(text: &str, p: &str) -> String {
    text.replace(
        "propagation = \"delta-tracking\"",
        &format!("propagation = \"{p}\""),
    )
}

/// Independent runs of a cell: with 32 the Student-t quantile at a row's smallest Holm level is
/// about 7 standard errors (16 runs: 7.7, 8 runs: 29).
const RUNS: u64 = 32;
/// Samples per pixel of a run (rows with expensive paths use fewer, see each row).
const SPP: u32 = 64;
/// The reference renders this many times the runs and samples of a cell, so its error adds
/// about a twelfth to a cell's.
const REFERENCE_RUNS: u64 = 2;
const REFERENCE_SPP: u32 = 3;
const NO_AREA_LIGHT: (&str, &str) = ("*+adjoint", "no area light");
/// Equiangular MIS needs the density free flight draws with, which a march does not follow.
const EQUIANGULAR_MARCHED: (&str, &str) = ("path+equiangular", "is marched");

fn row(name: &'static str, text: String, channels: usize) -> Row {
    Row {
        name,
        text,
        channels,
        max_depth: None,
        runs: RUNS,
        spp: SPP,
        mlt_bootstrap: 1024,
        reference: Reference::Integrator(IntegratorKind::Path),
        smc: SmcColumns::Every,
        refuse: &[],
        warn: &[],
    }
}

/// A row that changes only surfaces or the camera: SMC's proposed method alone
/// ([`SmcColumns::Proposed`]).
fn surface_row(name: &'static str, text: String, channels: usize) -> Row {
    Row {
        smc: SmcColumns::Proposed,
        ..row(name, text, channels)
    }
}

#[test]
fn agreement_fog_box() {
    let mut fam = Family::new("agreement: fog box");
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fog-box.toml"))
        .unwrap()
        .replace("resolution = [256, 256]", "resolution = [8, 8]");
    check_row(&mut fam, &row("fog-box", text, 3));
    fam.finish();
}

#[test]
fn agreement_furnace() {
    let mut fam = Family::new("agreement: furnace");
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace.toml"))
        .unwrap()
        .replace("resolution = [32, 32]", "resolution = [8, 8]");
    check_row(
        &mut fam,
        &Row {
            reference: Reference::Exact(1.0),
            refuse: &[NO_AREA_LIGHT],
            ..row("furnace", text, 1)
        },
    );
    fam.finish();
}

/// The fog box through Mitsuba's default gaussian filter (stddev 0.5, radius 2 pixels): on 8 x 8
/// pixels half the image is within the radius of an edge, where the film cuts the filter and
/// camera samples (sum(w f) / sum(w)) and splats (w f / N_j) must renormalize alike.
#[test]
fn agreement_fog_box_gaussian() {
    let mut fam = Family::new("agreement: fog box, gaussian filter");
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fog-box.toml"))
        .unwrap()
        .replace(
            "resolution = [256, 256]",
            "resolution = [8, 8]\nfilter = { type = \"gaussian\" }",
        );
    check_row(&mut fam, &row("fog-box-gaussian", text, 3));
    fam.finish();
}

/// A scene of constant radiance stays constant under every filter, for every integrator: the
/// furnace through the gaussian and a wide tent (radius 1.5), against its closed form 1.
#[test]
fn agreement_furnace_filtered() {
    let mut fam = Family::new("agreement: furnace, filtered");
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace.toml"))
        .unwrap();
    for (name, filter) in [
        ("furnace-gaussian", "{ type = \"gaussian\" }"),
        ("furnace-tent", "{ type = \"tent\", radius = 1.5 }"),
    ] {
        let text = text.replace(
            "resolution = [32, 32]",
            &format!("resolution = [8, 8]\nfilter = {filter}"),
        );
        check_row(
            &mut fam,
            &Row {
                reference: Reference::Exact(1.0),
                refuse: &[NO_AREA_LIGHT],
                ..row(name, text, 1)
            },
        );
    }
    fam.finish();
}

#[test]
fn agreement_chromatic() {
    let mut fam = Family::new("agreement: chromatic");
    check_row(
        &mut fam,
        &Row {
            refuse: &[NO_AREA_LIGHT],
            ..row("chromatic", fixture("chromatic.toml"), 3)
        },
    );
    fam.finish();
}

#[test]
fn agreement_grid() {
    let mut fam = Family::new("agreement: grid");
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            ..row("grid", fixture("grid.toml"), 1)
        },
    );
    fam.finish();
}

/// An OpenVDB medium (its tree read into the density lattice, tracked through the majorant
/// grid built from its voxels and tile).
#[test]
fn agreement_vdb() {
    let mut fam = Family::new("agreement: vdb");
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            ..row("vdb", fixture("vdb.toml"), 1)
        },
    );
    fam.finish();
}

#[test]
fn agreement_grid_random_offset() {
    let mut fam = Family::new("agreement: grid, random-offset marching");
    let text = with_propagation(&fixture("grid.toml"), "random-offset");
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            refuse: &[EQUIANGULAR_MARCHED],
            ..row("grid-random-offset", text, 1)
        },
    );
    fam.finish();
}

#[test]
fn agreement_procedural() {
    let mut fam = Family::new("agreement: procedural");
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            ..row("procedural", fixture("procedural.toml"), 1)
        },
    );
    fam.finish();
}

/// The three marching strategies at once: the cloud marched equidistantly, the gradient
/// stratified, the plume with a random offset.
#[test]
fn agreement_procedural_marching() {
    let mut fam = Family::new("agreement: procedural, marching");
    let mut text = fixture("procedural.toml");
    let key = "propagation = \"delta-tracking\"";
    for (medium, strategy) in [
        ("[media.cloud]", "equidistant"),
        ("[media.gradient]", "stratified"),
        ("[media.puff]", "random-offset"),
    ] {
        let at = text.find(medium).expect("the medium is in the scene");
        let offset = text[at..].find(key).expect("a propagation key") + at;
        text.replace_range(
            offset..offset + key.len(),
            &format!("propagation = \"{strategy}\""),
        );
    }
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            refuse: &[EQUIANGULAR_MARCHED],
            ..row("procedural-marching", text, 1)
        },
    );
    fam.finish();
}

#[test]
fn agreement_nested() {
    let mut fam = Family::new("agreement: nested");
    check_row(&mut fam, &row("nested", fixture("nested.toml"), 3));
    fam.finish();
}

/// Textured albedos (checkerboard, PNG and EXR bitmaps) on a quad, a box, a sphere and a disk:
/// every integrator looks the texture up at its own vertices.
#[test]
fn agreement_textured() {
    let mut fam = Family::new("agreement: textured");
    check_row(
        &mut fam,
        &surface_row("textured", fixture("textured.toml"), 3),
    );
    fam.finish();
}

/// Textures on a sphere turned by its own axes, a cylinder with its own `x_axis` and a flipped
/// disk, lit by a flipped quad lamp: every integrator measures uv in each shape's frame at its
/// own vertices.
#[test]
fn agreement_textured_shapes() {
    let mut fam = Family::new("agreement: textured shapes");
    check_row(
        &mut fam,
        &row("textured-shapes", fixture("textured-shapes.toml"), 3),
    );
    fam.finish();
}

/// Textured emission (a checkerboard quad lamp and an EXR sphere lamp, seen directly and
/// lighting a floor and a wall through haze): every column reads the radiance at its own light
/// vertices, and selects the lights by the textures' mean power.
#[test]
fn agreement_textured_emitter() {
    let mut fam = Family::new("agreement: textured emitter");
    check_row(
        &mut fam,
        &row("textured-emitter", fixture("textured-emitter.toml"), 3),
    );
    fam.finish();
}

/// Elliptic disks as light, floor and wall (the Mitsuba `disk` shape).
/// A checkerboard roughness on a rough conductor floor and a rough glass sphere, and a
/// checkerboard specular on the floor: every column reads alpha and specular at its own
/// vertices for values, sampling and densities.
#[test]
fn agreement_textured_roughness() {
    let mut fam = Family::new("agreement: textured roughness");
    check_row(
        &mut fam,
        &surface_row("textured-roughness", fixture("textured-roughness.toml"), 3),
    );
    fam.finish();
}

/// Anisotropic roughness on a GGX conductor quad and disk and a Beckmann rough glass sphere:
/// every column evaluates, samples and weighs the lobes in the frame of the shape's dp/du at
/// its own vertices.
#[test]
fn agreement_anisotropic() {
    let mut fam = Family::new("agreement: anisotropic roughness");
    check_row(
        &mut fam,
        &row("anisotropic", fixture("anisotropic.toml"), 3),
    );
    fam.finish();
}

/// A checkerboard eta on a smooth conductor sphere and a checkerboard k on a rough conductor
/// floor: every column (MLT's Dirac vertices too) reads the complex index at its own vertices;
/// light tracing cannot reach the camera through the Dirac sphere (it warns).
#[test]
fn agreement_textured_eta() {
    let mut fam = Family::new("agreement: textured eta");
    check_row(
        &mut fam,
        &Row {
            warn: &[("light*", "non-specular vertex")],
            ..surface_row("textured-eta", fixture("textured-eta.toml"), 3)
        },
    );
    fam.finish();
}

/// A checkerboard specular on a rough plastic floor: every column reads it at its own vertices
/// (the conductor's is in `agreement_textured_roughness`).
#[test]
fn agreement_textured_specular() {
    let mut fam = Family::new("agreement: textured specular");
    check_row(
        &mut fam,
        &surface_row("textured-specular", fixture("textured-specular.toml"), 3),
    );
    fam.finish();
}

/// Tinted glass: `specular_reflectance` and `specular_transmittance` on a smooth glass sphere
/// (a checkerboard transmittance), a rough glass sphere (a checkerboard reflectance) and a
/// thin pane; light tracing cannot reach the camera through the smooth glass (it warns).
#[test]
fn agreement_tinted_glass() {
    let mut fam = Family::new("agreement: tinted glass");
    check_row(
        &mut fam,
        &Row {
            warn: &[("light*", "non-specular vertex")],
            ..surface_row("tinted-glass", fixture("tinted-glass.toml"), 3)
        },
    );
    fam.finish();
}

/// `hide_emitters`: an area light in view, the environment and both seen through glass, in a
/// haze behind a null boundary: every column leaves out the paths without a scattering vertex
/// (the path tracer's first hit and escape, BDPT's and light tracing's (0, 2) and (1, 1), MLT's
/// contribution), and keeps the light arriving through the glass; light tracing cannot reach
/// the camera through the smooth glass (it warns).
#[test]
fn agreement_hidden_emitters() {
    let mut fam = Family::new("agreement: hidden emitters");
    check_row(
        &mut fam,
        &Row {
            warn: &[("light*", "non-specular vertex")],
            ..row("hidden", fixture("hidden.toml"), 3)
        },
    );
    fam.finish();
}

/// The same with a white sphere for the glass: light tracing reaches every path and is
/// compared too.
#[test]
fn agreement_hidden_emitters_without_glass() {
    let mut fam = Family::new("agreement: hidden emitters without glass");
    let text = fixture("hidden.toml").replace("material = \"glass\"", "material = \"white\"");
    check_row(&mut fam, &row("hidden-white", text, 3));
    fam.finish();
}

/// `hide_emitters` with area lights the camera looks through (`hidden-area.toml`): the wall a
/// panel lights seen through it, a white panel facing the camera transparent with its
/// reflection, the camera's collisions in a haze behind both; every column sees through them
/// on the camera's side of the first scattering vertex only (the path tracer's and SMC's first
/// ray, the camera subpath's first edge, light tracing's and BDPT's t = 1 connections, MLT's
/// contribution and its mutations' camera edges).
#[test]
fn agreement_hidden_area_emitters() {
    let mut fam = Family::new("agreement: hidden area emitters");
    check_row(
        &mut fam,
        &row("hidden-area", fixture("hidden-area.toml"), 3),
    );
    fam.finish();
}

#[test]
fn agreement_disk() {
    let mut fam = Family::new("agreement: disk");
    check_row(&mut fam, &row("disk", fixture("disk.toml"), 3));
    fam.finish();
}

#[test]
fn agreement_specular() {
    let mut fam = Family::new("agreement: specular");
    check_row(
        &mut fam,
        &Row {
            warn: &[("light*", "non-specular vertex")],
            ..surface_row("specular", fixture("specular.toml"), 3)
        },
    );
    fam.finish();
}

/// Smooth conductors with complex-index Fresnel (a gold sphere by Mitsuba's name, a tinted
/// copper mirror by eta and k) and a named rough conductor: the camera sees the light in the
/// Dirac metals, which light tracing cannot reach (it warns).
#[test]
fn agreement_gold() {
    let mut fam = Family::new("agreement: gold");
    check_row(
        &mut fam,
        &Row {
            warn: &[("light*", "non-specular vertex")],
            ..surface_row("gold", fixture("gold.toml"), 3)
        },
    );
    fam.finish();
}

/// Open cylinders (Mitsuba's `cylinder`) as the area light, a flipped tube and a pillar.
#[test]
fn agreement_cylinder() {
    let mut fam = Family::new("agreement: cylinder");
    check_row(&mut fam, &row("cylinder", fixture("cylinder.toml"), 3));
    fam.finish();
}

/// Thin glass panes: light passes a Dirac transmission unbent (thin_dielectric).
#[test]
fn agreement_thin() {
    let mut fam = Family::new("agreement: thin dielectric");
    check_row(
        &mut fam,
        &Row {
            warn: &[("light*", "non-specular vertex")],
            ..surface_row("thin", fixture("thin.toml"), 3)
        },
    );
    fam.finish();
}

#[test]
fn agreement_glossy() {
    // rough conductors and a rough dielectric holding a medium, with a point light behind the
    // rough glass: a glossy vertex is non-specular, so every column must reach every path
    let mut fam = Family::new("agreement: glossy");
    // (twice the samples: the row must resolve an eta^2 error of the light subpaths' rough
    // refraction, which changes the light of the point light by a factor 2.25)
    check_row(
        &mut fam,
        &Row {
            spp: 2 * SPP,
            ..surface_row("glossy", fixture("glossy.toml"), 3)
        },
    );
    fam.finish();
}

/// Smooth plastic, the BSDF with a Dirac and a regular lobe: the camera sees the coat mirror
/// the area light and the diffuse base, through haze (twice the samples: the row then resolves
/// 2-7% of the mean). Light tracing cannot reach what the
/// sensor sees in the coat (it warns); MLT refuses plastic by name.
#[test]
fn agreement_plastic() {
    let mut fam = Family::new("agreement: plastic");
    check_row(
        &mut fam,
        &Row {
            spp: 2 * SPP,
            refuse: &[("mlt*", "plastic")],
            warn: &[("light*", "non-specular vertex")],
            ..surface_row("plastic", fixture("plastic.toml"), 3)
        },
    );
    fam.finish();
}

/// The plastic scene seen from where no plastic is in view: the wall lit by light the coats
/// and bases reflected, so light tracing (its subpaths through Dirac and regular choices, its
/// connections at plastic never) is compared too.
#[test]
fn agreement_plastic_hidden() {
    let mut fam = Family::new("agreement: plastic, hidden");
    let text = fixture("plastic.toml")
        .replace("eye = [0.0, 0.6, 3.0]", "eye = [0.0, 1.0, 3.0]")
        .replace("look_at = [0.0, -0.8, 0.0]", "look_at = [0.0, 1.6, 0.0]");
    assert!(text.contains("look_at = [0.0, 1.6, 0.0]"));
    check_row(
        &mut fam,
        &Row {
            refuse: &[("mlt*", "plastic")],
            ..surface_row("plastic-hidden", text, 3)
        },
    );
    fam.finish();
}

#[test]
fn agreement_rough_plastic() {
    // rough plastics (Beckmann and GGX, one-sided and two-sided, nonlinear) beside a Beckmann
    // rough dielectric and conductor: regular lobes only, so every column must agree
    let mut fam = Family::new("agreement: rough plastic");
    check_row(
        &mut fam,
        &surface_row("rough-plastic", fixture("rough-plastic.toml"), 3),
    );
    fam.finish();
}

/// Low-poly spheres shaded by interpolated vertex normals (the file's and angle-weighted ones):
/// light and importance transport use the adjoint BSDF of shading normals (Veach 1997 sec.
/// 5.3), so every column must agree.
#[test]
fn agreement_smooth() {
    let mut fam = Family::new("agreement: smooth normals");
    check_row(&mut fam, &surface_row("smooth", fixture("smooth.toml"), 3));
    fam.finish();
}

/// Meshes turned around by `flip_normals`: a smooth sphere seen from inside (both normals
/// negated), a lamp mesh emitting from its flipped side and an inside-out cube holding haze
/// through its flip: every column must agree.
#[test]
fn agreement_flipped_meshes() {
    let mut fam = Family::new("agreement: flipped meshes");
    check_row(
        &mut fam,
        &surface_row("flipped", fixture("flipped.toml"), 3),
    );
    fam.finish();
}

#[test]
fn agreement_caustic() {
    let mut fam = Family::new("agreement: caustic");
    check_row(
        &mut fam,
        &Row {
            reference: Reference::Integrator(IntegratorKind::Bdpt),
            refuse: &[NO_AREA_LIGHT],
            warn: &[("path*", "Dirac light"), ("smc*", "Dirac light")],
            ..row("caustic", fixture("caustic.toml"), 1)
        },
    );
    fam.finish();
}

/// Many lights of every finite kind and a directional one: the light tree's selection (the path
/// tracer's default, and the reference) against power selection and every other integrator.
#[test]
fn agreement_many_lights() {
    let mut fam = Family::new("agreement: many lights");
    check_row(
        &mut fam,
        &Row {
            // 4x the samples: the path tracer's MIS at emitters found by chance with the power
            // pmf in place of the tree's shows at 5 standard errors with 64
            spp: 4 * SPP,
            ..row("many-lights", fixture("many-lights.toml"), 3)
        },
    );
    fam.finish();
}

#[test]
fn agreement_sky() {
    let mut fam = Family::new("agreement: sky");
    check_row(
        &mut fam,
        &Row {
            refuse: &[NO_AREA_LIGHT],
            ..row("sky", fixture("sky.toml"), 3)
        },
    );
    fam.finish();
}

/// Writes a `w` x `h` environment map (`texel(x, y)`) beside the other temporary files and
/// returns its absolute path, for a row's `map = "..."`.
fn temporary_map(tag: &str, w: u32, h: u32, texel: impl Fn(u32, u32) -> [f32; 3]) -> String {
    let dir = std::env::temp_dir().join(format!("pathspace-agreement-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut image = pathspace::image_io::Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            image.pixels[(y * w + x) as usize] = texel(x, y).into();
        }
    }
    let file = dir.join(format!("{tag}.exr"));
    pathspace::image_io::write_exr(&file, &image, &Default::default()).unwrap();
    file.display().to_string()
}

/// The white furnace under a constant environment map instead of the constant environment:
/// every pixel is still exactly 1, whatever the map's sampling density.
#[test]
fn agreement_furnace_map() {
    let mut fam = Family::new("agreement: furnace, constant map");
    let map = temporary_map("constant", 6, 4, |_, _| [1.0; 3]);
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace.toml"))
        .unwrap()
        .replace("resolution = [32, 32]", "resolution = [8, 8]")
        .replace("radiance = 1.0", &format!("map = {map:?}"));
    assert!(text.contains("map = "));
    check_row(
        &mut fam,
        &Row {
            reference: Reference::Exact(1.0),
            refuse: &[NO_AREA_LIGHT],
            ..row("furnace-map", text, 1)
        },
    );
    let _ = std::fs::remove_file(&map);
    fam.finish();
}

/// The sky row under a 16 x 8 map, turned, whose one bright texel gives as much light as the
/// rest of the sky: next-event estimation by the map's luminance, BSDF and phase sampling,
/// and light paths leaving the map must all meet.
#[test]
fn agreement_envmap() {
    let mut fam = Family::new("agreement: envmap");
    let map = temporary_map("texel", 16, 8, |x, y| {
        if (x, y) == (5, 2) {
            [60.0, 50.0, 40.0]
        } else {
            let t = 0.3 + 0.1 * y as f32 + 0.02 * x as f32;
            [0.5 * t, 0.7 * t, t]
        }
    });
    let sky = fixture("sky.toml");
    let at = sky.find("[[lights]]").unwrap();
    let text = format!(
        "{}[[lights]]\ntype = \"environment\"\nmap = {map:?}\n\
         to_world = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]\n",
        &sky[..at]
    );
    check_row(
        &mut fam,
        &Row {
            refuse: &[NO_AREA_LIGHT],
            ..row("envmap", text, 3)
        },
    );
    let _ = std::fs::remove_file(&map);
    fam.finish();
}

#[test]
fn agreement_meters() {
    let mut fam = Family::new("agreement: meters");
    check_row(
        &mut fam,
        &Row {
            refuse: &[
                NO_AREA_LIGHT,
                ("mlt*", "camera"),
                ("pssmlt", "camera"),
                ("mmlt", "camera"),
            ],
            ..row("meters", fixture("meters.toml"), 1)
        },
    );
    fam.finish();
}

/// A strongly forward-scattering slab (HG g = 0.8, tau 10, albedo 0.9) under a beam at 60 degrees:
/// long paths of forward vertices, where SMC's importance sampling from the cache was once
/// biased low (book: "SMC: the estimators", section "Forward scattering"). An eighth of the
/// samples of the other rows: SMC's three passes then sample from young caches, where the old
/// is1 was worst (is1_cv0's T 0.0064 +- 0.0013 against 0.039 at 3 passes, agreement at 24).
#[test]
fn agreement_forward() {
    let mut fam = Family::new("agreement: forward");
    check_row(
        &mut fam,
        &Row {
            refuse: &[
                NO_AREA_LIGHT,
                ("mlt*", "camera"),
                ("pssmlt", "camera"),
                ("mmlt", "camera"),
            ],
            spp: 8,
            ..row("forward", fixture("forward.toml"), 1)
        },
    );
    fam.finish();
}

#[test]
fn agreement_deep() {
    let mut fam = Family::new("agreement: deep");
    // paths of some 30 vertices: an eighth of the samples of the other rows
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 8,
            mlt_bootstrap: 512,
            ..row("deep", fixture("deep.toml"), 1)
        },
    );
    fam.finish();
}

// ---- emitting media (L_e,V0 of eq. 1): the path tracer, light tracing and BDPT (light
// subpaths from a volume vertex x0), SMC, MLT (chains whose x0 may lie in the medium), PSSMLT
// and MMLT (over BDPT's samples) against the delta-tracking reference ----

/// `text` with `emission = value` added after the line `after`.
fn with_emission(text: &str, after: &str, value: &str) -> String {
    assert!(text.contains(after), "`{after}` is in the scene");
    text.replacen(after, &format!("{after}\nemission = {value}"), 1)
}

/// The chromatic row's medium glowing, chromatic, beside its point and spot lights and surfaces.
#[test]
fn agreement_emitting_chromatic() {
    let mut fam = Family::new("agreement: emitting chromatic");
    let text = with_emission(
        &fixture("chromatic.toml"),
        "sigma_s = [0.9, 0.5, 0.2]",
        "[0.1, 0.3, 0.6]",
    );
    check_row(
        &mut fam,
        &Row {
            refuse: &[NO_AREA_LIGHT],
            ..row("emitting-chromatic", text, 3)
        },
    );
    fam.finish();
}

/// The grid row's blob glowing with its density, over a floor lit by an area light.
#[test]
fn agreement_emitting_grid() {
    let mut fam = Family::new("agreement: emitting grid");
    let text = with_emission(&fixture("grid.toml"), "sigma_s = 3.0", "[0.4, 0.2, 0.1]");
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            ..row("emitting-grid", text, 3)
        },
    );
    fam.finish();
}

/// The procedural row with the plume glowing with its density and the gradient glowing too:
/// two emitting media selected by power, beside an area light.
#[test]
fn agreement_emitting_procedural() {
    let mut fam = Family::new("agreement: emitting procedural");
    let text = with_emission(
        &fixture("procedural.toml"),
        "sigma_s = 4.0",
        "[3.0, 1.5, 0.5]",
    );
    let text = with_emission(&text, "sigma_s = 1.5", "0.2");
    check_row(
        &mut fam,
        &Row {
            spp: SPP / 2,
            ..row("emitting-procedural", text, 3)
        },
    );
    fam.finish();
}

/// A thin-lens camera (a lens point per camera ray, W_e per lens point, a lens point sampled for
/// every connection to the camera): a small area light and a point light in view, out of focus.
/// Path-space MLT's paths end at a lens point its bidirectional mutation redraws.
#[test]
fn agreement_lens() {
    let mut fam = Family::new("agreement: thin lens");
    check_row(
        &mut fam,
        &Row {
            spp: 2 * SPP,
            ..surface_row("lens", fixture("lens.toml"), 3)
        },
    );
    fam.finish();
}
