//! The ray-marching estimator with the joint virtual domain (Pegoraro, Wald, Parker 2008,
//! eq. 8 and 9).
//!
//! eq. (8): over an interval dx where the medium is constant,
//!   L(x + dx) = kappa_t L(x) + kappa_s L_i,  kappa_t = e^(-sigma_t dx),
//!   kappa_s = (1 - e^(-sigma_t dx)) sigma_s / sigma_t.
//! eq. (9): both terms are one integral I over the virtual domain Omega_t U Omega_s, Omega_t a
//! single point of measure 1 (the transmission direction) and Omega_s the sphere (measure
//! 4 pi), so one sample decides between continuing the ray and scattering, and one ray
//! estimates both the transmitted and the in-scattered radiance.
//!
//! Predicates on the joint domain [PWP08 sec. 4.5]: G = kappa_s G_s + kappa_t L~(d) where G_s
//! is the cache's spherical integral and L~(d) its reconstruction in the transmission
//! direction d. On Omega_t, p = P_t and f = kappa_t L (a newly traced continuation); on
//! Omega_s, p = (1 - P_t) p(w) and f = kappa_s f_p L(w), with p(w) the cache's pdf mixed with
//! the phase function (is1 at the first [`super::ADAPTIVE_DEPTH`] vertices, [`super::DEFENSIVE`])
//! or the phase function.
//!
//! DEVIATION: eq. (8) evaluates L_i at the start of the interval, an O(dx) bias. Here the
//! scattering point is jittered in the interval by the free-flight density truncated to it,
//! q(s) = sigma(s) e^(-tau(s)) / (1 - e^(-tau(dx))) (channel means), and the in-scattered term
//! is weighted by sigma_s(s) e^(-tau(s)) / q(s), whose expectation is exactly
//! int_0^dx sigma_s e^(-tau(s)) L_i(x + s) ds: the march is unbiased, while g, G and the
//! sampling probabilities keep the paper's kappa_s.
//!
//! DEVIATION: the paper completes its probability tree on the fly with the masses
//! kappa_t c(d) and kappa_s mean(c) (c the pdf coefficients), so that
//! P_t = kappa_t c(d) / (kappa_t c(d) + kappa_s mean(c)). That choice is made at every step,
//! and a ray that passes n steps carries the product of n ratios (analog / adaptive) of which
//! a single small c(d) makes each large: even kept within a factor 4 of the analog probability
//! the image of the heterogeneous cloud came out 3% (step 1 mfp) to 8% (step 1/4 mfp) dark,
//! a heavy tail that the analog choice P_t = kappa_t / (kappa_t + kappa_s) does not have. The
//! control variate still covers the joint domain (G includes kappa_t L~(d)), which is where
//! the method's gain on the test bed comes from (book: "SMC: experiments").
//!
//! DEVIATION: steps have equal optical depth (`step` mean free paths), not equal length: the
//! same thing in a homogeneous medium, and in an inhomogeneous one the only way to keep the
//! number of decisions per mean free path bounded; each step's kappas use its exact optical
//! depth, so the medium is read along the whole step, not where the ray entered it.
//! Book: "SMC: the estimators", section "Ray marching on Omega_t U Omega_s (eq. 8, 9)".

use super::cache::RadianceCache;
use super::walk::{self, Link, Previous, Scratch, State};
use super::Smc;
use crate::geometry::{Hit, Ray};
use crate::math::{warp, Sampler};
use crate::medium::Medium;
use crate::scene::{Scene, SegmentEnd, Segments};
use crate::spectrum::{self, Rgb};

/// Marching steps along one medium segment at most: [`check_steps`] refuses a scene whose
/// longest segment needs more, so that abandoning a ray here never happens to an accepted
/// scene. (It did: with sigma_a = 1e9 in one channel, steps of one mean free path of the
/// channel mean are 3e-9 long, the ray was dropped after 2^20 of them, 3 mm into the medium,
/// and the two thin channels lost all the light beyond: 40 times too dark.) Every step leaves
/// a link and a record for the structure, so the count is also the memory of a path.
pub const MAX_MARCH_STEPS: usize = 1 << 12;

/// The most steps a march through `med` takes along one segment: steps have `step_mfp` mean
/// free paths of the channel-mean majorant, and a segment is at most `length` long.
pub fn max_steps(med: &Medium, step_mfp: f32, length: f32) -> f64 {
    let sigma = spectrum::average(med.sigma_t_max()) as f64;
    (sigma * length as f64 / step_mfp as f64).ceil() + 1.0
}

