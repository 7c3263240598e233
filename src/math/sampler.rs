//! Random number streams. Every stream is derived from the render seed and an index (pixel,
//! pass, chain), never from thread identity, so images are identical whatever the thread count.

use glam::Vec2;
use rand::RngCore;
use rand_pcg::Pcg32;

use super::distribution::ONE_MINUS_EPSILON;
use super::primary_sample::PrimarySamples;

/// A uniform random number source on [0, 1): a PCG stream, or the coordinates of a
/// primary-sample-space Markov chain ([`PrimarySamples`]), which turns any sampler of this crate
/// into a Metropolis sampler without changing it.
pub struct Sampler {
    source: Source,
}

enum Source {
    Stream(Pcg32),
    Primary(Box<PrimarySamples>),
}

/// SplitMix64 finalizer: decorrelates consecutive indices before they seed PCG.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Point `k` of the two-dimensional (0, 2)-sequence in base 2, digitally shifted by `shift`:
/// the first coordinate is k's bits reversed (van der Corput's radical inverse), the second k
/// times the Pascal matrix mod 2 (together the first two dimensions of Sobol's sequence;
/// Kollig and Keller 2002, "Efficient multidimensional sampling", sec. 3), each then XORed
/// with 32 bits of `shift`. Every run of 2^m points starting at a multiple of 2^m has exactly
/// one point in each of the 2^m elementary intervals of area 2^-m (any shape 2^-i x
/// 2^-(m-i)): the shift permutes the intervals and keeps that. Over a uniformly random
/// `shift` each point is uniform on the grid of 2^-24, as [`Sampler::next_f32`]'s numbers
/// are, so an estimate from these points is unbiased whatever the integrand.
pub fn stratified_point(k: u32, shift: u64) -> Vec2 {
    let (mut x, mut y) = (0u32, 0u32);
    let (mut vx, mut vy) = (1u32 << 31, 1u32 << 31);
    let mut i = k;
    while i != 0 {
        if i & 1 != 0 {
            x ^= vx;
            y ^= vy;
        }
        i >>= 1;
        vx >>= 1;
        // the next column of the Pascal matrix mod 2
        vy ^= vy >> 1;
    }
    let unit = |bits: u32| (bits >> 8) as f32 * (1.0 / 16_777_216.0);
    Vec2::new(unit(x ^ shift as u32), unit(y ^ (shift >> 32) as u32))
}

/// Set into the pixel's index for the digital shift of its film points, so that the shift is
/// none of the pixel's PCG streams' seeds.
const FILM_SHIFT_STREAM: u64 = 0x6669_6c6d_7368_6966;

/// The digital shift of pixel `pixel`'s film points under seed `seed` ([`stratified_point`]):
/// its own for each pixel and seed, the same in every pass, so that the points of all the
/// pixel's passes are one sequence.
pub fn film_shift(seed: u64, pixel: u64) -> u64 {
    mix64(seed ^ mix64(pixel ^ FILM_SHIFT_STREAM))
}

impl Sampler {
    /// The stream for (`seed`, `index`, `pass`): pixel `index` in pass `pass`, or chain `index`.
    pub fn new(seed: u64, index: u64, pass: u64) -> Self {
        let state = mix64(seed ^ mix64(index ^ mix64(pass.wrapping_add(0x5851_F42D))));
        let stream = mix64(index.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ pass);
        Sampler {
            source: Source::Stream(Pcg32::new(state, stream)),
        }
    }

    /// A sampler that reads the coordinates of a primary-sample-space chain.
    pub fn primary(chain: PrimarySamples) -> Self {
        Sampler {
            source: Source::Primary(Box::new(chain)),
        }
    }

    /// The chain of a [`Sampler::primary`] sampler.
    pub fn chain(&mut self) -> Option<&mut PrimarySamples> {
        match &mut self.source {
            Source::Primary(p) => Some(p),
            Source::Stream(_) => None,
        }
    }

    /// Reads primary-sample stream `s` from now on (see [`PrimarySamples`]); no effect on a
    /// PCG stream.
    #[inline]
    pub fn set_stream(&mut self, s: usize) {
        if let Source::Primary(p) = &mut self.source {
            p.set_stream(s);
        }
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        match &mut self.source {
            // 24 random bits: every value is exactly representable and < 1
            Source::Stream(rng) => {
                ((rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)).min(ONE_MINUS_EPSILON)
            }
            Source::Primary(p) => (p.next_number() as f32).min(ONE_MINUS_EPSILON),
        }
    }

    /// Uniform in [0, 1) with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        match &mut self.source {
            Source::Stream(rng) => (rng.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0),
            Source::Primary(p) => p.next_number(),
        }
    }

    /// Two uniform numbers.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }

    /// Uniform integer in [0, n).
    #[inline]
    pub fn next_index(&mut self, n: usize) -> usize {
        ((self.next_f64() * n as f64) as usize).min(n.saturating_sub(1))
    }
}
