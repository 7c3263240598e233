//! Primary-sample-space MLT (Kelemen et al. 2002; `integrator::pssmlt`) as a Markov chain:
//!
//! (a) Exact balance on an enumerable target. A target that reads two or three numbers (the
//!     third only in half of its states, as a walk that takes one more bounce) and is constant
//!     on 24 cells of the unit cube has the stationary distribution f* / b over the cells in
//!     closed form. Chains started from exact draws of f* (rejection sampling with the chain's
//!     own start) run the integrator's kernel (`kernel::KelemenChain::step`: the large and small
//!     steps and the acceptance) and their last states must still follow f* / b (Pearson's
//!     chi-square), for small steps alone, large steps alone and their mixture.
//! (b) Stationarity on a scene. On the 4 x 4 fog box, chains of the BDPT target
//!     (`sample::BdptTarget`) start from uniform states weighted by f*(u_0): for any kernel K
//!     that keeps f* / b invariant, E[f*(U_0) 1{X_n in j}] = b (f*/b K^n)(j) = integral of f*
//!     over cell j, which independent uniform samples estimate too. Cells are the film pixels
//!     of the state's film point; each pixel's two estimates are compared by Welch's test with
//!     Holm's correction.
//! (c) Determinism: the same seed gives the same image bit for bit on one thread or three.

use crate::common;

use glam::Vec2;
use pathspace::integrator::pssmlt::kernel::{start_chain, Deposit, KelemenChain, Target};
use pathspace::integrator::pssmlt::sample::{BdptTarget, STREAM_FILM};
use pathspace::integrator::pssmlt::{stream, PssmltSettings};
use pathspace::integrator::{IntegratorKind, RenderSettings, Renderer, Setup};
use pathspace::math::Sampler;
use pathspace::path::PLAIN;
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::{luminance, Rgb};
use rand::RngCore;
use rand_pcg::Pcg32;
use rayon::prelude::*;

use common::stats::Family;

// ------------------------------------------------------------------------------------------
// (a) the kernel on an enumerable target

/// f* on the cells (a, b) of the first two numbers (4 x 4; one cell is empty)...
const G: [[f64; 4]; 4] = [
    [0.0, 1.0, 2.0, 0.5],
    [3.0, 1.0, 0.2, 1.0],
    [1.0, 4.0, 1.0, 2.0],
    [0.5, 1.0, 6.0, 1.0],
];
/// ... times this factor of a third number's half c, read only when a >= 2.
const G2: [f64; 2] = [1.0, 3.0];
const F_MAX: f64 = 18.0;
const CELLS: usize = 8 + 16;

fn cell(a: usize, b: usize, c: usize) -> usize {
    if a < 2 {
        a * 4 + b
    } else {
        8 + ((a - 2) * 4 + b) * 2 + c
    }
}

/// The enumerable target: the numbers are read from three streams as a BDPT sample reads its
/// film point and walks; the value is deposited in two parts (a splat, then the sample's own),
/// and f* is their summed luminance, as the integrator's target makes it.
struct Discrete;

impl Target for Discrete {
    fn evaluate(&mut self, s: &mut Sampler, out: &mut Vec<Deposit>) -> f64 {
        out.clear();
        s.set_stream(0);
        let a = s.next_index(4);
        s.set_stream(1);
        let b = s.next_index(4);
        let mut f = G[a][b];
        if a >= 2 {
            s.set_stream(2);
            f *= G2[s.next_index(2)];
        }
        if f == 0.0 {
            return 0.0;
        }
        out.push((Vec2::ZERO, Rgb::splat(0.25 * f as f32)));
        out.push((Vec2::new(a as f32, b as f32), Rgb::splat(0.75 * f as f32)));
        out.iter().map(|(_, v)| luminance(*v) as f64).sum()
    }
}

/// The cell of a chain's current state (numbers it read are stored as the state's).
fn state_cell(chain: &mut KelemenChain) -> usize {
    let st = chain.state();
    let index = |v: f64, n: usize| ((v * n as f64) as usize).min(n - 1);
    let a = index(st.value(0, 0).unwrap(), 4);
    let b = index(st.value(1, 0).unwrap(), 4);
    let c = if a >= 2 {
        index(st.value(2, 0).unwrap(), 2)
    } else {
        0
    };
    cell(a, b, c)
}