/// The longest segment through `med`: within its box (an inhomogeneous medium) and within the
/// scene's bounds (media are enclosed by closed shapes).
fn longest_segment(scene: &Scene, med: &Medium) -> f32 {
    if scene.bounds.is_empty() {
        return 0.0; // no shapes, so no medium is entered
    }
    let scene_diagonal = scene.bounds.extent().length();
    med.bounds()
        .map_or(scene_diagonal, |b| b.extent().length().min(scene_diagonal))
}

/// The most steps a march takes along one segment through any medium of `scene` (1 without
/// media): a path's records and links grow with it.
pub fn scene_max_steps(scene: &Scene, step_mfp: f32) -> f64 {
    scene
        .media
        .iter()
        .map(|m| max_steps(m, step_mfp, longest_segment(scene, m)))
        .fold(1.0, f64::max)
}

/// Refuses a march whose steps along some medium's longest segment exceed
/// [`MAX_MARCH_STEPS`].
pub fn check_steps(scene: &Scene, step_mfp: f32) -> Result<(), super::SmcError> {
    for (i, med) in scene.media.iter().enumerate() {
        let length = longest_segment(scene, med);
        let steps = max_steps(med, step_mfp, length);
        if steps.is_nan() || steps > MAX_MARCH_STEPS as f64 {
            return Err(super::SmcError::MarchSteps {
                medium: scene
                    .medium_names
                    .get(i)
                    .cloned()
                    .unwrap_or(format!("#{i}")),
                step: step_mfp,
                steps,
                sigma: spectrum::average(med.sigma_t_max()),
                length,
                limit: MAX_MARCH_STEPS,
            });
        }
    }
    Ok(())
}

/// The probability of Omega_t for masses `m_t` (transmission) and `m_s` (scattering).
#[inline]
fn transmit_probability(m_t: f64, m_s: f64) -> f64 {
    if m_s > 0.0 {
        m_t / (m_t + m_s)
    } else {
        1.0
    }
}

/// A point s in [0, dx) of the step `here` of mean optical depth `tau`, drawn by the free-flight
/// density truncated to the step, q(s) = sigma(s) e^(-tau(s)) / (1 - e^(-tau)) with the
/// channel means (inverted in optical depth, exactly), and the weight
/// sigma_s(s) e^(-tau(s)) / q(s) per channel that makes the in-scattered term unbiased for the
/// integral of sigma_s e^-tau L_i over the step. The third value is e^(-tau(s)) / q(s), the
/// weight of the emission L_e,V0 at s: unbiased for the step's source term, the integral of
/// e^-tau L_e,V0 (eq. 3), wherever q > 0, which holds wherever the medium has extinction.
#[inline]
fn jittered_point(
    med: &Medium,
    here: &Ray,
    dx: f32,
    tau: f32,
    sampler: &mut Sampler,
) -> (f32, Rgb, Rgb) {
    let u = sampler.next_f32();
    if tau.is_nan() || tau <= 0.0 {
        // no extinction in the step: nothing scatters (kappa_s is zero too), and s is uniform
        return (u * dx, Rgb::ZERO, Rgb::splat(dx));
    }
    let one_minus = -(-tau).exp_m1();
    let tau_s = -(1.0 - u * one_minus).ln();
    let s = med.advance(here, tau_s, dx).unwrap_or(dx).clamp(0.0, dx);
    let p = here.at(s);
    let tau_s = med.optical_depth(here, s);
    let q = spectrum::average(med.sigma_t(p)) * (-spectrum::average(tau_s)).exp() / one_minus;
    if q.is_nan() || q <= 0.0 {
        return (s, Rgb::ZERO, Rgb::ZERO);
    }
    let transmittance = (-tau_s).exp();
    (s, med.sigma_s(p) * transmittance / q, transmittance / q)
}

/// The marching walk of `state` (its ray, medium, throughput); `step_mfp` is the step in mean
/// free paths.
// ANCHOR: march
pub fn walk(
    smc: &Smc,
    scene: &Scene,
    mut state: State,
    step_mfp: f32,
    sampler: &mut Sampler,
    scratch: &mut Scratch,
) {
    let mut march = March {
        smc,
        scene,
        step_mfp,
        sampler,
        scratch,
    };
    while march.ray(&mut state) {}
}

