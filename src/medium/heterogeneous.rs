//! Inhomogeneous media: Table 1, right column, and section 4.1 of Pauly, Kollig, Keller 2000.
//!
//! sigma_t(x) = density(x) sigma_t with a scalar density field (a grid, an analytic or a
//! procedural field, zero outside the medium's box) times RGB coefficients. The transmittance
//! is exp(-tau), tau(t) = integral_0^t sigma_t(x + s w) ds; a collision distance d solves the
//! implicit equation of Table 1, -ln(1 - xi) = tau(d), and has density sigma_t(x') exp(-tau(d)).
//!
//! Two families solve it ([`LineIntegral`]):
//! * ray marching (sec. 4.1), biased for a finite step Delta: the ray is cut into segments of
//!   length Delta and sigma_t is evaluated at one point per segment, at the midpoint
//!   (equidistant), at an independent uniform point (stratified, jittering) or at the same
//!   random offset in every segment (random offset, the paper's method); sigma_t is accumulated
//!   until -ln(1 - xi) is reached or the segment ends;
//! * tracking, unbiased: delta (Woodcock) tracking samples tentative collisions with a majorant
//!   sigma_bar >= sigma_t and accepts one with probability sigma_t / sigma_bar; ratio tracking
//!   estimates transmittance as the product of (1 - sigma_t / sigma_bar) over tentative
//!   collisions (with Russian roulette once the estimate is small). The majorant is a coarse
//!   grid of block maxima, so empty blocks are skipped.
//!
//! Chromatic media: a channel is picked uniformly and the distance sampled with its sigma_t;
//! the recorded pdf is the average of the three channels' pdfs (one-sample MIS), as for the
//! homogeneous medium. All channels share the scalar density, so they share the integral of
//! the density D(t) and tau_c = sigma_t[c] D.
//!
//! Book: "Table 1: inhomogeneous media" (`book/src/table1-inhomogeneous.md`); executable spec:
//! `tests/spec/medium/heterogeneous.rs`.

use glam::Vec3;

use crate::geometry::{Aabb, Ray};
use crate::math::Sampler;
use crate::spectrum::{average, Rgb};

use super::grid::{cell_segments, cell_spans, EmptyCells, Grid, GAUSS2};
use super::procedural::Field;
use super::{FreeFlight, MediumError, Phase, WeightedFlight};

/// The number of colour channels a distance can be sampled for (`Rgb` has three).
const N_CHANNELS: usize = 3;
/// Blocks per axis of the majorant grid (a block's majorant is the field's bound over it): 8,
/// the cloud's most efficient of 8, 16 and 32 (book: "Where the time goes", "The cloud,
/// profiled").
pub const MAJORANT_RES: usize = 8;
/// Russian roulette in ratio tracking: once the running estimate is below this in every
/// channel, each tentative collision may end the walk. pbrt-v4's rule
/// (`VolPathIntegrator::SampleLd`, "Possibly terminate transmittance computation using Russian
/// roulette") with its threshold 0.05 raised to 0.2, the more efficient on the cloud.
pub const RR_THRESHOLD: f32 = 0.2;
/// The probability that a walk below [`RR_THRESHOLD`] ends at a tentative collision
/// (pbrt-v4: q = 0.75); a survivor's estimate is divided by 1 - RR_Q, so its mean is kept.
pub const RR_Q: f32 = 0.75;
/// Cells per axis of the fixed Gauss-Legendre quadrature that stands in for the exact optical
/// depth of procedural fields (those without a closed form).
pub const PROCEDURAL_QUADRATURE_RES: usize = 256;

/// Steps a ray march may take across the medium's box (its diagonal over the step Delta): a
/// smaller step is refused, because the march's work per ray segment is this count.
pub const MAX_MARCH_STEPS: f32 = 1e5;
/// Tentative collisions a tracking walk may expect across the medium's box (the majorant's
/// optical depth along the diagonal): a denser medium is refused, because ratio tracking
/// visits every tentative collision of a segment while any channel still transmits.
pub const MAX_TRACKING_DEPTH: f32 = 1e5;

