//! Emitting media (the volume emittance L_e,V0 of Pauly, Kollig, Keller 2000, eqs. 1, 3, 5, 6)
//! against closed forms: an absorbing slab seen head-on, the emitting furnace (emission
//! proportional to absorption under a uniform environment: every radiance is the
//! environment's), irradiance meters inside and outside an emitting sphere (the hemisphere
//! integral of the chord radiance by numerical quadrature, independent of the renderer), and
//! the integrators that cannot collect the emission refusing it by name.
//!
//! Statistics: image means per channel with standard errors from the pixels' own sample
//! variances, meters with theirs; each test function is one Holm family (fixed seeds).
//! Book: "The transport equations", section "Emitting media".

use crate::common;

use common::stats::Family;
use glam::Vec3;
use pathspace::integrator::mlt::{Mlt, MltSettings};
use pathspace::integrator::smc::{EstimatorForm, SmcSettings, Variant};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer, Setup};
use pathspace::scene::{Scene, SceneSource};

fn load(text: &str) -> Scene {
    let mut src = SceneSource::embedded("emission.toml", text);
    src.base_dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/agreement");
    Scene::load(&src).unwrap_or_else(|e| panic!("{e}"))
}

/// The image mean of every channel of a path-traced render against `truth`.
fn image_is(fam: &mut Family, what: &str, scene: &Scene, spp: u32, seed: u64, truth: [f64; 3]) {
    let r = Renderer::new(scene, IntegratorKind::Path, seed, None);
    renderer_is(fam, what, r, spp, truth);
}

/// The image mean of every channel of `r`'s render of `spp` samples against `truth`.
fn renderer_is(fam: &mut Family, what: &str, mut r: Renderer, spp: u32, truth: [f64; 3]) {
    r.pass(spp, &|| {});
    let film = r.film.as_ref().unwrap();
    for (c, t) in truth.iter().enumerate() {
        let (m, se, dof) = common::film_mean(film, c);
        fam.mean_is(&format!("{what} channel {c}"), m, se, dof, *t);
    }
}

/// The image mean of every channel of `kind` against `truth`, from `runs` independent renders
/// of `spp` samples (light tracing and BDPT splat onto other pixels, so the pixels' own
/// variances do not apply: the runs' spread does).
fn image_runs_are(
    fam: &mut Family,
    what: &str,
    kind: IntegratorKind,
    scene: &Scene,
    (runs, spp, seed): (u64, u32, u64),
    truth: [f64; 3],
) {
    let means: Vec<[f64; 3]> = (0..runs)
        .map(|i| {
            let mut r = Renderer::new(scene, kind, seed + i, None);
            r.pass(spp, &|| {});
            let img = r.film.as_ref().unwrap().image();
            let n = (img.width * img.height) as f64;
            let mut m = [0.0f64; 3];
            for y in 0..img.height {
                for x in 0..img.width {
                    let p = img.get(x, y);
                    for (c, mc) in m.iter_mut().enumerate() {
                        *mc += p[c] as f64 / n;
                    }
                }
            }
            m
        })
        .collect();
    for (c, t) in truth.iter().enumerate() {
        let a: Vec<f64> = means.iter().map(|m| m[c]).collect();
        fam.runs_are(&format!("{what}, {} channel {c}", kind.name()), &a, *t);
    }
}

/// The integrators that start light subpaths at a volume vertex x0 (eq. 5).
const BIDIRECTIONAL: [IntegratorKind; 2] = [IntegratorKind::Light, IntegratorKind::Bdpt];

/// The primary-sample chains over a BDPT sample (PSSMLT) and over one of its strategies (MMLT).
const PRIMARY_SAMPLE: [IntegratorKind; 2] = [IntegratorKind::Pssmlt, IntegratorKind::Mmlt];

/// The mean of every channel of `r`'s image (splats included).
fn image_mean(r: &Renderer) -> [f64; 3] {
    let img = r.film.as_ref().unwrap().image();
    let n = (img.width * img.height) as f64;
    let mut m = [0.0f64; 3];
    for y in 0..img.height {
        for x in 0..img.width {
            let p = img.get(x, y);
            for (c, mc) in m.iter_mut().enumerate() {
                *mc += p[c] as f64 / n;
            }
        }
    }
    m
}

