//! Small numerical building blocks: orthonormal frames, warps from the unit square, sampling by
//! solid angle, discrete distributions and the random number streams.
//! Book: "Conventions of the code" (frames, measures) and "Sampling toolbox".

pub mod distribution;
pub mod frame;
pub mod mixing;
pub mod primary_sample;
pub mod sampler;
pub mod spherical;
pub mod warp;

pub use distribution::{Bilinear2D, Distribution1D, Distribution2D};
pub use frame::Frame;
pub use primary_sample::PrimarySamples;
pub use sampler::Sampler;