/// How the line integral of sigma_t is computed along a ray (Pauly et al. sec. 4.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineIntegral {
    /// Ray marching with step Delta, sigma_t at each segment's midpoint (biased, aliasing).
    Equidistant,
    /// Ray marching with an independent uniform point in each segment (jittering).
    Stratified,
    /// Ray marching with one uniform offset shared by all segments of a ray [PKK00 sec. 4.1].
    RandomOffset,
    /// Delta tracking for distances, ratio tracking for transmittance (unbiased).
    DeltaTracking,
}

/// How a tracking medium estimates the transmittance of a shadow ray or a connection
/// (`[render] transmittance`, `--transmittance`; book: "Table 1: inhomogeneous media").
/// Both are unbiased; the marching strategies ignore it (their transmittance is the marched
/// exp(-sigma_t D)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum TransmittanceEstimator {
    /// Ratio tracking: the product of (1 - sigma_t / sigma_bar) over the tentative collisions
    /// (Novak et al. 2014), a value in [0, 1].
    #[default]
    RatioTracking,
    /// Delta tracking: 1 if the walk passes every tentative collision, 0 at the first real
    /// one (each channel its own Bernoulli thinning of the same tentative collisions).
    DeltaTracking,
}

crate::option_value!(TransmittanceEstimator, "transmittance estimator");

/// A propagation name the scene format does not know (`LineIntegral::parse`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown propagation `{0}` (one of: {names})", names = LineIntegral::ALL.map(LineIntegral::name).join(", "))]
pub struct UnknownPropagation(pub String);

/// The command line reports errors as text.
impl From<UnknownPropagation> for String {
    fn from(e: UnknownPropagation) -> String {
        e.to_string()
    }
}

impl LineIntegral {
    /// The scene-file spelling.
    pub fn name(self) -> &'static str {
        match self {
            LineIntegral::Equidistant => "equidistant",
            LineIntegral::Stratified => "stratified",
            LineIntegral::RandomOffset => "random-offset",
            LineIntegral::DeltaTracking => "delta-tracking",
        }
    }

    /// Every strategy, in the order of the paper (then tracking).
    pub const ALL: [LineIntegral; 4] = [
        LineIntegral::Equidistant,
        LineIntegral::Stratified,
        LineIntegral::RandomOffset,
        LineIntegral::DeltaTracking,
    ];

    /// From the scene-file spelling.
    pub fn parse(s: &str) -> Result<Self, UnknownPropagation> {
        Self::ALL
            .into_iter()
            .find(|l| l.name() == s)
            .ok_or_else(|| UnknownPropagation(s.to_string()))
    }

    /// True for the ray-marching strategies, biased for any finite step.
    pub fn is_marching(self) -> bool {
        !matches!(self, LineIntegral::DeltaTracking)
    }
}

/// A scalar density field on the local unit cube of the medium's box.
#[derive(Clone, Debug, PartialEq)]
pub enum Density {
    Field(Field),
    Grid(Grid),
}

impl Density {
    #[inline]
    pub fn eval(&self, u: Vec3) -> f32 {
        match self {
            Density::Field(f) => f.eval(u),
            Density::Grid(g) => g.eval(u),
        }
    }

    /// An upper bound over the local box [lo, hi].
    pub fn max_in(&self, lo: Vec3, hi: Vec3) -> f32 {
        match self {
            Density::Field(f) => f.max_in(lo, hi),
            Density::Grid(g) => g.max_in(lo, hi),
        }
    }

    /// D = the integral of the density over t in [ta, tb] along u(t) = u0 + t du: closed form
    /// for the analytic fields, exact cell-by-cell quadrature for grids.
    /// DEVIATION: procedural fields use a fixed Gauss-Legendre rule on a 256^3 lattice
    /// ([`PROCEDURAL_QUADRATURE_RES`]), a deterministic approximation of the exact integral.
    pub fn integrate(&self, u0: Vec3, du: Vec3, ta: f32, tb: f32) -> f32 {
        if tb <= ta {
            return 0.0;
        }
        match self {
            Density::Grid(g) => g.integrate(u0, du, ta, tb),
            Density::Field(f) => f.integrate_closed_form(u0, du, ta, tb).unwrap_or_else(|| {
                let q = PROCEDURAL_QUADRATURE_RES as f32;
                cell_spans(u0 * q, du * q, ta, tb)
                    .map(|(a, b)| {
                        let h = b - a;
                        let f0 = f.eval(u0 + du * (a + GAUSS2[0] * h));
                        let f1 = f.eval(u0 + du * (a + GAUSS2[1] * h));
                        0.5 * h * (f0 + f1)
                    })
                    .sum()
            }),
        }
    }
}