/// The image mean of every channel of PSSMLT or MMLT (`kind`) against `truth`, from `runs`
/// independent runs of `spp` mutations per pixel, each with its own small bootstrap of 1024
/// samples and 4 chains (the chains' correlation is in the runs' spread).
fn chain_runs_are(
    fam: &mut Family,
    what: &str,
    kind: IntegratorKind,
    scene: &Scene,
    (runs, spp, seed): (u64, u32, u64),
    truth: [f64; 3],
) {
    use pathspace::integrator::mmlt::multiplexed_target;
    use pathspace::integrator::pssmlt::{bdpt_target, Pssmlt, PssmltSettings};
    let settings = PssmltSettings {
        bootstrap: 1024,
        chains: 4,
        ..PssmltSettings::default()
    };
    let target = match kind {
        IntegratorKind::Mmlt => multiplexed_target,
        _ => bdpt_target,
    };
    let means: Vec<[f64; 3]> = (0..runs)
        .map(|i| {
            let plain = &pathspace::path::technique::PLAIN;
            let mut r = Renderer::new(scene, kind, seed + i, None);
            let chains = Pssmlt::with_target(
                scene,
                plain,
                settings.clone(),
                seed + i,
                None,
                (kind.name(), target),
            );
            r.integrator = Box::new(chains.unwrap());
            r.pass(spp, &|| {});
            image_mean(&r)
        })
        .collect();
    for (c, t) in truth.iter().enumerate() {
        let a: Vec<f64> = means.iter().map(|m| m[c]).collect();
        fam.runs_are(&format!("{what}, {} channel {c}", kind.name()), &a, *t);
    }
}

/// A camera on +z looking at the origin.
fn camera(eye_z: f32, fov: f32) -> String {
    format!(
        "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, {eye_z:.1}]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = {fov}\nresolution = [6, 6]\n"
    )
}

// ---- (a) the emitting slab ----

/// L = (L_e,V0 / sigma_a)(1 - exp(-sigma_a d)): eq. (3)'s source term integrated along a
/// chord of length d through a non-scattering medium. The field of view is 0.4 degree, so the
/// chords differ from d by a relative 1e-5, far below the test's resolution.
#[test]
fn emitting_slab_head_on() {
    let (sa, e, d) = ([0.5f64, 1.0, 2.5], [1.0f64, 2.0, 0.5], 1.2f64);
    let truth: [f64; 3] = std::array::from_fn(|c| e[c] / sa[c] * (1.0 - (-sa[c] * d).exp()));
    let coeffs = "sigma_a = [0.5, 1.0, 2.5]\nsigma_s = 0.0\nemission = [1.0, 2.0, 0.5]";
    let media = [
        ("homogeneous", format!("type = \"homogeneous\"\n{coeffs}")),
        (
            "procedural constant, delta tracking",
            format!("type = \"procedural\"\ndensity = \"constant\"\nmin = [-20.0, -20.0, -1.2]\nmax = [20.0, 20.0, 0.0]\npropagation = \"delta-tracking\"\n{coeffs}"),
        ),
    ];
    let mut fam = Family::new("emitting slab");
    for (i, (what, body)) in media.iter().enumerate() {
        let text = format!(
            "{}\n[media.slab]\n{body}\n\n[[shapes]]\ntype = \"box\"\nmin = [-20.0, -20.0, -1.2]\nmax = [20.0, 20.0, 0.0]\nmaterial = \"null\"\ninterior = \"slab\"\n",
            camera(5.0, 0.4)
        );
        image_is(&mut fam, what, &load(&text), 256, 11 + i as u64, truth);
    }
    fam.finish();
}

/// The slab for light tracing and BDPT: a column just wider than the view (half-width 0.03;
/// the view's cone is 0.022 wide at the far face), so most volume starts x0 are seen by the
/// camera; every ray still crosses the full depth d. Light tracing sees the glow only through
/// x0 connected to the camera (s = 1, t = 1), BDPT weighs that against the eye walk's
/// collisions (s = 0).
#[test]
fn emitting_slab_head_on_bidirectional() {
    let (sa, e, d) = ([0.5f64, 1.0, 2.5], [1.0f64, 2.0, 0.5], 1.2f64);
    let truth: [f64; 3] = std::array::from_fn(|c| e[c] / sa[c] * (1.0 - (-sa[c] * d).exp()));
    let text = format!(
        "{}\n[media.slab]\ntype = \"homogeneous\"\nsigma_a = [0.5, 1.0, 2.5]\nsigma_s = 0.0\nemission = [1.0, 2.0, 0.5]\n\n[[shapes]]\ntype = \"box\"\nmin = [-0.03, -0.03, -1.2]\nmax = [0.03, 0.03, 0.0]\nmaterial = \"null\"\ninterior = \"slab\"\n",
        camera(5.0, 0.4)
    );
    let scene = load(&text);
    let mut fam = Family::new("emitting slab, bidirectional");
    for (i, kind) in BIDIRECTIONAL.into_iter().enumerate() {
        image_runs_are(
            &mut fam,
            "slab",
            kind,
            &scene,
            (16, 16, 41 + 100 * i as u64),
            truth,
        );
    }
    fam.finish();
}

