//! The homogeneous medium: Table 1, left column (Pauly, Kollig, Keller 2000).
//!
//! tau(x, x') = exp(-sigma_t d); a collision distance is drawn by inverting the CDF,
//! d = -ln(1 - xi) / sigma_t, with density sigma_t exp(-sigma_t d). A distance beyond the next
//! surface becomes the surface point itself, with the discrete probability exp(-sigma_t d_surf).
//!
//! Chromatic media: the distance is drawn with the sigma_t of one channel picked uniformly, and
//! the pdf is the average of the three channels' pdfs (one-sample MIS over channels), so no
//! channel's contribution is lost or biased.
//!
//! Book: "Table 1: homogeneous media" (`book/src/table1-homogeneous.md`); executable spec:
//! `tests/spec/medium/homogeneous.rs`.

use crate::spectrum::{average, Rgb};

use super::{FreeFlight, MediumError, Phase};

/// The number of colour channels a distance can be sampled for (`Rgb` has three).
const N_CHANNELS: usize = 3;

/// Constant coefficients throughout the medium.
#[derive(Clone, Debug, PartialEq)]
pub struct Homogeneous {
    pub sigma_a: Rgb,
    pub sigma_s: Rgb,
    pub sigma_t: Rgb,
    pub phase: Phase,
    /// The volume emittance L_e,V0 of eq. (1): radiance added per unit length, isotropic
    /// (zero for a medium that does not glow; set by [`super::Medium::with_emission`]).
    pub emission: Rgb,
}

impl Homogeneous {
    /// Validated constructor: coefficients must be finite and non-negative.
    pub fn new(sigma_a: Rgb, sigma_s: Rgb, phase: Phase) -> Result<Self, MediumError> {
        for (name, v) in [("sigma_a", sigma_a), ("sigma_s", sigma_s)] {
            for c in v.to_array() {
                if !c.is_finite() || c < 0.0 {
                    return Err(MediumError::NegativeCoefficient { name, value: c });
                }
            }
        }
        Ok(Homogeneous {
            sigma_a,
            sigma_s,
            sigma_t: sigma_a + sigma_s,
            phase,
            emission: Rgb::ZERO,
        })
    }

    /// Single-scattering albedo sigma_s / sigma_t per channel (0 where sigma_t = 0).
    pub fn albedo(&self) -> Rgb {
        Rgb::select(
            self.sigma_t.cmpgt(Rgb::ZERO),
            self.sigma_s / self.sigma_t,
            Rgb::ZERO,
        )
    }

    /// exp(-sigma_t d).
    // ANCHOR: homogeneous_transmittance
    #[inline]
    pub fn transmittance(&self, d: f32) -> Rgb {
        // ASSIGNMENT: transmittance
        if d.is_infinite() {
            // a ray to infinity is extinguished in every channel with sigma_t > 0
            return Rgb::select(self.sigma_t.cmpgt(Rgb::ZERO), Rgb::ZERO, Rgb::ONE);
        }
        let s = self.sigma_t;
        if s.x == s.y && s.y == s.z {
            // a grey medium: one exponential (the same value) serves the three channels
            return Rgb::splat((-s.x * d).exp());
        }
        (-self.sigma_t * d).exp()
        // END ASSIGNMENT
    }
    // ANCHOR_END: homogeneous_transmittance

    /// Table 1, left column, with the channel picked by `u_channel`.
    // ANCHOR: homogeneous_sample
    #[inline]
    pub fn sample_free_flight(&self, t_max: f32, u_channel: f32, u: f32) -> FreeFlight {
        // ASSIGNMENT: free_flight
        // one-sample MIS over channels: pick c uniformly, sample with sigma_t[c]
        let c = ((u_channel * N_CHANNELS as f32) as usize).min(N_CHANNELS - 1);
        let sigma = self.sigma_t[c];
        // [PKK00 Table 1] d = -ln(1 - xi) / sigma_t, inverting the CDF 1 - exp(-sigma_t d)
        let t = if sigma > 0.0 {
            -(1.0 - u).ln() / sigma
        } else {
            f32::INFINITY
        };
        if t < t_max {
            let tr = self.transmittance(t);
            FreeFlight {
                t,
                scattered: true,
                transmittance: tr,
                sigma_s: self.sigma_s,
                // density sigma_t exp(-sigma_t t), averaged over the channel choice
                pdf: average(self.sigma_t * tr),
            }
        } else {
            let tr = self.transmittance(t_max);
            FreeFlight {
                t: t_max,
                scattered: false,
                transmittance: tr,
                sigma_s: Rgb::ZERO,
                // probability exp(-sigma_t t_max) of passing, averaged over the channel choice
                pdf: average(tr),
            }
        }
        // END ASSIGNMENT
    }
    // ANCHOR_END: homogeneous_sample

    /// The pdf of the outcome `(t, scattered)` under [`Self::sample_free_flight`]: the density
    /// of a collision at `t`, or the probability of passing to `t = t_max`, each averaged over
    /// the uniformly chosen channel.
    // ANCHOR: homogeneous_pdf
    pub fn free_flight_pdf(&self, t: f32, scattered: bool) -> f32 {
        // ASSIGNMENT: free_flight
        let tr = self.transmittance(t);
        if scattered {
            average(self.sigma_t * tr)
        } else {
            average(tr)
        }
        // END ASSIGNMENT
    }
    // ANCHOR_END: homogeneous_pdf
}