/// A medium with a spatially varying density.
#[derive(Clone, Debug, PartialEq)]
pub struct Heterogeneous {
    pub density: Density,
    /// The density is zero outside this box; the field's local coordinates span it.
    pub bounds: Aabb,
    /// Coefficients per unit density: sigma(x) = density(x) sigma.
    pub sigma_a: Rgb,
    pub sigma_s: Rgb,
    pub sigma_t: Rgb,
    pub phase: Phase,
    pub line_integral: LineIntegral,
    /// The marching step Delta (world units).
    pub delta: f32,
    /// L_e,V0 per unit density (eq. 1): emission(x) = density(x) emission, like sigma_a and
    /// sigma_s (zero for a medium that does not glow).
    pub emission: Rgb,
    /// The tracking strategy's transmittance estimator.
    pub transmittance_estimator: TransmittanceEstimator,
    /// Block maxima of the density on a `MAJORANT_RES`^3 grid over the box.
    majorant: Vec<f32>,
    /// A grid density's cells of zero density, which its line integrals skip.
    empty_cells: Option<EmptyCells>,
}

/// A ray segment in the medium's local frame, clipped to the box: u(t) = u0 + t du, t in
/// [t0, t1].
#[derive(Clone, Copy, Debug)]
struct Local {
    u0: Vec3,
    du: Vec3,
    t0: f32,
    t1: f32,
}

/// Where a march or a tracking walk stopped.
enum Walk {
    /// A collision at `t` where the density (the marched box value, or the true density for
    /// tracking) is `f`.
    Collision {
        t: f32,
        f: f32,
    },
    Passage,
}

impl Heterogeneous {
    /// Validated constructor. `relative_step` is the user's base step as a fraction of the
    /// box's largest side: Delta = relative_step * max extent [PKK00 sec. 4.1: "derived from a
    /// user-specified base stepsize, taking into account ... the extent of the medium"].
    pub fn new(
        density: Density,
        bounds: Aabb,
        sigma_a: Rgb,
        sigma_s: Rgb,
        phase: Phase,
        line_integral: LineIntegral,
        relative_step: f32,
    ) -> Result<Self, MediumError> {
        for (name, v) in [("sigma_a", sigma_a), ("sigma_s", sigma_s)] {
            for c in v.to_array() {
                if !c.is_finite() || c < 0.0 {
                    return Err(MediumError::NegativeCoefficient { name, value: c });
                }
            }
        }
        let m = MAJORANT_RES as f32;
        let mut majorant = Vec::with_capacity(MAJORANT_RES.pow(3));
        for z in 0..MAJORANT_RES {
            for y in 0..MAJORANT_RES {
                for x in 0..MAJORANT_RES {
                    let lo = Vec3::new(x as f32, y as f32, z as f32) / m;
                    majorant.push(density.max_in(lo, lo + Vec3::splat(1.0 / m)));
                }
            }
        }
        let empty_cells = match &density {
            Density::Grid(g) => Some(EmptyCells::new(g)),
            Density::Field(_) => None,
        };
        let h = Heterogeneous {
            density,
            bounds,
            sigma_a,
            sigma_s,
            sigma_t: sigma_a + sigma_s,
            phase,
            line_integral,
            delta: relative_step * bounds.extent().max_element(),
            emission: Rgb::ZERO,
            transmittance_estimator: TransmittanceEstimator::RatioTracking,
            majorant,
            empty_cells,
        };
        h.check_work(relative_step)?;
        Ok(h)
    }

    /// The work per ray segment is bounded by the scene: a march takes at most
    /// [`Heterogeneous::march_steps`] steps, tracking expects at most
    /// [`Heterogeneous::tracking_depth`] tentative collisions; either above its limit is refused.
    fn check_work(&self, relative_step: f32) -> Result<(), MediumError> {
        if self.line_integral.is_marching() {
            let steps = self.march_steps();
            if steps.is_nan() || steps > MAX_MARCH_STEPS {
                return Err(MediumError::MarchSteps {
                    step: relative_step,
                    steps,
                    limit: MAX_MARCH_STEPS,
                });
            }
        } else {
            let depth = self.tracking_depth();
            if depth.is_nan() || depth > MAX_TRACKING_DEPTH {
                return Err(MediumError::TrackingDepth {
                    depth,
                    sigma: self.sigma_t.max_element(),
                    density: self.max_density(),
                    diagonal: self.bounds.extent().length(),
                    limit: MAX_TRACKING_DEPTH,
                });
            }
        }
        Ok(())
    }