/// The slab for MLT: the column of the bidirectional test, whose chains' x0 are volume
/// vertices from the pre-pass, the bidirectional mutation (by emitted power, or as a
/// collision of the eye side) and the propagation perturbation (along the pinhole's ray).
#[test]
fn emitting_slab_head_on_mlt() {
    let (sa, e, d) = ([0.5f64, 1.0, 2.5], [1.0f64, 2.0, 0.5], 1.2f64);
    let truth: [f64; 3] = std::array::from_fn(|c| e[c] / sa[c] * (1.0 - (-sa[c] * d).exp()));
    let text = format!(
        "{}\n[media.slab]\ntype = \"homogeneous\"\nsigma_a = [0.5, 1.0, 2.5]\nsigma_s = 0.0\nemission = [1.0, 2.0, 0.5]\n\n[[shapes]]\ntype = \"box\"\nmin = [-0.03, -0.03, -1.2]\nmax = [0.03, 0.03, 0.0]\nmaterial = \"null\"\ninterior = \"slab\"\n",
        camera(5.0, 0.4)
    );
    let scene = load(&text);
    let mut fam = Family::new("emitting slab, mlt");
    mlt_runs_are(&mut fam, "slab", &scene, (16, 256, 43), truth);
    fam.finish();
}

/// The means of every channel of MLT (a pre-pass of 4096 BDPT samples, 4 chains) over the
/// whole image, its central 2 x 2 pixels and its four corner pixels against `truth` (the
/// value of every pixel), from `runs` independent renders of `spp` mutations per pixel. The
/// image's total luminance is b, BDPT's estimate, whatever the chains do: an error of f or of
/// a transition density moves light between pixels and channels, so the regions carry it.
fn mlt_runs_are(
    fam: &mut Family,
    what: &str,
    scene: &Scene,
    (runs, spp, seed): (u64, u32, u64),
    truth: [f64; 3],
) {
    const REGIONS: [&str; 3] = ["image", "centre", "corners"];
    let means: Vec<[[f64; 3]; 3]> = (0..runs)
        .map(|i| {
            let settings = MltSettings {
                bootstrap: 4096,
                chains: 4,
                ..MltSettings::default()
            };
            let mlt = Mlt::new(scene, &pathspace::path::PLAIN, settings, seed + i, None)
                .unwrap_or_else(|e| panic!("mlt renders the scene: {e}"));
            let mut r = Renderer::new(scene, IntegratorKind::Mlt, seed + i, None);
            r.integrator = Box::new(mlt);
            r.pass(spp, &|| {});
            let img = r.film.as_ref().unwrap().image();
            let (w, h) = (img.width, img.height);
            let corner = |x: u32, y: u32| (x == 0 || x + 1 == w) && (y == 0 || y + 1 == h);
            let centre = |x: u32, y: u32| {
                (w / 2 - 1..=w / 2).contains(&x) && (h / 2 - 1..=h / 2).contains(&y)
            };
            let mut m = [[0.0f64; 3]; 3];
            let mut n = [0.0f64; 3];
            for y in 0..h {
                for x in 0..w {
                    let p = img.get(x, y);
                    for (k, inside) in [true, centre(x, y), corner(x, y)].into_iter().enumerate() {
                        if inside {
                            n[k] += 1.0;
                            for (c, mc) in m[k].iter_mut().enumerate() {
                                *mc += p[c] as f64;
                            }
                        }
                    }
                }
            }
            for k in 0..3 {
                assert!(n[k] > 0.0, "the {} has pixels", REGIONS[k]);
                m[k] = m[k].map(|v| v / n[k]);
            }
            m
        })
        .collect();
    for (k, region) in REGIONS.iter().enumerate() {
        for (c, t) in truth.iter().enumerate() {
            let a: Vec<f64> = means.iter().map(|m| m[k][c]).collect();
            fam.runs_are(&format!("{what}, mlt {region} channel {c}"), &a, *t);
        }
    }
}

/// The slab column of the bidirectional test through the primary-sample chains: PSSMLT's
/// BDPT sample starts its light subpath at x0 from the same numbers as BDPT, MMLT picks one
/// strategy per state, the glow seen through the eye walk's collisions (s = 0) or through x0
/// joined to the camera (s = 1, t = 1) with its weight.
#[test]
fn emitting_slab_head_on_primary_sample_chains() {
    let (sa, e, d) = ([0.5f64, 1.0, 2.5], [1.0f64, 2.0, 0.5], 1.2f64);
    let truth: [f64; 3] = std::array::from_fn(|c| e[c] / sa[c] * (1.0 - (-sa[c] * d).exp()));
    let text = format!(
        "{}\n[media.slab]\ntype = \"homogeneous\"\nsigma_a = [0.5, 1.0, 2.5]\nsigma_s = 0.0\nemission = [1.0, 2.0, 0.5]\n\n[[shapes]]\ntype = \"box\"\nmin = [-0.03, -0.03, -1.2]\nmax = [0.03, 0.03, 0.0]\nmaterial = \"null\"\ninterior = \"slab\"\n",
        camera(5.0, 0.4)
    );
    let scene = load(&text);
    let mut fam = Family::new("emitting slab, primary-sample chains");
    for (i, kind) in PRIMARY_SAMPLE.into_iter().enumerate() {
        let seed = 61 + 100 * i as u64;
        chain_runs_are(&mut fam, "slab", kind, &scene, (32, 32, seed), truth);
    }
    fam.finish();
}

