//! Enlightened local path sampling (Kristensen 2010, ch. 5), extended to participating media.
//!
//! Local sampling decisions (where a light path starts, which direction a vertex scatters in)
//! are made closer to proportional to the path contribution f by giving them the global
//! context they lack: the incident radiance L_i (represented by photons) and the incident
//! importance W_i (represented by importons).
//!
//! - [`particles`]: weighted rays (r_i, alpha_i) with E[sum alpha_i W_e(r_i)] = <W_e, L_i>
//!   (Kristensen 2010, eq. (5.8)-(5.12)): the classical photon / importon tracer and the
//!   bidirectional particle sampler.
//! - [`metropolis`]: the Metropolis particle sampler (eq. (5.15)): the bidirectional sampler
//!   as a Markov chain in primary sample space, so particles crowd where light reaches the
//!   sensor.
//! - [`adjoint`]: the adjoint image (Kristensen 2010, sec. 5.2.1 and 5.3.1, eq. (5.3), (5.6),
//!   (5.7)): an invertible light-sampling map F from the unit square onto the area lights, a
//!   low-resolution grid of the adjoint measurement I* over it, and light start points sampled
//!   from that grid with their exact area density, used by BDPT's MIS and MLT's transition
//!   densities.
//! - [`regions`], [`direction_map`], [`guide`]: regions by k-means with eq. (5.16), per-region
//!   equal-area maps of L_i and W_i (sec. 5.2.3, 5.2.4), and the guided mixtures of eqs.
//!   (5.17)-(5.19) extended to medium vertices (sec. 5.3).
//!
//! Book: "Enlightened local path sampling: the adjoint image and particles" and
//! "Enlightened local path sampling: guiding".

pub mod adjoint;
pub mod direction_map;
pub mod guide;
pub mod metropolis;
pub mod particles;
pub mod regions;
pub mod technique;

pub use adjoint::{AdjointError, AdjointImage, AdjointSettings, LightMap};
pub use direction_map::DirectionMap;
pub use guide::{Deposit, Guide, GuideError, GuideKind, GuideSettings, GuideStats};
pub use particles::{Particle, Quantity};
pub use regions::{RegionParams, RegionPoint, Regions};
pub use technique::Enlightened;
