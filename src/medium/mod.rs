//! Participating media: the coefficients sigma_a, sigma_s, sigma_t = sigma_a + sigma_s of the
//! global balance equation (Pauly, Kollig, Keller 2000, eq. 1), transmittance (eq. 3) and the
//! propagation sampling of Table 1 (left column: `homogeneous`; right column, ray marching and
//! tracking through grids and procedural fields: `heterogeneous`, `grid`, `procedural`).
//! Book: "Participating media and Table 1", "Table 1: inhomogeneous media".

pub mod equiangular;
pub mod grid;
pub mod heterogeneous;
pub mod homogeneous;
pub mod phase;
pub mod procedural;
pub mod vdb;

pub use equiangular::Equiangular;
pub use grid::Grid;
pub use heterogeneous::{Density, Heterogeneous, LineIntegral, TransmittanceEstimator};
pub use homogeneous::Homogeneous;
pub use phase::{Phase, PhaseError, PhaseSample};
pub use procedural::{Axis, Fbm, Field};

use glam::Vec3;

use crate::geometry::Ray;
use crate::math::Sampler;
use crate::spectrum::Rgb;

/// Why a medium was rejected.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MediumError {
    #[error("{name} = {value} is negative or not finite (coefficients are per unit length, >= 0)")]
    NegativeCoefficient { name: &'static str, value: f32 },
    #[error(transparent)]
    Phase(#[from] PhaseError),
    /// A march would take more steps across the medium's box than the stated limit.
    #[error("step = {step} makes a ray march take up to {steps:.3e} steps across the medium's box (its diagonal / (step x its largest side)), more than the limit {limit:e}: raise step")]
    MarchSteps { step: f32, steps: f32, limit: f32 },
    /// Tracking would expect more tentative collisions across the box than the stated limit.
    #[error("the majorant's optical depth across the medium's box is {depth:.3e} (max sigma_t {sigma:e} x max density {density:e} x diagonal {diagonal:e}), more than the limit {limit:e} tentative collisions a delta or ratio tracking walk may expect per segment: lower sigma_a / sigma_s or the density")]
    TrackingDepth {
        depth: f32,
        sigma: f32,
        density: f32,
        diagonal: f32,
        limit: f32,
    },
    /// Emission in a medium without extinction: the free-flight estimator collects L_e,V0 at
    /// collisions, and a medium with sigma_t = 0 in every channel has none.
    #[error("emission = {emission} in a medium with sigma_a + sigma_s = 0 in every channel: the path tracer collects emission at free-flight collisions, and this medium has none (give it some absorption)")]
    EmissionWithoutExtinction { emission: Rgb },
}

/// The outcome of sampling a free-flight distance inside one medium segment [0, t_max)
/// (Table 1): a collision at `t < t_max`, or passage to the segment's end.
///
/// Carries the transmittance and the probability (density or mass) of the outcome, never only
/// their ratio, because BDPT and MLT need the pdfs themselves.
#[derive(Clone, Copy, Debug)]
pub struct FreeFlight {
    /// Distance of the collision, or `t_max` on passage.
    pub t: f32,
    /// True for a collision (a medium vertex), false for passage to the segment's end.
    pub scattered: bool,
    /// Transmittance exp(-tau) over [0, t] per channel.
    pub transmittance: Rgb,
    /// sigma_s at the collision point (zero on passage).
    pub sigma_s: Rgb,
    /// Density (per unit length) of the collision distance, or the probability of passage.
    pub pdf: f32,
}

impl FreeFlight {
    /// The factor a path's throughput is multiplied by: transmittance times sigma_s for a
    /// collision (the f-hat of the medium vertex), over the pdf.
    #[inline]
    pub fn weight(&self) -> Rgb {
        if self.pdf <= 0.0 {
            return Rgb::ZERO;
        }
        if self.scattered {
            self.transmittance * self.sigma_s / self.pdf
        } else {
            self.transmittance / self.pdf
        }
    }
}

/// A free flight sampled for an estimator that needs only its throughput factor
/// [`FreeFlight::weight`] (the path tracer's walk), from [`Medium::sample_free_flight_weight`].
///
/// In a grey tracked inhomogeneous medium the weight does not depend on the optical depth
/// (`Heterogeneous::sample_free_flight_weight`), so the depth is not computed and the flight's
/// transmittance and pdf are known only up to a common factor: they are not exposed, only the
/// weight and the outcome.
#[derive(Clone, Copy, Debug)]
pub struct WeightedFlight(FreeFlight);

impl WeightedFlight {
    /// A flight whose transmittance and pdf are exact, or share one positive factor.
    pub(crate) fn new(scaled: FreeFlight) -> Self {
        WeightedFlight(scaled)
    }

    /// Distance of the collision, or `t_max` on passage.
    #[inline]
    pub fn t(&self) -> f32 {
        self.0.t
    }

    /// True for a collision, false for passage.
    #[inline]
    pub fn scattered(&self) -> bool {
        self.0.scattered
    }

    /// sigma_s at the collision point (zero on passage).
    #[inline]
    pub fn sigma_s(&self) -> Rgb {
        self.0.sigma_s
    }

    /// [`FreeFlight::weight`] of the flight (to rounding where the depth was skipped).
    #[inline]
    pub fn weight(&self) -> Rgb {
        self.0.weight()
    }

    /// The flight with its transmittance and pdf divided by a common factor: only their ratio
    /// means anything. For products over a walk's segments (`Scene::propagate_weight_from`),
    /// kept as the two products a `Propagation` keeps.
    #[inline]
    pub(crate) fn scaled(&self) -> FreeFlight {
        self.0
    }
}

/// The closed set of media.
#[derive(Clone, Debug, PartialEq)]
pub enum Medium {
    Homogeneous(Homogeneous),
    /// Boxed: the density grid and the majorant make it much larger than the homogeneous case.
    Heterogeneous(Box<Heterogeneous>),
}

impl Medium {
    pub fn phase(&self) -> &Phase {
        match self {
            Medium::Homogeneous(h) => &h.phase,
            Medium::Heterogeneous(h) => &h.phase,
        }
    }

    pub fn sigma_s(&self, p: Vec3) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.sigma_s,
            Medium::Heterogeneous(h) => h.sigma_s * h.density_at(p),
        }
    }

    /// The volume emittance L_e,V0(p) of eq. (1): radiance added per unit length at `p`,
    /// isotropic, scaled by the density like sigma_a and sigma_s. pbrt-v4's `Le` is multiplied
    /// by sigma_a instead: L_e,V0 = sigma_a Le.
    #[inline]
    pub fn emission(&self, p: Vec3) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.emission,
            Medium::Heterogeneous(h) => h.emission * h.density_at(p),
        }
    }

    /// The emission coefficient: L_e,V0 of a homogeneous medium, L_e,V0 per unit density of
    /// an inhomogeneous one.
    pub fn emission_coefficient(&self) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.emission,
            Medium::Heterogeneous(h) => h.emission,
        }
    }

    /// True when the medium glows (some channel of L_e,V0 is positive somewhere).
    #[inline]
    pub fn emits(&self) -> bool {
        self.emission_coefficient().max_element() > 0.0
    }

    /// This medium with volume emittance `emission` (per unit density for an inhomogeneous
    /// medium); refused when it is negative, not finite, or the medium has no extinction.
    pub fn with_emission(mut self, emission: Rgb) -> Result<Self, MediumError> {
        for c in emission.to_array() {
            if !c.is_finite() || c < 0.0 {
                let name = "emission";
                return Err(MediumError::NegativeCoefficient { name, value: c });
            }
        }
        let sigma_t = match &self {
            Medium::Homogeneous(h) => h.sigma_t,
            Medium::Heterogeneous(h) => h.sigma_t,
        };
        if emission.max_element() > 0.0 && sigma_t.max_element() <= 0.0 {
            return Err(MediumError::EmissionWithoutExtinction { emission });
        }
        match &mut self {
            Medium::Homogeneous(h) => h.emission = emission,
            Medium::Heterogeneous(h) => h.emission = emission,
        }
        Ok(self)
    }

    pub fn sigma_t(&self, p: Vec3) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.sigma_t,
            Medium::Heterogeneous(h) => h.sigma_t * h.density_at(p),
        }
    }

    /// The optical depth tau = integral of sigma_t over [0, t] along `ray` (eq. 3), per
    /// channel, deterministic: closed forms and the exact per-cell quadrature of grids (the fixed
    /// lattice quadrature of fBm fields, see [`Density::integrate`]).
    #[inline]
    pub fn optical_depth(&self, ray: &Ray, t: f32) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.sigma_t * t,
            Medium::Heterogeneous(h) => h.sigma_t * h.density_integral(ray, t),
        }
    }

    /// The distance along `ray` at which the optical depth, averaged over the channels,
    /// reaches `tau` (the inverse of [`Medium::optical_depth`]), if it does before `t_max`.
    pub fn advance(&self, ray: &Ray, tau: f32, t_max: f32) -> Option<f32> {
        let t = match self {
            Medium::Homogeneous(h) => {
                let k = crate::spectrum::average(h.sigma_t);
                (k > 0.0).then(|| tau / k)
            }
            Medium::Heterogeneous(h) => {
                let k = crate::spectrum::average(h.sigma_t);
                if k > 0.0 {
                    h.invert_density_integral(ray, tau / k, t_max)
                } else {
                    None
                }
            }
        };
        t.filter(|&t| t < t_max)
    }

    /// An upper bound of sigma_t over the whole medium (its majorant), per channel.
    pub fn sigma_t_max(&self) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.sigma_t,
            Medium::Heterogeneous(h) => h.sigma_t * h.max_density(),
        }
    }

    /// True when the optical depth along a segment is a closed form of its length (a
    /// homogeneous medium): its transmittance draws no random numbers and the free-flight
    /// density at any point needs no walk. A shadow ray may then stop at its first occluder
    /// (`Scene::closed_form_tau`), a path's throughput can be recomputed (`path::verify`), and
    /// equiangular sampling can weigh its distances against free flight.
    pub fn closed_form(&self) -> bool {
        match self {
            Medium::Homogeneous(_) => true,
            Medium::Heterogeneous(_) => false,
        }
    }

    /// The box outside which the medium is empty (an inhomogeneous medium's), `None` for a
    /// medium that fills the shapes enclosing it.
    pub fn bounds(&self) -> Option<crate::geometry::Aabb> {
        match self {
            Medium::Homogeneous(_) => None,
            Medium::Heterogeneous(h) => Some(h.bounds),
        }
    }

    /// The bytes of its own data (an inhomogeneous medium's density grid), for the memory
    /// estimate.
    pub fn memory_bytes(&self) -> u64 {
        match self {
            Medium::Homogeneous(_) => 0,
            Medium::Heterogeneous(h) => match &h.density {
                Density::Grid(g) => g.values.len() as u64 * 4,
                Density::Field(_) => 0,
            },
        }
    }

    /// True when equiangular sampling may place a scattering vertex in it (the path tracer's
    /// `distance = "equiangular-mis"`): a medium that scatters in some channel, homogeneous or
    /// tracked. Delta tracking draws collisions with exactly the density sigma_t(x) exp(-tau)
    /// of Table 1, which [`Medium::free_flight_pdf`] evaluates from the deterministic optical
    /// depth, so the MIS weights against it are those densities (for fBm fields, the fixed
    /// quadrature's: still a partition of unity, see `path::distance`); a marched medium is
    /// left out (its collisions do not follow that density, see [`Medium::marched`]).
    pub fn scatters_equiangular(&self) -> bool {
        match self {
            Medium::Homogeneous(h) => h.sigma_s.max_element() > 0.0,
            Medium::Heterogeneous(h) => {
                !h.line_integral.is_marching() && h.sigma_s.max_element() > 0.0
            }
        }
    }

    /// True for an inhomogeneous medium sampled by ray marching (biased for any step): its
    /// collisions do not follow [`Medium::free_flight_pdf`], which is the exact density.
    pub fn marched(&self) -> bool {
        match self {
            Medium::Homogeneous(_) => false,
            Medium::Heterogeneous(h) => h.line_integral.is_marching(),
        }
    }

    /// True when [`Medium::optical_depth`] is the exact integral of sigma_t (closed forms and
    /// grids' per-cell rule), false for the fixed quadrature of fBm fields: only then is
    /// [`Medium::transmittance_exact`] the transmittance itself rather than an approximation.
    pub fn exact_optical_depth(&self) -> bool {
        match self {
            Medium::Homogeneous(_) => true,
            Medium::Heterogeneous(h) => match &h.density {
                Density::Grid(_) => true,
                Density::Field(f) => f.has_closed_form_integral(),
            },
        }
    }

    /// What `pathspace info` says of it (its coefficients, line integral and phase function).
    pub fn describe(&self) -> String {
        use crate::spectrum::{round3, show};
        match self {
            Medium::Homogeneous(h) => format!(
                "homogeneous, sigma_a {}, sigma_s {}, sigma_t {}, albedo {}, mean free path {}, phase {}",
                show(h.sigma_a),
                show(h.sigma_s),
                show(h.sigma_t),
                show(h.albedo()),
                show(h.sigma_t.recip()),
                h.phase.describe()
            ),
            Medium::Heterogeneous(h) => format!(
                "heterogeneous, sigma_a {} and sigma_s {} per unit density, {}, Delta {}, phase {}",
                show(h.sigma_a),
                show(h.sigma_s),
                h.line_integral.name(),
                round3(h.delta),
                h.phase.describe()
            ),
        }
    }

    /// Sets how an inhomogeneous medium integrates sigma_t along a ray; false for a medium
    /// without a line integral to choose (homogeneous: the closed form).
    pub fn set_line_integral(&mut self, li: LineIntegral) -> bool {
        match self {
            Medium::Homogeneous(_) => false,
            Medium::Heterogeneous(h) => {
                h.line_integral = li;
                true
            }
        }
    }

    /// Sets how a tracking medium estimates transmittance; false for a medium that has no
    /// estimator to choose (homogeneous: the closed form).
    pub fn set_transmittance_estimator(&mut self, e: TransmittanceEstimator) -> bool {
        match self {
            Medium::Homogeneous(_) => false,
            Medium::Heterogeneous(h) => {
                h.transmittance_estimator = e;
                true
            }
        }
    }

    /// sigma_s / sigma_t per channel (0 where sigma_t is 0): the same everywhere in a medium,
    /// because an inhomogeneous medium scales both by one density.
    pub fn albedo(&self) -> Rgb {
        let (s, t) = match self {
            Medium::Homogeneous(h) => (h.sigma_s, h.sigma_t),
            Medium::Heterogeneous(h) => (h.sigma_s, h.sigma_t),
        };
        Rgb::select(t.cmpgt(Rgb::ZERO), s / t, Rgb::ZERO)
    }

    /// Samples a collision distance in [0, t_max) along `ray` (Table 1).
    #[inline]
    pub fn sample_free_flight(&self, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> FreeFlight {
        match self {
            Medium::Homogeneous(h) => {
                h.sample_free_flight(t_max, sampler.next_f32(), sampler.next_f32())
            }
            Medium::Heterogeneous(h) => h.sample_free_flight(ray, t_max, sampler),
        }
    }

    /// [`Medium::sample_free_flight`] for an estimator that needs only the flight's weight: the
    /// same outcome from the same random numbers, the weight equal to rounding; the exact
    /// optical depth is skipped in a grey tracked inhomogeneous medium.
    #[inline]
    pub fn sample_free_flight_weight(
        &self,
        ray: &Ray,
        t_max: f32,
        sampler: &mut Sampler,
    ) -> WeightedFlight {
        match self {
            Medium::Heterogeneous(h) => h.sample_free_flight_weight(ray, t_max, sampler),
            _ => WeightedFlight::new(self.sample_free_flight(ray, t_max, sampler)),
        }
    }

    /// Transmittance exp(-tau) over [0, t_max) along `ray` (eq. 3); for inhomogeneous media an
    /// estimate (ratio tracking, unbiased; or the marched value, biased).
    #[inline]
    pub fn transmittance(&self, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.transmittance(t_max),
            Medium::Heterogeneous(h) => h.transmittance(ray, t_max, sampler),
        }
    }

    /// The exact transmittance exp(-tau) over [0, t_max) along `ray` (eq. 3), deterministic in
    /// every medium: for a target that must be a function of the path alone (MLT's f, whose
    /// edges are reused across mutations and compared in the acceptance).
    #[inline]
    pub fn transmittance_exact(&self, ray: &Ray, t_max: f32) -> Rgb {
        match self {
            Medium::Homogeneous(h) => h.transmittance(t_max),
            Medium::Heterogeneous(h) => h.transmittance_exact(ray, t_max),
        }
    }

    /// The density (collision) or probability (passage) of a free flight of length `t` on
    /// [0, t_max), as `sample_free_flight` would have produced it. For path pdfs in BDPT/MLT.
    pub fn free_flight_pdf(&self, ray: &Ray, t: f32, scattered: bool) -> f32 {
        match self {
            Medium::Homogeneous(h) => h.free_flight_pdf(t, scattered),
            Medium::Heterogeneous(h) => h.free_flight_pdf(ray, t, scattered),
        }
    }

    /// The free-flight pdfs of the segment [0, t] along `ray` in both directions: forward
    /// (a collision at its end if `scattered_end`) and walked back from its end (a collision at
    /// `ray.o` if `scattered_start`), as two [`Medium::free_flight_pdf`] calls would give them
    /// (bit for bit in a homogeneous medium; from one density integral in an inhomogeneous one,
    /// `Heterogeneous::free_flight_pdfs`). For the edges of BDPT and MLT.
    #[inline]
    pub fn free_flight_pdfs(
        &self,
        ray: &Ray,
        t: f32,
        scattered_end: bool,
        scattered_start: bool,
    ) -> (f32, f32) {
        match self {
            // one exponential when both directions end alike (a pdf of the length alone)
            Medium::Homogeneous(h) if scattered_end == scattered_start => {
                let pdf = h.free_flight_pdf(t, scattered_end);
                (pdf, pdf)
            }
            Medium::Homogeneous(h) => (
                h.free_flight_pdf(t, scattered_end),
                h.free_flight_pdf(t, scattered_start),
            ),
            Medium::Heterogeneous(h) => h.free_flight_pdfs(ray, t, scattered_end, scattered_start),
        }
    }
}