// ---- (b) the emitting furnace ----

/// Radiance of the environment: chromatic, so a channel mixed up shows.
const L_W: [f32; 3] = [1.0, 0.5, 2.0];

/// A sphere of radius 1 filled with `medium` (its `[media.glow]` body, which must set
/// emission = sigma_a L_W) under a uniform environment of radiance L_W.
fn furnace(medium: &str) -> String {
    format!(
        "{}\n[media.glow]\n{medium}\n\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"null\"\ninterior = \"glow\"\n\n[[lights]]\ntype = \"environment\"\nradiance = [{}, {}, {}]\n",
        camera(3.0, 30.0),
        L_W[0],
        L_W[1],
        L_W[2]
    )
}

/// The emitting furnace's coefficients: chromatic sigma_a and sigma_s, and L_e,V0 = sigma_a L_W,
/// which balances eq. (1) at L = L_W.
fn furnace_coeffs() -> String {
    let sa = [0.6f32, 1.5, 0.3];
    let e: Vec<f32> = (0..3).map(|c| sa[c] * L_W[c]).collect();
    format!(
        "sigma_a = [{}, {}, {}]\nsigma_s = [1.2, 0.4, 2.0]\nemission = [{}, {}, {}]",
        sa[0], sa[1], sa[2], e[0], e[1], e[2]
    )
}

/// The media the emitting furnaces fill their sphere with.
#[derive(Clone, Copy)]
enum FurnaceMedium {
    /// The blob grid, delta-tracked.
    Grid,
    /// The procedural cloud with a backward HG lobe, delta-tracked or ray-marched.
    Cloud { tracked: bool },
    /// A homogeneous medium with a forward HG lobe.
    HomogeneousHg,
}

/// The `[media.glow]` body of `kind` with the coefficients `coeffs`.
fn furnace_medium(kind: FurnaceMedium, coeffs: &str) -> String {
    let box_ = "min = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]";
    let tracking = "propagation = \"delta-tracking\"";
    match kind {
        FurnaceMedium::Grid => {
            format!("type = \"grid\"\nfile = \"blob.grid\"\n{box_}\n{tracking}\n{coeffs}")
        }
        FurnaceMedium::Cloud { tracked } => format!(
            "type = \"procedural\"\ndensity = \"cloud\"\noctaves = 3\nseed = 4\n{box_}\n{}{coeffs}\nphase = {{ type = \"hg\", g = -0.3 }}",
            if tracked { format!("{tracking}\n") } else { String::new() }
        ),
        FurnaceMedium::HomogeneousHg => {
            format!("type = \"homogeneous\"\n{coeffs}\nphase = {{ type = \"hg\", g = 0.6 }}")
        }
    }
}

/// L_e,V0 = sigma_a L_w balances eq. (1) at L = L_w: 0 = sigma_a L_w - sigma_t L_w + sigma_s
/// L_w. So every pixel is L_w for any albedo, phase function and density; the sphere fills
/// the view. Collected emission, next-event estimation of the medium and their MIS weights all
/// enter: a missing or doubled part is a bias. The delta-tracked media come first: their free
/// flights need no other assignment before the emission found, so the course grades
/// `volume_emission_found` with this test.
#[test]
fn emitting_furnace() {
    let coeffs = furnace_coeffs();
    let media = [
        ("grid", furnace_medium(FurnaceMedium::Grid, &coeffs)),
        (
            "procedural cloud",
            furnace_medium(FurnaceMedium::Cloud { tracked: true }, &coeffs),
        ),
        (
            "homogeneous, hg",
            furnace_medium(FurnaceMedium::HomogeneousHg, &coeffs),
        ),
    ];
    let truth = L_W.map(|v| v as f64);
    let mut fam = Family::new("emitting furnace");
    for (i, (what, body)) in media.iter().enumerate() {
        let scene = load(&furnace(body));
        image_is(&mut fam, what, &scene, 96, 21 + i as u64, truth);
        // light and BDPT take the environment: volume starts x0 and environment starts both
        for (j, kind) in BIDIRECTIONAL.into_iter().enumerate() {
            let seed = 200 + 50 * j as u64 + 10 * i as u64;
            image_runs_are(&mut fam, what, kind, &scene, (32, 16, seed), truth);
        }
    }
    fam.finish();
}