    /// The most steps a march takes along one ray segment: a segment is clipped to the box,
    /// so it is at most the box's diagonal over Delta, plus the last partial step.
    pub fn march_steps(&self) -> f32 {
        (self.bounds.extent().length() / self.delta).ceil() + 1.0
    }

    /// The expected number of tentative collisions of a tracking walk along the longest segment
    /// (the box's diagonal) at the largest majorant: max sigma_t x max density x diagonal.
    pub fn tracking_depth(&self) -> f32 {
        self.sigma_t.max_element() * self.max_density() * self.bounds.extent().length()
    }

    /// The density at world point `p` (zero outside the box).
    #[inline]
    pub fn density_at(&self, p: Vec3) -> f32 {
        if p.cmplt(self.bounds.min).any() || p.cmpgt(self.bounds.max).any() {
            return 0.0;
        }
        self.density
            .eval((p - self.bounds.min) / self.bounds.extent())
    }

    /// The largest density anywhere (the maximum of the majorant grid).
    pub fn max_density(&self) -> f32 {
        self.majorant.iter().copied().fold(0.0, f32::max)
    }

    /// The part of [0, t_max) of `ray` inside the box, in local coordinates.
    #[inline]
    fn local(&self, ray: &Ray, t_max: f32) -> Option<Local> {
        let (t0, t1) = self.bounds.intersect(ray, ray.d.recip(), t_max)?;
        let inv = self.bounds.extent().recip();
        (t1 > t0).then(|| Local {
            u0: (ray.o - self.bounds.min) * inv,
            du: ray.d * inv,
            t0,
            t1,
        })
    }

    /// The exact integral D of the density over [0, t] along `ray`; tau = sigma_t D.
    pub fn density_integral(&self, ray: &Ray, t: f32) -> f32 {
        match self.local(ray, t) {
            Some(l) => self.integrate(&l, l.t0, l.t1),
            None => 0.0,
        }
    }

    /// [`Density::integrate`] over [ta, tb] along the local segment, a grid's empty cells
    /// skipped (bit for bit the same value).
    #[inline]
    fn integrate(&self, l: &Local, ta: f32, tb: f32) -> f32 {
        match (&self.density, &self.empty_cells) {
            (Density::Grid(g), Some(empty)) if tb > ta => {
                g.integrate_skipping(empty, l.u0, l.du, ta, tb)
            }
            _ => self.density.integrate(l.u0, l.du, ta, tb),
        }
    }

