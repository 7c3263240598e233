//! Multiplexed MLT (Hachisuka et al. 2014; `integrator::mmlt`): the target of one strategy per
//! state against BDPT's sample, and its chains' stationarity.
//!
//! (a) The multiplexed weights. For uniform u, a state's contribution
//!     (d + 2) / p(d) w_{s,t} f / p_{s,t} is one strategy of one depth; summed over the choices
//!     its expectation is BDPT's image only if the weights w_{s,t} of the strategies sum to one
//!     over s for every path, as BDPT's MIS weights do, and the choice's probability is the one
//!     divided by. Per pixel of the 4 x 4 fog box, the mean luminance the MMLT target deposits is
//!     compared with the BDPT sample's (PSSMLT's target) by Welch's test, at depth limits 3
//!     and 8 and without a limit, with Holm's correction.
//!     The same on a room lit by its glowing fog (light subpaths from volume vertices x0).
//! (b) Stationarity: chains of the MMLT target, started from uniform states weighted by
//!     f*(u_0), against independent uniform states (as `tests/spec/integrator/pssmlt.rs` (b)): a step that
//!     switches strategy must keep f*/b invariant like any other.
//! (c) No start-up bias: the mean of many short runs (bootstrap, normalization, chains) of the
//!     white furnace is 1.

use crate::common;

use pathspace::bidir::{Bdpt, Strategies};
use pathspace::integrator::mmlt::MultiplexedTarget;
use pathspace::integrator::pssmlt::kernel::{start_chain, KelemenChain, Target};
use pathspace::integrator::pssmlt::sample::{BdptTarget, STREAM_FILM};
use pathspace::integrator::pssmlt::stream;
use pathspace::math::{PrimarySamples, Sampler};
use pathspace::path::PLAIN;
use pathspace::scene::{Scene, SceneSource};
use pathspace::spectrum::luminance;
use rayon::prelude::*;

use common::stats::Family;

const RES: u32 = 4;

fn fog_box() -> Scene {
    let text = pathspace::scene::FOG_BOX.replace(
        "resolution = [256, 256]",
        &format!("resolution = [{RES}, {RES}]"),
    );
    Scene::load(&SceneSource::embedded("fog-box", &text)).expect("valid fog box")
}