/// The emitting furnace for integrators without environment lights: the sphere of [`furnace`]
/// inside a closed box of black walls that emit L_W inwards (the camera inside). Radiance
/// L_W leaves every wall, and the medium keeps it so (eq. 1 balances), so every pixel reads
/// L_W.
fn walled_furnace(medium: &str) -> String {
    let (e, a) = (format!("[{}, {}, {}]", L_W[0], L_W[1], L_W[2]), 3.0f32);
    // origin, u, v of each wall with u x v pointing inwards
    let walls = [
        ([-a, -a, -a], [0.0, 0.0, 2.0 * a], [2.0 * a, 0.0, 0.0]),
        ([-a, a, -a], [2.0 * a, 0.0, 0.0], [0.0, 0.0, 2.0 * a]),
        ([-a, -a, -a], [2.0 * a, 0.0, 0.0], [0.0, 2.0 * a, 0.0]),
        ([-a, -a, a], [0.0, 2.0 * a, 0.0], [2.0 * a, 0.0, 0.0]),
        ([-a, -a, -a], [0.0, 2.0 * a, 0.0], [0.0, 0.0, 2.0 * a]),
        ([a, -a, -a], [0.0, 0.0, 2.0 * a], [0.0, 2.0 * a, 0.0]),
    ];
    let mut text = format!(
        "{}\n[media.glow]\n{medium}\n\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"null\"\ninterior = \"glow\"\n",
        camera(2.5, 60.0)
    );
    for (o, u, v) in walls {
        text += &format!(
            "\n[[shapes]]\ntype = \"quad\"\norigin = {o:?}\nu = {u:?}\nv = {v:?}\nemission = {e}\n"
        );
    }
    text
}

/// The emitting furnace inside black emitting walls for MLT (a closed scene, no light at
/// infinity), the homogeneous and the procedural cloud media of [`emitting_furnace`]: paths
/// start on the walls or at volume vertices x0, and every pixel is L_W. A doubled or missing
/// emission at x0, or emission not scaled by the cloud's density, is a bias.
#[test]
fn emitting_furnace_in_emitting_walls_mlt() {
    let coeffs = furnace_coeffs();
    let media = [
        (
            "procedural cloud",
            furnace_medium(FurnaceMedium::Cloud { tracked: false }, &coeffs),
        ),
        (
            "homogeneous, hg",
            furnace_medium(FurnaceMedium::HomogeneousHg, &coeffs),
        ),
    ];
    let truth = L_W.map(|v| v as f64);
    let mut fam = Family::new("emitting furnace in emitting walls");
    for (i, (what, body)) in media.iter().enumerate() {
        let scene = load(&walled_furnace(body));
        // the path tracer checks the scene itself
        image_is(&mut fam, what, &scene, 64, 31 + i as u64, truth);
        mlt_runs_are(
            &mut fam,
            what,
            &scene,
            (16, 512, 300 + 20 * i as u64),
            truth,
        );
    }
    fam.finish();
}

/// The emitting furnace through the primary-sample chains (they take the environment: its
/// starts and the volume starts x0 share the light subpaths by power): any density of x0
/// missing from a weight, or a strategy MMLT never picks, leaves the image off L_w.
#[test]
fn emitting_furnace_primary_sample_chains() {
    let coeffs = furnace_coeffs();
    let media = [
        ("grid", furnace_medium(FurnaceMedium::Grid, &coeffs)),
        (
            "homogeneous, hg",
            furnace_medium(FurnaceMedium::HomogeneousHg, &coeffs),
        ),
    ];
    let truth = L_W.map(|v| v as f64);
    let mut fam = Family::new("emitting furnace, primary-sample chains");
    for (i, (what, body)) in media.iter().enumerate() {
        let scene = load(&furnace(body));
        for (j, kind) in PRIMARY_SAMPLE.into_iter().enumerate() {
            let seed = 400 + 50 * j as u64 + 10 * i as u64;
            chain_runs_are(&mut fam, what, kind, &scene, (32, 32, seed), truth);
        }
    }
    fam.finish();
}

// ---- SMC and the path tracer without volume next-event estimation ----

/// SMC in `form` with `variant` on `scene`.
fn smc<'a>(scene: &'a Scene, variant: Variant, form: EstimatorForm, seed: u64) -> Renderer<'a> {
    let mut settings = RenderSettings::for_scene(scene);
    settings.smc = SmcSettings {
        variant,
        form,
        ..SmcSettings::default()
    };
    Renderer::new(scene, IntegratorKind::Smc, seed, None)
        .with_settings(&settings)
        .unwrap()
}

/// The SMC configurations checked: the full method and plain Monte Carlo, in both forms (the
/// march's source term is estimated at its jittered point, the distance form's at the
/// collision).
fn smc_configs() -> Vec<(String, Variant, EstimatorForm)> {
    let march = EstimatorForm::RayMarching { step: 1.0 };
    let mut v = Vec::new();
    for (variant, form) in [
        (Variant::SMC, march),
        (Variant::ALL[0], march),
        (Variant::SMC, EstimatorForm::Distance),
        (Variant::ALL[0], EstimatorForm::Distance),
    ] {
        v.push((
            format!("smc {} {}", variant.name(), form.name()),
            variant,
            form,
        ));
    }
    v
}