/// The stationary distribution over the cells: f* times each cell's volume, normalized.
fn exact_cells() -> Vec<f64> {
    let mut p = [0.0; CELLS];
    for a in 0..4 {
        for b in 0..4 {
            if a < 2 {
                p[cell(a, b, 0)] += G[a][b] / 16.0;
            } else {
                for (c, g2) in G2.iter().enumerate() {
                    p[cell(a, b, c)] += G[a][b] * g2 / 32.0;
                }
            }
        }
    }
    let total: f64 = p.iter().sum();
    p.iter().map(|x| x / total).collect()
}

/// Chain `c` started from an exact draw of f* / b: states of the chain's own start
/// (`start_chain`) accepted with probability f* / F_MAX.
fn exact_start(c: u64, sigma: f64) -> KelemenChain {
    let mut rng = Pcg32::new(c, 0xacce);
    for k in 0.. {
        let own = stream(7, 2, c);
        if let Some(chain) = start_chain(stream(7, 1, c * 1000 + k), own, sigma, &mut Discrete) {
            let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
            if u * F_MAX < chain.f {
                return chain;
            }
        }
    }
    unreachable!()
}

/// The last cells of `n` chains of `steps` steps each.
fn last_cells(n: u64, steps: u32, large_step: f64, sigma: f64) -> (Vec<u64>, f64) {
    let parts: Vec<(usize, u64)> = (0..n)
        .into_par_iter()
        .map(|c| {
            let mut chain = exact_start(c, sigma);
            let mut accepted = 0;
            for _ in 0..steps {
                let o = chain.step(large_step, &mut Discrete, &mut |_, _| {});
                accepted += u64::from(o.accepted);
            }
            (state_cell(&mut chain), accepted)
        })
        .collect();
    let mut counts = vec![0u64; CELLS];
    let mut accepted = 0;
    for (i, a) in parts {
        counts[i] += 1;
        accepted += a;
    }
    (counts, accepted as f64 / (n * steps as u64) as f64)
}

#[test]
fn the_kelemen_kernel_keeps_an_enumerable_target_invariant() {
    let mut fam = Family::new("pssmlt: the kernel keeps f* invariant on 24 cells");
    let n = 20_000;
    let p = exact_cells();
    let expected: Vec<f64> = p.iter().map(|x| x * n as f64).collect();
    for (what, steps, large, sigma) in [
        ("small steps", 24, 0.0, 0.1),
        ("large steps", 6, 1.0, 0.1),
        ("mixed steps", 24, 0.3, 0.05),
    ] {
        let (counts, rate) = last_cells(n, steps, large, sigma);
        eprintln!("{what}: acceptance {rate:.3}, counts {counts:?}");
        // a chain that never moves would pass trivially
        assert!(rate > 0.2, "{what}: acceptance {rate}");
        fam.chi_square(what, &counts, &expected);
    }
    fam.finish();
}

// ------------------------------------------------------------------------------------------
// (b) the BDPT target on the fog box

const RES: u32 = 4;

fn fog_box() -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{RES}, {RES}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

/// The film pixel of a state's film point, as `BdptTarget` computes it.
fn pixel(chain: &mut KelemenChain) -> usize {
    let st = chain.state();
    let coord = |j| {
        let u = (st.value(STREAM_FILM, j).unwrap() as f32).min(1.0 - f32::EPSILON / 2.0);
        ((u * RES as f32) as usize).min(RES as usize - 1)
    };
    let (x, y) = (coord(0), coord(1));
    y * RES as usize + x
}