    /// The distance along `ray` at which the density integral D reaches `target`, if it does
    /// before `t_max`: the exact inverse of [`Heterogeneous::density_integral`], found block by
    /// block of the majorant grid and by bisection inside the block where D crosses the target
    /// (SMC's march takes steps of equal optical depth with it).
    pub fn invert_density_integral(&self, ray: &Ray, target: f32, t_max: f32) -> Option<f32> {
        /// Bisection steps: the bracket shrinks below f32 resolution of any block long before.
        const BISECTIONS: usize = 40;
        if target <= 0.0 {
            return Some(0.0);
        }
        let l = self.local(ray, t_max)?;
        let mut acc = 0.0f32;
        for (a, b, m) in self.majorant_segments(&l) {
            if m <= 0.0 {
                continue;
            }
            let piece = self.integrate(&l, a, b);
            if acc + piece < target {
                acc += piece;
                continue;
            }
            let (mut lo, mut hi) = (a, b);
            for _ in 0..BISECTIONS {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if acc + self.integrate(&l, a, mid) < target {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return Some(hi);
        }
        None
    }

    // ANCHOR: march
    /// Ray marching [PKK00 sec. 4.1]: accumulates the density integral D over segments of
    /// length Delta from the box entry, one density sample per segment, until `target` is
    /// reached (inside the segment, the collision is placed by inverting the box rule) or the
    /// segment ends. Returns the walk's outcome and the marched D at its end.
    fn march(&self, l: &Local, target: f32, sampler: &mut Sampler) -> (Walk, f32) {
        let delta = self.delta;
        // random offset: one offset for the whole ray
        let offset = match self.line_integral {
            LineIntegral::RandomOffset => sampler.next_f32(),
            _ => 0.5,
        };
        let mut acc = 0.0f32;
        let mut s = l.t0;
        while s < l.t1 {
            let e = (s + delta).min(l.t1);
            let len = e - s;
            let u = match self.line_integral {
                LineIntegral::Stratified => sampler.next_f32(), // jittering
                _ => offset,
            };
            let f = self.density.eval(l.u0 + l.du * (s + u * len));
            let step = len * f;
            if acc + step >= target && step > 0.0 {
                // [PKK00 Table 1] -ln(1 - xi) = tau(d), with sigma_t constant on the segment
                let t = (s + (target - acc) / f).min(e);
                return (Walk::Collision { t, f }, target);
            }
            acc += step;
            s = e;
        }
        (Walk::Passage, acc)
    }
    // ANCHOR_END: march

    /// The majorant pieces along the local segment: (t_start, t_end, block maximum density).
    fn majorant_segments(&self, l: &Local) -> impl Iterator<Item = (f32, f32, f32)> + '_ {
        let m = MAJORANT_RES as f32;
        cell_segments(l.u0 * m, l.du * m, l.t0, l.t1, [MAJORANT_RES; 3])
            .map(move |(a, b, c)| (a, b, self.majorant[c]))
    }

    // ANCHOR: delta_tracking
    /// Delta (Woodcock) tracking with sigma_t = k density: tentative collisions at rate
    /// k max_density per majorant block (empty blocks are skipped), each accepted with
    /// probability density / max_density. The accepted distance has exactly the density
    /// sigma_t(x) exp(-tau) of Table 1.
    fn delta_tracking(&self, l: &Local, k: f32, sampler: &mut Sampler) -> Walk {
        if k <= 0.0 {
            return Walk::Passage;
        }
        // remaining majorant optical depth to the next tentative collision
        let mut s = -(1.0 - sampler.next_f32()).ln();
        for (a, b, m) in self.majorant_segments(l) {
            let rate = k * m;
            if rate <= 0.0 {
                continue;
            }
            let mut t = a;
            loop {
                let dt = s / rate;
                if t + dt >= b {
                    s = (s - (b - t) * rate).max(0.0);
                    break;
                }
                t += dt;
                let f = self.density.eval(l.u0 + l.du * t);
                if sampler.next_f32() * m < f {
                    return Walk::Collision { t, f };
                }
                s = -(1.0 - sampler.next_f32()).ln();
            }
        }
        Walk::Passage
    }
    // ANCHOR_END: delta_tracking

    // ANCHOR: ratio_tracking
    /// Ratio tracking: an unbiased estimate of exp(-tau) per channel, the product of
    /// (1 - sigma_t(x) / sigma_bar) over tentative collisions drawn at the majorant rate
    /// sigma_bar = max_c(sigma_t[c]) max_density (Novak, Selle, Jarosz 2014). A walk whose
    /// estimate has fallen below [`RR_THRESHOLD`] in every channel plays Russian roulette at
    /// each tentative collision (pbrt-v4's rule): its expectation is unchanged, and walks
    /// through dense regions, which would carry a tiny estimate to the segment's end, mostly
    /// stop early.
    fn ratio_tracking(&self, l: &Local, sampler: &mut Sampler) -> Rgb {
        // ASSIGNMENT: ratio_tracking
        let k_max = self.sigma_t.max_element();
        if k_max <= 0.0 {
            return Rgb::ONE;
        }
        let mut tr = Rgb::ONE;
        let mut s = -(1.0 - sampler.next_f32()).ln();
        for (a, b, m) in self.majorant_segments(l) {
            let rate = k_max * m;
            if rate <= 0.0 {
                continue;
            }
            let mut t = a;
            loop {
                let dt = s / rate;
                if t + dt >= b {
                    s = (s - (b - t) * rate).max(0.0);
                    break;
                }
                t += dt;
                let f = self.density.eval(l.u0 + l.du * t);
                tr *= (Rgb::ONE - self.sigma_t * (f / rate)).max(Rgb::ZERO);
                if tr == Rgb::ZERO {
                    return tr;
                }
                if tr.max_element() < RR_THRESHOLD {
                    // Russian roulette: the walk ends (estimate 0) with probability RR_Q, a
                    // survivor's estimate is divided by its probability 1 - RR_Q
                    if sampler.next_f32() < RR_Q {
                        return Rgb::ZERO;
                    }
                    tr /= 1.0 - RR_Q;
                }
                s = -(1.0 - sampler.next_f32()).ln();
            }
        }
        tr
        // END ASSIGNMENT
    }
    // ANCHOR_END: ratio_tracking

    /// Delta tracking as a transmittance estimator: the tentative collisions of ratio tracking
    /// (rate sigma_bar), channel c's walk ended at one with probability sigma_t[c](x) /
    /// sigma_bar, one uniform number shared by the channels. Each channel's estimate is 1 or 0
    /// with mean exp(-tau_c); ratio tracking is its expectation given the tentative collisions,
    /// so its variance is never larger, while this walk stops at the first real collision.
    fn delta_tracking_transmittance(&self, l: &Local, sampler: &mut Sampler) -> Rgb {
        let k_max = self.sigma_t.max_element();
        if k_max <= 0.0 {
            return Rgb::ONE;
        }
        let mut alive = Rgb::ONE;
        let mut s = -(1.0 - sampler.next_f32()).ln();
        for (a, b, m) in self.majorant_segments(l) {
            let rate = k_max * m;
            if rate <= 0.0 {
                continue;
            }
            let mut t = a;
            loop {
                let dt = s / rate;
                if t + dt >= b {
                    s = (s - (b - t) * rate).max(0.0);
                    break;
                }
                t += dt;
                let f = self.density.eval(l.u0 + l.du * t);
                let xi = sampler.next_f32();
                let real = (self.sigma_t * (f / rate)).cmpgt(Rgb::splat(xi));
                alive = Rgb::select(real, Rgb::ZERO, alive);
                if alive == Rgb::ZERO {
                    return alive;
                }
                s = -(1.0 - sampler.next_f32()).ln();
            }
        }
        alive
    }

    // ANCHOR: heterogeneous_sample
    /// Table 1, right column: a collision distance in [0, t_max) along `ray`, or passage.
    pub fn sample_free_flight(&self, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> FreeFlight {
        // one channel c chosen uniformly, distances with sigma_t[c] (one-sample MIS)
        let c = sampler.next_index(N_CHANNELS);
        let k = self.sigma_t[c];
        let passage = |d: f32, t: f32| {
            let tr = (-self.sigma_t * d).exp();
            FreeFlight {
                t,
                scattered: false,
                transmittance: tr,
                sigma_s: Rgb::ZERO,
                pdf: average(tr),
            }
        };
        let collision = |d: f32, t: f32, f: f32| {
            let tr = (-self.sigma_t * d).exp();
            FreeFlight {
                t,
                scattered: true,
                transmittance: tr,
                sigma_s: self.sigma_s * f,
                // density sigma_t(x') exp(-tau), averaged over the channel choice
                pdf: average(self.sigma_t * f * tr),
            }
        };
        let Some(l) = self.local(ray, t_max) else {
            return passage(0.0, t_max);
        };
        if self.line_integral.is_marching() {
            // the marched estimates of D and sigma_t stand in for the exact ones
            let target = if k > 0.0 {
                -(1.0 - sampler.next_f32()).ln() / k
            } else {
                f32::INFINITY
            };
            match self.march(&l, target, sampler) {
                (Walk::Collision { t, f }, d) => collision(d, t, f),
                (Walk::Passage, d) => passage(d, t_max),
            }
        } else {
            // tracking: the exact D, so that pdf and transmittance are those of the outcome
            match self.delta_tracking(&l, k, sampler) {
                Walk::Collision { t, f } => collision(self.integrate(&l, l.t0, t), t, f),
                Walk::Passage => passage(self.integrate(&l, l.t0, l.t1), t_max),
            }
        }
    }
    // ANCHOR_END: heterogeneous_sample

    /// True when sigma_t is the same in every channel (the density scales all alike).
    pub fn grey(&self) -> bool {
        self.sigma_t.x == self.sigma_t.y && self.sigma_t.y == self.sigma_t.z
    }

    // ANCHOR: heterogeneous_sample_weight
    /// [`Heterogeneous::sample_free_flight`] for an estimator that needs only the weight. For a
    /// grey tracked medium the weight does not depend on the optical depth tau: a collision's
    /// is tr sigma_s f / average(sigma_t f tr) = sigma_s f / (sigma_t f), a passage's
    /// tr / average(tr) = 1, so the exact depth (most of a tracked flight's cost) is skipped and
    /// the flight carries transmittance and pdf divided by exp(-tau). Same random numbers, same
    /// outcome; every other medium gives the full flight.
    pub fn sample_free_flight_weight(
        &self,
        ray: &Ray,
        t_max: f32,
        sampler: &mut Sampler,
    ) -> WeightedFlight {
        if self.line_integral.is_marching() || !self.grey() {
            return WeightedFlight::new(self.sample_free_flight(ray, t_max, sampler));
        }
        // the channel draw of `sample_free_flight`, so the random numbers stay in step
        let c = sampler.next_index(N_CHANNELS);
        let k = self.sigma_t[c];
        let passage = FreeFlight {
            t: t_max,
            scattered: false,
            transmittance: Rgb::ONE,
            sigma_s: Rgb::ZERO,
            pdf: 1.0,
        };
        let Some(l) = self.local(ray, t_max) else {
            return WeightedFlight::new(passage);
        };
        WeightedFlight::new(match self.delta_tracking(&l, k, sampler) {
            Walk::Collision { t, f } => FreeFlight {
                t,
                scattered: true,
                transmittance: Rgb::ONE,
                sigma_s: self.sigma_s * f,
                pdf: k * f,
            },
            Walk::Passage => passage,
        })
    }
    // ANCHOR_END: heterogeneous_sample_weight

    /// Transmittance over [0, t_max) along `ray`: the marched exp(-sigma_t D) for the marching
    /// strategies; for delta tracking an unbiased estimate, by ratio tracking or delta tracking
    /// ([`TransmittanceEstimator`]).
    pub fn transmittance(&self, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> Rgb {
        let Some(l) = self.local(ray, t_max) else {
            return Rgb::ONE;
        };
        if self.line_integral.is_marching() {
            let (_, d) = self.march(&l, f32::INFINITY, sampler);
            (-self.sigma_t * d).exp()
        } else {
            match self.transmittance_estimator {
                TransmittanceEstimator::RatioTracking => self.ratio_tracking(&l, sampler),
                TransmittanceEstimator::DeltaTracking => {
                    self.delta_tracking_transmittance(&l, sampler)
                }
            }
        }
    }

    /// The exact transmittance exp(-sigma_t D) over [0, t_max) (deterministic).
    pub fn transmittance_exact(&self, ray: &Ray, t_max: f32) -> Rgb {
        (-self.sigma_t * self.density_integral(ray, t_max)).exp()
    }

    /// The pdf of the outcome `(t, scattered)`: the exact sigma_t(x') exp(-tau(t)) (collision)
    /// or exp(-tau(t)) (passage), averaged over the channels; deterministic, so BDPT and MLT
    /// can recompute it.
    /// DEVIATION: for the marching strategies this is the exact pdf, not the marched one the
    /// sampler used (the stratified and random-offset marches are random and cannot be
    /// replayed); the discrepancy is of the order of the marching bias.
    pub fn free_flight_pdf(&self, ray: &Ray, t: f32, scattered: bool) -> f32 {
        let tr = (-self.sigma_t * self.density_integral(ray, t)).exp();
        if scattered {
            average(self.sigma_t * self.density_at(ray.at(t)) * tr)
        } else {
            average(tr)
        }
    }

    /// [`Heterogeneous::free_flight_pdf`] of the segment [0, t] along `ray` (collision at its
    /// end if `scattered_end`) and of the same segment walked back from its end (collision at
    /// `ray.o` if `scattered_start`), from one density integral: D is the same line integral
    /// in either direction (eq. 3). The two walks' integrals computed apart differed only by
    /// f32 rounding, and the exact integral was half of BDPT's time on the door slit.
    pub fn free_flight_pdfs(
        &self,
        ray: &Ray,
        t: f32,
        scattered_end: bool,
        scattered_start: bool,
    ) -> (f32, f32) {
        let tr = (-self.sigma_t * self.density_integral(ray, t)).exp();
        let pdf = |scattered: bool, p: Vec3| {
            if scattered {
                average(self.sigma_t * self.density_at(p) * tr)
            } else {
                average(tr)
            }
        };
        (pdf(scattered_end, ray.at(t)), pdf(scattered_start, ray.o))
    }
}