/// The emitting slab of (a) through SMC: eq. (3)'s source term in the march and at the
/// distance form's collisions, for a homogeneous and a delta-tracked procedural slab.
#[test]
fn smc_emitting_slab_head_on() {
    let (sa, e, d) = ([0.5f64, 1.0, 2.5], [1.0f64, 2.0, 0.5], 1.2f64);
    let truth: [f64; 3] = std::array::from_fn(|c| e[c] / sa[c] * (1.0 - (-sa[c] * d).exp()));
    let coeffs = "sigma_a = [0.5, 1.0, 2.5]\nsigma_s = 0.0\nemission = [1.0, 2.0, 0.5]";
    let media = [
        ("homogeneous", format!("type = \"homogeneous\"\n{coeffs}")),
        (
            "procedural",
            format!("type = \"procedural\"\ndensity = \"constant\"\nmin = [-20.0, -20.0, -1.2]\nmax = [20.0, 20.0, 0.0]\npropagation = \"delta-tracking\"\n{coeffs}"),
        ),
    ];
    let mut fam = Family::new("smc: emitting slab");
    for (i, (what, body)) in media.iter().enumerate() {
        let text = format!(
            "{}\n[media.slab]\n{body}\n\n[[shapes]]\ntype = \"box\"\nmin = [-20.0, -20.0, -1.2]\nmax = [20.0, 20.0, 0.0]\nmaterial = \"null\"\ninterior = \"slab\"\n",
            camera(5.0, 0.4)
        );
        let scene = load(&text);
        for (j, (name, variant, form)) in smc_configs().into_iter().enumerate() {
            let r = smc(&scene, variant, form, 41 + (4 * i + j) as u64);
            renderer_is(&mut fam, &format!("{what}, {name}"), r, 128, truth);
        }
    }
    fam.finish();
}

/// The emitting furnace of (b) through SMC: every pixel reads L_w whatever the albedo and
/// density, so emission dropped, counted twice at a collision, or left out of the records
/// that the next estimates' control variates are built from shows as a bias.
#[test]
fn smc_emitting_furnace() {
    let coeffs = furnace_coeffs();
    let media = [
        ("homogeneous", format!("type = \"homogeneous\"\n{coeffs}")),
        ("grid", furnace_medium(FurnaceMedium::Grid, &coeffs)),
    ];
    let truth = L_W.map(|v| v as f64);
    let mut fam = Family::new("smc: emitting furnace");
    for (i, (what, body)) in media.iter().enumerate() {
        let scene = load(&furnace(body));
        for (j, (name, variant, form)) in smc_configs().into_iter().enumerate() {
            let r = smc(&scene, variant, form, 61 + (4 * i + j) as u64);
            renderer_is(&mut fam, &format!("{what}, {name}"), r, 48, truth);
        }
    }
    fam.finish();
}

/// The path tracer with `[render] volume_next_event = false`: the emission collected by the
/// walk alone, with weight 1 (a weight still shared with the absent next-event estimate
/// would make it dark), is unbiased on the furnace and the slab.
#[test]
fn path_without_volume_next_event() {
    let body = furnace_medium(FurnaceMedium::HomogeneousHg, &furnace_coeffs());
    let scene = load(&furnace(&body));
    let mut settings = RenderSettings::for_scene(&scene);
    assert!(settings.volume_next_event, "on by default");
    settings.volume_next_event = false;
    let setup = Setup {
        scene: &scene,
        technique: &pathspace::path::technique::PLAIN,
        settings: &settings,
        seed: 81,
        max_depth: None,
    };
    let r = Renderer::prepared(IntegratorKind::Path, &setup).unwrap();
    let mut fam = Family::new("path without volume next-event estimation");
    renderer_is(&mut fam, "furnace", r, 96, L_W.map(|v| v as f64));
    fam.finish();
}

// ---- (c) irradiance meters and an emitting sphere ----

/// Radius, absorption and emission of the sphere (non-scattering).
const R: f64 = 1.0;
const SA: [f64; 3] = [0.4, 1.0, 3.0];
const E: [f64; 3] = [1.0, 1.5, 2.0];
/// Side of the meters.
const SIDE: f64 = 0.05;

/// The length of the chord of the sphere along x + t w, t > 0.
fn chord(x: [f64; 3], w: [f64; 3]) -> f64 {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (b, c) = (dot(x, w), dot(x, x) - R * R);
    let disc = b * b - c;
    if disc <= 0.0 {
        return 0.0;
    }
    let (t0, t1) = (-b - disc.sqrt(), -b + disc.sqrt());
    (t1.max(0.0) - t0.max(0.0)).max(0.0)
}