#[test]
fn chains_of_the_bdpt_target_keep_f_star_over_b_on_the_fog_box() {
    let scene = fog_box();
    let bdpt = pathspace::bidir::Bdpt::new(&PLAIN, Some(3), pathspace::bidir::Strategies::All);
    let pixels = (RES * RES) as usize;
    let (chains, steps, large, sigma) = (16_000u64, 16, 0.3, 0.02);
    // chain c starts from the uniform state of stream c, weighted by its f*
    let weighted: Vec<(usize, f64)> = (0..chains)
        .into_par_iter()
        .map(|c| {
            let mut target = BdptTarget::new(&scene, &bdpt);
            let Some(mut chain) = start_chain(stream(3, 1, c), stream(3, 2, c), sigma, &mut target)
            else {
                return (0, 0.0);
            };
            let w = chain.f;
            for _ in 0..steps {
                chain.step(large, &mut target, &mut |_, _| {});
            }
            (pixel(&mut chain), w)
        })
        .collect();
    // independent uniform states: f* in the pixel of their film point
    let uniform: Vec<(usize, f64)> = (0..chains)
        .into_par_iter()
        .map(|i| {
            let mut target = BdptTarget::new(&scene, &bdpt);
            match start_chain(stream(4, 1, i), stream(4, 2, i), sigma, &mut target) {
                Some(mut chain) => (pixel(&mut chain), chain.f),
                None => (0, 0.0),
            }
        })
        .collect();
    let mut fam = Family::new("pssmlt: chains keep f*/b on the fog box");
    for j in 0..pixels {
        let of = |v: &[(usize, f64)]| -> Vec<f64> {
            v.iter()
                .map(|&(p, w)| if p == j { w } else { 0.0 })
                .collect()
        };
        fam.runs_agree(&format!("pixel {j}"), &of(&weighted), &of(&uniform));
    }
    fam.finish();
}

/// The light subpath of a uniform primary-sample state starts where BDPT's does: it reads its
/// numbers with BDPT's own walk (`Bdpt::light_subpath`), so a volume vertex x0 of a glowing
/// fog is chosen with the media's share of the emitted power and lies uniformly in the
/// homogeneous fog's box (mean height 0, variance 1/3).
#[test]
fn primary_states_start_light_subpaths_at_a_volume_x0_by_power() {
    use pathspace::bidir::{volume_share, Bdpt, Strategies, WalkLimits};
    use pathspace::integrator::pssmlt::sample::STREAM_LIGHT;
    use pathspace::math::PrimarySamples;
    use pathspace::path::VertexKind;
    let text = "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 0.9]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 60.0\nresolution = [4, 4]\n\
        [materials.white]\ntype = \"lambert\"\nalbedo = 0.6\n\
        [media.fog]\ntype = \"homogeneous\"\nsigma_a = 0.3\nsigma_s = 0.7\nemission = 0.05\n\
        [[shapes]]\ntype = \"box\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\nmaterial = \"white\"\ninterior = \"fog\"\n\
        [[shapes]]\ntype = \"quad\"\norigin = [-0.3, 0.99, -0.3]\nu = [0.6, 0.0, 0.0]\nv = [0.0, 0.0, 0.6]\nemission = 5.0\n";
    let scene = Scene::load(&SceneSource::embedded("glowing-room", text)).unwrap();
    let share = volume_share(&scene) as f64;
    assert!(
        share > 0.2 && share < 0.8,
        "the share {share} tests both starts"
    );
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let n = 40_000u64;
    let heights: Vec<Option<f64>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut sampler = Sampler::primary(PrimarySamples::new(stream(7, 5, i), 0.01));
            sampler.chain().unwrap().start_iteration(true);
            sampler.set_stream(STREAM_LIGHT);
            let mut path = Vec::new();
            bdpt.light_subpath(&scene, WalkLimits::BDPT, &mut sampler, &mut path);
            let x0 = path.first().expect("every start succeeds here");
            matches!(x0.kind, VertexKind::Medium { .. }).then_some(x0.p.y as f64)
        })
        .collect();
    let y: Vec<f64> = heights.into_iter().flatten().collect();
    let mut fam = Family::new("pssmlt: light subpaths from a volume x0");
    fam.binomial("volume starts", y.len() as u64, n, share);
    let k = y.len() as f64;
    let mean = y.iter().sum::<f64>() / k;
    let var = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (k - 1.0);
    fam.samples_are("height of x0", mean, var, y.len() as u64, 0.0);
    fam.finish();
}

// ------------------------------------------------------------------------------------------
// (c) determinism

fn render(scene: &Scene, threads: usize) -> Vec<f32> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut settings = RenderSettings::for_scene(scene);
        settings.pssmlt = PssmltSettings {
            bootstrap: 2048,
            chains: 6,
            ..PssmltSettings::default()
        };
        let setup = Setup {
            scene,
            technique: &PLAIN,
            settings: &settings,
            seed: 5,
            max_depth: None,
        };
        let mut r = Renderer::prepared(IntegratorKind::Pssmlt, &setup).unwrap();
        r.pass(4, &|| {});
        r.pass(4, &|| {});
        let img = r.film.as_ref().unwrap().image();
        img.pixels.iter().flat_map(|p| p.to_array()).collect()
    })
}