/// What the march reads (the estimator, the scene, the step) and writes (the sampler, the
/// path's links), bundled for its parts.
struct March<'a> {
    smc: &'a Smc,
    scene: &'a Scene,
    step_mfp: f32,
    sampler: &'a mut Sampler,
    scratch: &'a mut Scratch,
}

/// How a medium segment or one of its steps ends.
enum Flow {
    /// The ray goes on (through the step, or past the segment).
    Through,
    /// The path scattered: `State` holds the new ray.
    Scattered,
    /// The path ended.
    End,
}

/// One step's quantities that the scattering branch (Omega_s) needs.
struct Step<'c> {
    d: glam::Vec3,
    kappa_s: Rgb,
    kappa_s_jit: Rgb,
    xs: glam::Vec3,
    cache_s: &'c RadianceCache,
    use_cache: bool,
    p_t: f32,
    big_g: Rgb,
    /// The step's emission, eq. (3)'s source term (zero in a medium that does not emit).
    emitted: Rgb,
}

impl March<'_> {
    /// Follows the state's ray through media and null boundaries to its next scattering
    /// vertex (the state then holds the new ray); false when the path ends.
    fn ray(&mut self, s: &mut State) -> bool {
        // the camera's rays see through hidden emitters until the first scattering vertex
        let segments = Segments::new(self.scene, s.ray, s.medium, f32::INFINITY);
        for seg in segments.from_camera(s.depth == 0) {
            if let Some(m) = seg.medium {
                match self.segment(s, m, seg.t0, seg.t1) {
                    Flow::Through => {}
                    Flow::Scattered => return true,
                    Flow::End => return false,
                }
            }
            // the end of the segment: background, null boundary or surface
            match seg.end {
                SegmentEnd::Null(_) => {}
                SegmentEnd::Open => {
                    let a = walk::escaped(self.scene, s.ray.d, &s.prev, s.depth);
                    self.scratch.links.push(Link::plain(a, Rgb::ZERO));
                    return false;
                }
                SegmentEnd::Surface(hit) => return self.surface(s, &hit, seg.medium),
            }
        }
        false
    }

    /// The steps of `step_mfp` mean free paths through the medium `m` from `t_start` to
    /// `t_hit`: equal optical depth, so that an inhomogeneous medium gets as many decisions per
    /// mean free path as a homogeneous one (see DEVIATION above).
    fn segment(&mut self, s: &mut State, m: u32, t_start: f32, t_hit: f32) -> Flow {
        let med = &self.scene.media[m as usize];
        let sigma_max = spectrum::average(med.sigma_t_max());
        // (a NaN majorant marches nothing, as a zero one)
        if sigma_max.is_nan() || sigma_max <= 0.0 {
            return Flow::Through;
        }
        let albedo = med.albedo();
        let mut t = t_start;
        let mut steps = 0;
        while t < t_hit {
            steps += 1;
            if steps > MAX_MARCH_STEPS {
                return Flow::End;
            }
            let here = Ray::new(s.ray.at(t), s.ray.d);
            let dx = med
                .advance(&here, self.step_mfp, t_hit - t)
                .unwrap_or(t_hit - t);
            match self.step(s, m, albedo, t, &here, dx) {
                Flow::Through => t += dx,
                flow => return flow,
            }
        }
        Flow::Through
    }

    /// One step of length `dx` from `t` (`here` the ray from there): eq. (8)'s kappas, the
    /// jittered scattering point, G, and the choice between Omega_t and Omega_s.
    fn step(&mut self, s: &mut State, m: u32, albedo: Rgb, t: f32, here: &Ray, dx: f32) -> Flow {
        let (smc, med) = (self.smc, &self.scene.media[m as usize]);
        let cv = smc.settings.variant.cv;
        let d = s.ray.d;
        // the step's exact optical depth (eq. 8's kappas for the medium as it is along the
        // step)
        let tau = med.optical_depth(here, dx);
        let kappa_t = (-tau).exp();
        let kappa_s = if s.depth < smc.max_depth {
            (Rgb::ONE - kappa_t) * albedo
        } else {
            Rgb::ZERO
        };
        // the scattering point, jittered in the step (see DEVIATION above); drawn before the
        // branch so that both branches share G
        let (sj, kappa_s_jit, emission_jit) =
            jittered_point(med, here, dx, spectrum::average(tau), self.sampler);
        let xs = s.ray.at(t + sj);
        // the step's source term, estimated at the same point: added whichever branch follows
        let emitted = if med.emits() {
            emission_jit * med.emission(xs)
        } else {
            Rgb::ZERO
        };
        let x_end = s.ray.at(t + dx);
        // the snapshot's caches: where the transmitted radiance L(x + dx, d) arrives, and
        // where the in-scattered radiance is estimated
        let cache_t = smc.octree.cache(x_end);
        let cache_s = smc.octree.cache(xs);
        // the vertex this step would scatter at: the (depth + 1)-th
        let use_cache = smc.adaptive(cache_s, s.depth + 1);
        // the choice between Omega_t and Omega_s by the analog masses kappa_t and kappa_s
        // (see DEVIATION above)
        let p_t = transmit_probability(
            spectrum::average(kappa_t) as f64,
            spectrum::average(kappa_s) as f64,
        ) as f32;
        // g on Omega_t and G on the joint domain
        let g_t = kappa_t * cache_t.radiance(d, cv);
        let big_g = kappa_s * cache_s.integral(cv) + g_t;
        if self.sampler.next_f32() < p_t {
            // Omega_t: the transmitted radiance, by continuing the ray
            let b = kappa_t / p_t;
            self.scratch.links.push(Link {
                a: walk::plus_emitted(big_g - g_t / p_t, emitted),
                b,
                record: Some((x_end, d, warp::INV_FOUR_PI)),
                roulette: None,
            });
            s.beta *= b;
            return Flow::Through;
        }
        let step = Step {
            d,
            kappa_s,
            kappa_s_jit,
            xs,
            cache_s,
            use_cache,
            p_t,
            big_g,
            emitted,
        };
        self.scatter(s, m, med, &step)
    }

    /// Omega_s: the in-scattered radiance at the jittered point; p is the joint density of
    /// (Omega_s, wi).
    fn scatter(&mut self, s: &mut State, m: u32, med: &Medium, st: &Step) -> Flow {
        let cv = self.smc.settings.variant.cv;
        let sampler = &mut *self.sampler;
        let p_s = 1.0 - st.p_t;
        let phase = med.phase();
        let wo = -st.d;
        let (wi, p) = if st.use_cache {
            let (wi, p_dir) = super::defensive_direction(st.cache_s, phase, wo, sampler);
            (wi, p_s * p_dir)
        } else {
            let ps = phase.sample(wo, sampler.next_2d());
            (ps.wi, p_s * ps.pdf)
        };
        if p.is_nan() || p <= 0.0 {
            if st.emitted != Rgb::ZERO {
                self.scratch.links.push(Link::plain(st.emitted, Rgb::ZERO));
            }
            return Flow::End;
        }
        let phase_value = phase.eval(wo, wi);
        let g = st.kappa_s * st.cache_s.g(wi, cv);
        let xs = st.xs;
        let delta = walk::delta_lights(self.scene, xs, Some(m), sampler, |w| phase.eval(wo, w));
        let b = st.kappa_s_jit * (phase_value / p);
        let mut link = Link {
            a: walk::plus_emitted(st.big_g - g / p + st.kappa_s_jit * delta / p_s, st.emitted),
            b,
            record: Some((xs, wi, phase_value)),
            roulette: None,
        };
        s.depth += 1;
        s.beta *= b;
        let c = st.cache_s.radiance(wi, cv);
        let alive = walk::roulette(s.depth, &mut s.beta, c, &mut link, sampler);
        self.scratch.links.push(link);
        if !alive {
            return Flow::End;
        }
        s.ray = Ray::new(xs, wi);
        s.medium = Some(m);
        s.prev = Previous::singular(xs);
        Flow::Scattered
    }

    /// A surface vertex (`walk::surface`); true when the path goes on from it.
    fn surface(&mut self, s: &mut State, hit: &Hit, medium: Option<u32>) -> bool {
        let st = walk::surface(self.scene, hit, medium, s, self.smc.max_depth, self.sampler);
        let Some((w, next_ray, next_medium, next_prev)) = st.next else {
            self.scratch.links.push(Link::plain(st.a, Rgb::ZERO));
            return false;
        };
        let mut link = Link::plain(st.a, w);
        s.beta *= w;
        let alive = walk::roulette(s.depth, &mut s.beta, Rgb::ZERO, &mut link, self.sampler);
        self.scratch.links.push(link);
        if !alive {
            return false;
        }
        s.ray = next_ray;
        s.medium = next_medium;
        s.prev = next_prev;
        true
    }
}
// ANCHOR_END: march