/// Irradiance at x with normal n: the integral over the hemisphere of (e / sa)(1 - exp(-sa l))
/// cos theta, with u = sin^2 theta (cos theta dw = du dphi / 2), by the midpoint rule.
fn irradiance(x: [f64; 3], n: Vec3, c: usize) -> f64 {
    let (nu, nphi) = (300, 300);
    let frame = pathspace::math::Frame::from_normal(n);
    let mut sum = 0.0;
    for i in 0..nu {
        let u = (i as f64 + 0.5) / nu as f64;
        let (s, ct) = (u.sqrt(), (1.0 - u).sqrt());
        for j in 0..nphi {
            let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / nphi as f64;
            let local = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, ct as f32);
            let w = frame.to_world(local).as_dvec3().to_array();
            let l = chord(x, w);
            sum += E[c] / SA[c] * (1.0 - (-SA[c] * l).exp());
        }
    }
    sum * 0.5 * 2.0 * std::f64::consts::PI / (nu * nphi) as f64
}

/// The mean irradiance over the meter origin + a u + b v (3 x 3 Gauss-Legendre points).
fn meter_irradiance(origin: Vec3, u: Vec3, v: Vec3, c: usize) -> f64 {
    let g = [
        (0.5 - 0.5 * (0.6f64).sqrt(), 5.0 / 18.0),
        (0.5, 8.0 / 18.0),
        (0.5 + 0.5 * (0.6f64).sqrt(), 5.0 / 18.0),
    ];
    let n = u.cross(v).normalize();
    let mut sum = 0.0;
    for (a, wa) in g {
        for (b, wb) in g {
            let x = (origin.as_dvec3() + a * u.as_dvec3() + b * v.as_dvec3()).to_array();
            sum += wa * wb * irradiance(x, n, c);
        }
    }
    sum
}

/// Meters outside (facing the centre), at the centre and off-centre inside an absorbing,
/// emitting sphere: next-event estimation of the medium from the meter and the emission its
/// cosine-sampled walk collects, MIS-combined, against the quadrature.
#[test]
fn meters_and_an_emitting_sphere() {
    let h = (SIDE / 2.0) as f32;
    let s = SIDE as f32;
    let meters = [
        (
            "outside",
            Vec3::new(-h, -h, 2.0),
            Vec3::new(0.0, s, 0.0),
            Vec3::new(s, 0.0, 0.0),
        ),
        (
            "centre",
            Vec3::new(-h, -h, 0.0),
            Vec3::new(s, 0.0, 0.0),
            Vec3::new(0.0, s, 0.0),
        ),
        (
            "off-centre",
            Vec3::new(0.5, -h, -h),
            Vec3::new(0.0, s, 0.0),
            Vec3::new(0.0, 0.0, s),
        ),
    ];
    let v3 = |v: Vec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
    let mut text = format!(
        "[media.glow]\ntype = \"homogeneous\"\nsigma_a = [{}, {}, {}]\nsigma_s = 0.0\nemission = [{}, {}, {}]\n\n[[shapes]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = {R:.1}\nmaterial = \"null\"\ninterior = \"glow\"\n",
        SA[0], SA[1], SA[2], E[0], E[1], E[2]
    );
    for (name, o, u, v) in &meters {
        text += &format!(
            "\n[[sensors]]\ntype = \"irradiance_meter\"\nname = \"{name}\"\norigin = {}\nu = {}\nv = {}\n",
            v3(*o),
            v3(*u),
            v3(*v)
        );
    }
    let scene = load(&text);
    let mut fam = Family::new("meters and an emitting sphere");
    let kinds = [
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
    ];
    for (k, kind) in kinds.into_iter().enumerate() {
        let mut r = Renderer::new(&scene, kind, 31 + k as u64, None);
        r.meter_samples = 1 << 14;
        r.pass(1, &|| {});
        for (est, (name, o, u, v)) in r.meter_estimates().iter().zip(&meters) {
            assert_eq!(&est.name, name);
            for c in 0..3 {
                let (m, se, dof) = common::meter_mean(est, c);
                let truth = meter_irradiance(*o, *u, *v, c);
                let what = format!("{} {name} channel {c}", kind.name());
                fam.mean_is(&what, m, se, dof, truth);
            }
        }
    }
    fam.finish();
}

/// The quadrature itself: at the centre every chord is R, so E = pi (e / sa)(1 - exp(-sa R)).
#[test]
fn quadrature_at_the_centre_is_the_closed_form() {
    for c in 0..3 {
        let exact = std::f64::consts::PI * E[c] / SA[c] * (1.0 - (-SA[c] * R).exp());
        let q = irradiance([0.0, 0.0, 0.0], Vec3::Z, c);
        assert!((q - exact).abs() < 1e-6 * exact, "{q} vs {exact}");
    }
}