/// The luminance a target deposits in each pixel for `n` uniform states of streams `salt`.
fn pixel_sums<T: Target>(
    make: impl Fn() -> T + Sync,
    n: u64,
    salt: u64,
) -> Vec<[f64; (RES * RES) as usize]> {
    const CHUNK: u64 = 1024;
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .flat_map_iter(|c| {
            let mut target = make();
            let mut out = Vec::new();
            let mut sampler = Sampler::primary(PrimarySamples::new(stream(9, salt, c), 0.01));
            (c * CHUNK..((c + 1) * CHUNK).min(n))
                .map(|i| {
                    let chain = sampler.chain().unwrap();
                    chain.restart(stream(9, salt, i));
                    chain.start_iteration(true);
                    target.evaluate(&mut sampler, &mut out);
                    let mut sums = [0.0; (RES * RES) as usize];
                    for (r, v) in &out {
                        let (x, y) = (r.x as usize, r.y as usize);
                        if x < RES as usize && y < RES as usize {
                            sums[y * RES as usize + x] += luminance(*v) as f64;
                        }
                    }
                    sums
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn the_multiplexed_target_deposits_bdpts_image() {
    let scene = fog_box();
    let mut fam = Family::new("mmlt: the multiplexed target's image is BDPT's");
    // the depth uniform under a limit, and p(d) = 1 / ((d + 1)(d + 2)) without one
    for depth in [Some(3), Some(8), None] {
        let bdpt = Bdpt::new(&PLAIN, depth, Strategies::All);
        let n = 200_000;
        let mmlt = pixel_sums(|| MultiplexedTarget::new(&scene, &bdpt), n, 1);
        let pssmlt = pixel_sums(|| BdptTarget::new(&scene, &bdpt), n, 2);
        for j in 0..(RES * RES) as usize {
            let a: Vec<f64> = mmlt.iter().map(|s| s[j]).collect();
            let b: Vec<f64> = pssmlt.iter().map(|s| s[j]).collect();
            fam.runs_agree(&format!("depth {depth:?}, pixel {j}"), &a, &b);
        }
    }
    fam.finish();
}

/// A closed room of Lambertian walls filled with glowing fog (L_e,V0 = 0.3), with or without a
/// ceiling light: light subpaths start at volume vertices x0 (all of them without the light).
fn glowing_room(ceiling_light: bool) -> Scene {
    let mut text = format!(
        "[camera]\ntype = \"pinhole\"\neye = [0.0, 0.0, 0.9]\nlook_at = [0.0, 0.0, 0.0]\nfov_deg = 60.0\nresolution = [{RES}, {RES}]\n\
         [materials.white]\ntype = \"lambert\"\nalbedo = 0.6\n\
         [media.fog]\ntype = \"homogeneous\"\nsigma_a = 0.3\nsigma_s = 0.7\nemission = 0.3\nphase = {{ type = \"hg\", g = 0.4 }}\n\
         [[shapes]]\ntype = \"box\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\nmaterial = \"white\"\ninterior = \"fog\"\n"
    );
    if ceiling_light {
        text += "[[shapes]]\ntype = \"quad\"\norigin = [-0.3, 0.99, -0.3]\nu = [0.6, 0.0, 0.0]\nv = [0.0, 0.0, 0.6]\nemission = 5.0\n";
    }
    Scene::load(&SceneSource::embedded("glowing-room", &text)).expect("valid glowing room")
}

/// (a) where x0 is a volume vertex: every strategy's weight in the multiplexed target
/// includes x0's density per unit volume (the light subpath's, next-event estimation's and the
/// eye walk's collision density for s = 0), so the target still deposits BDPT's image, in a
/// room lit by its fog alone (no light but the medium) and by fog and a ceiling light.
#[test]
fn the_multiplexed_target_deposits_bdpts_image_in_a_glowing_medium() {
    let mut fam = Family::new("mmlt: the multiplexed target's image is BDPT's, glowing fog");
    for light in [false, true] {
        let scene = glowing_room(light);
        for depth in [Some(3), None] {
            let bdpt = Bdpt::new(&PLAIN, depth, Strategies::All);
            let n = 100_000;
            let mmlt = pixel_sums(|| MultiplexedTarget::new(&scene, &bdpt), n, 3);
            let pssmlt = pixel_sums(|| BdptTarget::new(&scene, &bdpt), n, 4);
            for j in 0..(RES * RES) as usize {
                let a: Vec<f64> = mmlt.iter().map(|s| s[j]).collect();
                let b: Vec<f64> = pssmlt.iter().map(|s| s[j]).collect();
                let what = format!("ceiling light {light}, depth {depth:?}, pixel {j}");
                fam.runs_agree(&what, &a, &b);
            }
        }
    }
    fam.finish();
}

/// The film pixel of a state's film point, as the targets compute it.
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
fn chains_of_the_multiplexed_target_keep_f_star_over_b() {
    let scene = fog_box();
    let bdpt = Bdpt::new(&PLAIN, Some(3), Strategies::All);
    let (chains, steps, large, sigma) = (16_000u64, 16, 0.3, 0.05);
    let run = |salt: u64, steps: u32| -> Vec<(usize, f64)> {
        (0..chains)
            .into_par_iter()
            .map(|c| {
                let mut target = MultiplexedTarget::new(&scene, &bdpt);
                let own = stream(salt, 2, c);
                let Some(mut chain) = start_chain(stream(salt, 1, c), own, sigma, &mut target)
                else {
                    return (0, 0.0);
                };
                let w = chain.f;
                for _ in 0..steps {
                    chain.step(large, &mut target, &mut |_, _| {});
                }
                (pixel(&mut chain), w)
            })
            .collect()
    };
    let weighted = run(5, steps);
    let uniform = run(6, 0);
    let mut fam = Family::new("mmlt: chains keep f*/b on the fog box");
    for j in 0..(RES * RES) as usize {
        let of = |v: &[(usize, f64)]| -> Vec<f64> {
            v.iter()
                .map(|&(p, w)| if p == j { w } else { 0.0 })
                .collect()
        };
        fam.runs_agree(&format!("pixel {j}"), &of(&weighted), &of(&uniform));
    }
    fam.finish();
}

/// (c) No start-up bias: many short runs of the white furnace (every pixel exactly 1), each with
/// its own bootstrap, are unbiased in the mean, even where a run is mostly its start (a
/// bootstrap of 256 states and 64 steps per chain). A run's estimate is skewed (a few runs
/// whose chains found a bright, rarely sampled strategy read high, most a little low), so a
/// handful of runs leans low by chance; the mean over many runs must not.
#[test]
fn short_runs_are_unbiased_on_the_white_furnace() {
    use pathspace::integrator::mmlt::multiplexed_target;
    use pathspace::integrator::pssmlt::{Pssmlt, PssmltSettings};
    use pathspace::integrator::{IntegratorKind, Renderer};
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace.toml"))
        .unwrap()
        .replace("resolution = [32, 32]", "resolution = [8, 8]");
    let scene = Scene::load(&SceneSource::embedded("furnace", &text)).unwrap();
    let mut fam = Family::new("mmlt: short runs on the white furnace");
    // (bootstrap, mutations per pixel, runs): 64 and 1024 steps per chain of 4
    for (bootstrap, spp, runs) in [(256, 4, 2048), (1024, 64, 512)] {
        let settings = PssmltSettings {
            bootstrap,
            chains: 4,
            ..PssmltSettings::default()
        };
        let means: Vec<f64> = (0..runs)
            .into_par_iter()
            .map(|i| {
                let seed = 7000 + i;
                let mut r = Renderer::new(&scene, IntegratorKind::Mmlt, seed, None);
                let target = ("mmlt", multiplexed_target as _);
                let chains =
                    Pssmlt::with_target(&scene, &PLAIN, settings.clone(), seed, None, target);
                r.integrator = Box::new(chains.unwrap());
                r.pass(spp, &|| {});
                let img = r.film.as_ref().unwrap().image();
                let n = (img.width * img.height) as f64;
                img.pixels.iter().map(|p| p[0] as f64).sum::<f64>() / n
            })
            .collect();
        fam.runs_are(
            &format!("bootstrap {bootstrap}, {spp} mutations per pixel"),
            &means,
            1.0,
        );
    }
    fam.finish();
}

/// (a) on the volume caustic (a spot light focused by a glass sphere into haze, no depth
/// limit): the caustic's paths have one strategy each (light tracing through the glass, t = 1),
/// and the multiplexed target still deposits BDPT's image pixel by pixel.
#[test]
fn the_multiplexed_target_deposits_bdpts_image_on_the_volume_caustic() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/volume-caustic.toml"
    ))
    .expect("the volume caustic");
    let at = text.find("resolution = [").expect("a resolution");
    let end = text[at..].find(']').expect("its end") + at + 1;
    let text = format!("{}resolution = [{RES}, {RES}]{}", &text[..at], &text[end..]);
    let scene = Scene::load(&SceneSource::embedded("volume-caustic", &text)).expect("valid");
    let bdpt = Bdpt::new(&PLAIN, None, Strategies::All);
    let n = 400_000;
    let mmlt = pixel_sums(|| MultiplexedTarget::new(&scene, &bdpt), n, 5);
    let pssmlt = pixel_sums(|| BdptTarget::new(&scene, &bdpt), n, 6);
    let mut fam = Family::new("mmlt: the multiplexed target's image is BDPT's, volume caustic");
    for j in 0..(RES * RES) as usize {
        let a: Vec<f64> = mmlt.iter().map(|s| s[j]).collect();
        let b: Vec<f64> = pssmlt.iter().map(|s| s[j]).collect();
        fam.runs_agree(&format!("pixel {j}"), &a, &b);
    }
    fam.finish();
}