#[test]
fn an_image_is_the_same_whatever_the_thread_count() {
    let scene = fog_box();
    let one = render(&scene, 1);
    let three = render(&scene, 3);
    assert!(one.iter().any(|&v| v > 0.0), "a black image");
    assert_eq!(
        one.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        three.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

// ------------------------------------------------------------------------------------------
// (d) the options

/// Every `--pssmlt-*` flag reaches PSSMLT's settings and no other table's (flags of nested
/// tables share field names: `chains`, `bootstrap`, `sigma`), and clap finds no clash.
#[test]
fn the_pssmlt_flags_are_their_own() {
    use clap::{CommandFactory, Parser};
    use pathspace::cli::{Cli, Command};
    pathspace::cli::Cli::command().debug_assert();
    let argv = [
        "pathspace",
        "render",
        "--pssmlt-chains",
        "3",
        "--pssmlt-bootstrap",
        "999",
        "--pssmlt-sigma",
        "0.02",
        "--pssmlt-large-step",
        "0.5",
        "--mlt-chains",
        "5",
        "--mlt-bootstrap",
        "77",
        "--guide-sigma",
        "0.03",
    ];
    let Some(Command::Render(args)) = Cli::try_parse_from(argv).unwrap().command else {
        panic!("not a render");
    };
    let o = &args.options;
    assert_eq!(
        (
            o.pssmlt.chains,
            o.pssmlt.bootstrap,
            o.pssmlt.sigma,
            o.pssmlt.large_step
        ),
        (Some(3), Some(999), Some(0.02), Some(0.5))
    );
    assert_eq!((o.mlt.chains, o.mlt.bootstrap), (Some(5), Some(77)));
    assert_eq!(o.guide.sigma, Some(0.03));
}

/// A scene of the repository at `RES` x `RES` pixels.
fn repository_scene(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("a repository scene");
    let at = text.find("resolution = [").expect("a resolution");
    let end = text[at..].find(']').expect("its end") + at + 1;
    let text = format!("{}resolution = [{RES}, {RES}]{}", &text[..at], &text[end..]);
    Scene::load(&SceneSource::embedded(name, &text)).expect("valid scene")
}

/// A chain starts from the bootstrap state it drew, re-created from that state's stream: the
/// re-creation reaches the bootstrap's f* bit for bit (and no chain where f* was 0), for
/// PSSMLT's and MMLT's targets, in a homogeneous fog, through glass into haze, in a glowing
/// plume and in the cloud, where a path reads a varying count of numbers. A replay that read
/// its numbers in another order would seed the chains away from f*/b.
#[test]
fn a_chain_starts_from_the_bootstrap_state_it_drew() {
    use pathspace::bidir::Scratch;
    use pathspace::integrator::mmlt::multiplexed_target;
    use pathspace::integrator::pssmlt::{bdpt_target, MakeTarget, Pssmlt};
    let settings = PssmltSettings {
        bootstrap: 1024,
        ..PssmltSettings::default()
    };
    for name in ["fog-box", "volume-caustic", "plume-glow", "cloud"] {
        let scene = repository_scene(name);
        for (kind, make) in [
            ("pssmlt", bdpt_target as MakeTarget),
            ("mmlt", multiplexed_target as MakeTarget),
        ] {
            let p = Pssmlt::with_target(&scene, &PLAIN, settings.clone(), 7, None, (kind, make))
                .expect("settings");
            let f = p.bootstrap(&scene);
            let mut replayed = 0;
            for (i, &fi) in f.iter().enumerate() {
                let mut target = (p.make_target)(&scene, &p.bdpt, Scratch::default());
                let got = p.replay(i as u64, 0, target.as_mut()).map_or(0.0, |c| c.f);
                assert_eq!(
                    got.to_bits(),
                    fi.to_bits(),
                    "{kind} on {name}, bootstrap state {i}: replay got f* = {got}, expected {fi}"
                );
                replayed += (fi > 0.0) as u32;
            }
            assert!(
                replayed > 16,
                "{kind} on {name}: only {replayed} states reach the camera"
            );
        }
    }
}