// ---- who takes it ----

/// Every integrator takes an emitting medium: each collects L_e,V0 (an integrator that did
/// not would refuse the scene by name: the default of `Facts::emitting_media_refusal`).
#[test]
fn every_integrator_takes_an_emitting_medium() {
    let scene = load(&furnace(
        "type = \"homogeneous\"\nsigma_a = 1.0\nsigma_s = 1.0\nemission = [1.0, 0.5, 2.0]",
    ));
    for kind in IntegratorKind::ALL.iter().copied() {
        let outcome = Renderer::try_new(&scene, kind, 1, None);
        assert!(outcome.is_ok(), "{}: {:?}", kind.name(), outcome.err());
    }
}

/// The guide and the adjoint image refuse an emitting medium by name, whatever the
/// integrator they run with would do: they represent light paths starting on the lights only.
#[test]
fn guide_and_adjoint_image_refuse_an_emitting_medium() {
    use pathspace::enlightened::GuideKind;
    use pathspace::render::Render;
    let text = furnace("type = \"homogeneous\"\nsigma_a = 1.0\nsigma_s = 1.0\nemission = 1.0");
    let src = SceneSource::embedded("emission.toml", &text);
    let (scene, settings) = pathspace::integrator::settings::load(&src).unwrap();
    for kind in [
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Mlt,
    ] {
        for (guide, adjoint) in [(true, false), (false, true), (true, true)] {
            let mut s = settings.clone();
            if guide {
                s.guide.kind = GuideKind::Both;
            }
            s.adjoint_image = adjoint;
            let e = match Render::new(&scene, &src, kind, s, None) {
                Ok(_) => panic!("{} with the guide or adjoint image rendered", kind.name()),
                Err(e) => e.to_string(),
            };
            let names = |w: &str| e.contains(w);
            assert!(
                names("`glow`") && names("emitting medium") && names("x0"),
                "{}: {e}",
                kind.name()
            );
            assert_eq!(names("guide"), guide, "{e}");
            assert_eq!(names("adjoint image"), adjoint, "{e}");
        }
    }
    // the path tracer takes the guide (not the adjoint image: it starts no light paths)
    let mut s = settings.clone();
    s.guide.kind = GuideKind::Volume;
    let e = match Render::new(&scene, &src, IntegratorKind::Path, s, None) {
        Ok(_) => panic!("path with the guide rendered an emitting medium"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("`glow`") && e.contains("the guide"), "path: {e}");
}

/// A scene without emission has no volume emitters: nothing is sampled, no random number
/// drawn (the images of such scenes are unchanged).
#[test]
fn no_emission_no_emitters() {
    let scene = load(&furnace(
        "type = \"homogeneous\"\nsigma_a = 1.0\nsigma_s = 1.0",
    ));
    assert!(scene.emitters.is_empty());
    assert!(!scene.media[0].emits());
}

/// The emitter's density integrates to one over its box and its power is 4 pi L_e,V0 times
/// the volume of the cells whose centre lies in the sphere (close to 4/3 pi R^3).
#[test]
fn volume_emitter_density_and_power() {
    let scene = load(&furnace(
        "type = \"homogeneous\"\nsigma_a = 1.0\nsigma_s = 0.0\nemission = 2.0",
    ));
    let em = &scene.emitters;
    assert_eq!(em.emitters.len(), 1);
    let mut s = common::sampler(7, 0);
    let (mut inside, n) = (0, 20000);
    for _ in 0..n {
        let u = Vec3::new(s.next_f32(), s.next_f32(), s.next_f32());
        let vs = em.sample(&scene, s.next_f32(), u).unwrap();
        assert!(
            (vs.pdf - em.pdf(0, vs.p)).abs() <= 1e-5 * vs.pdf,
            "pdf of the sample"
        );
        inside += (vs.p.length() < 1.0) as u32;
    }
    // the density integrates to 1: a Riemann sum over a fine lattice of the box
    let b = em.emitters[0].bounds;
    let k = 60;
    let cell = b.extent() / k as f32;
    let mut total = 0.0f64;
    for i in 0..k * k * k {
        let c = Vec3::new((i % k) as f32, ((i / k) % k) as f32, (i / (k * k)) as f32);
        total += em.pdf(0, b.min + cell * (c + 0.5)) as f64;
    }
    total *= (cell.x * cell.y * cell.z) as f64;
    assert!(
        (total - 1.0).abs() < 1e-3,
        "the density integrates to {total}"
    );
    assert!(
        inside as f64 > 0.8 * n as f64,
        "{inside} of {n} points in the sphere"
    );
    let p = em.power().x as f64;
    let ball = 4.0 * std::f64::consts::PI * 2.0 * 4.0 / 3.0 * std::f64::consts::PI;
    assert!((p / ball - 1.0).abs() < 0.1, "power {p} vs {ball}");
}
