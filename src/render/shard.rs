//! Shards: the I-th of N disjoint parts of one render, for N processes or machines whose images
//! `merge` puts back together.
//!
//! - **Pass-based integrators** (`path`, `light`, `bdpt`, guided or with the adjoint image): a
//!   render of T spp is P = ceil(T / PASS_SPP) passes, pass p drawing the streams
//!   `Sampler::new(seed, pixel, p)`. Shard I of N renders the contiguous passes
//!   `(I-1)P/N .. IP/N` of the same seed, so the N shards draw exactly the single run's samples,
//!   each once. Contiguous rather than strided, because a shard's provenance is then one range
//!   `SEED:FIRST..END`, the merged streams are the single run's `SEED:0..P`, and a shard's
//!   checkpoint is its next pass index like any render's. The preprocessing (guide, adjoint
//!   image) depends on the seed only, so every shard builds the same one: a fixed cost per shard,
//!   no change to the estimator. The merge equals the single run to float rounding, not bit
//!   for bit: each shard's EXR holds its mean rounded to f32, and the merge adds the shards' sums
//!   in another order than the single run's film (see the book, "Measuring a renderer").
//! - **MLT**: shard I of N is an independent MLT run with a seed of its own
//!   ([`Shard::mlt_seed`]), C/N of the C chains and M/N of the M mutations per pixel, so each
//!   chain is as long as in the single run; each shard has its own bootstrap (its own b and
//!   seed paths). The merge is the sample-weighted average of N independent runs: the same
//!   estimator as one run only in expectation.
//! - **SMC** is refused: its radiance cache at pass k is learnt from passes 0..k, so a shard of
//!   later passes would need every earlier one.
//! - **A filter other than the box** is refused for pass-based integrators: a pixel is the ratio
//!   sum(w f) / sum(w) of its samples, and the merge of the shards' ratios by samples would be
//!   the single run's only in expectation.
//! - **`--time`** is refused: a timed render's pass count is known only at its end.
//!
//! Book: "Measuring a renderer" (shards).

use std::fmt;
use std::ops::Range;

use super::plan::{self, PASS_SPP};
use crate::integrator::{IntegratorKind, ShardSplit};

/// Shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

/// Why a render cannot be sharded as asked.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShardError {
    #[error("--shard {0:?} is not I/N (e.g. --shard 2/4: the second of four shards)")]
    Format(String),
    #[error("--shard {0}/{1}: shards are numbered from 1 to {1}")]
    Zero(u32, u32),
    #[error("--shard {0}/{1}: there are only {1} shards (numbered from 1)")]
    Beyond(u32, u32),
    #[error(
        "--shard cannot split a --time render: its pass count is known only when the time is \
         up; give --spp, or render independent timed runs with other --seed values and merge them"
    )]
    Timed,
    #[error(
        "--shard cannot split an {0} render: its radiance cache at a pass is learnt from every \
         earlier pass, so a shard of later passes would need the earlier ones; render \
         independent runs with other --seed values and merge them"
    )]
    Learning(&'static str),
    #[error(
        "--shard cannot split a render through a tent or gaussian filter: each pixel is the \
         ratio sum(w f) / sum(w) of the samples around it, which the merge of the shards' \
         images would not reproduce; render unsharded, or with filter = {{ type = \"box\" }}"
    )]
    Filtered,
    #[error(
        "--shard {index}/{count}: {spp} spp are only {passes} passes of {PASS_SPP} spp, fewer \
         than the {count} shards (ask for at most {passes} shards or more spp)"
    )]
    TooFewPasses {
        index: u32,
        count: u32,
        spp: u32,
        passes: u64,
    },
    #[error(
        "--shard {index}/{count} of an mlt render splits its chains and mutations evenly: \
         {what} ({value}) must be a multiple of {count}"
    )]
    Uneven {
        index: u32,
        count: u32,
        what: &'static str,
        value: u64,
    },
}

impl Shard {
    /// Reads `I/N` with 1 <= I <= N.
    pub fn parse(text: &str) -> Result<Shard, ShardError> {
        let bad = || ShardError::Format(text.to_string());
        let (i, n) = text.trim().split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        match (index, count) {
            (_, 0) => Err(bad()),
            (0, n) => Err(ShardError::Zero(0, n)),
            (i, n) if i > n => Err(ShardError::Beyond(i, n)),
            (index, count) => Ok(Shard { index, count }),
        }
    }

    /// This shard's passes of a pass-based render of `spp` samples per pixel.
    pub fn passes(self, spp: u32) -> Range<u64> {
        let p = plan::passes(spp as u64);
        let (i, n) = (self.index as u64, self.count as u64);
        (i - 1) * p / n..i * p / n
    }

    /// The samples per pixel of this shard's passes (the last pass of the render may be short).
    pub fn spp(self, spp: u32) -> u32 {
        plan::spp_of(self.passes(spp), spp)
    }

    /// The seed of this shard of an MLT render seeded `seed`: a mix of the seed and the shard
    /// (SplitMix64's finalizer), so that shards draw independent bootstraps and chains.
    pub fn mlt_seed(self, seed: u64) -> u64 {
        let salt =
            ((self.count as u64) << 32 | self.index as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93);
        let mut z = (seed ^ 0x5348_4152_4400_0000).wrapping_add(salt);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// What this shard holds of a render of `spp` seeded `seed` (words for a merge's message).
    pub fn describe(self, spp: u32, seed: u64, mlt: bool) -> String {
        if mlt {
            format!(
                "{self} (an independent run with seed {})",
                self.mlt_seed(seed)
            )
        } else {
            let r = self.passes(spp);
            format!("{self} (passes {}..{})", r.start, r.end)
        }
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What a shard renders: its first pass, samples per pixel, seed and (MLT) chain count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShardPlan {
    pub first_pass: u64,
    pub spp: u32,
    pub seed: u64,
    /// MLT's chains in this shard; `None` for pass-based integrators.
    pub chains: Option<u32>,
}

/// The part `shard` of a render with integrator `kind`, `spp` samples (mutations) per pixel,
/// seed `seed` and `chains` chains (the flag that sets them, and their count) when it has
/// chains; or why it cannot be sharded.
pub fn plan(
    shard: Shard,
    kind: IntegratorKind,
    spp: u32,
    seed: u64,
    chains: Option<(&'static str, u32)>,
) -> Result<ShardPlan, ShardError> {
    let (index, count) = (shard.index, shard.count);
    match kind.facts().shard_split() {
        ShardSplit::Refused(name) => Err(ShardError::Learning(name)),
        ShardSplit::IndependentChains => {
            let uneven = |what, value: u64| ShardError::Uneven {
                index,
                count,
                what,
                value,
            };
            let (flag, chains) = chains.unwrap_or(("--mlt-chains", count));
            if !chains.is_multiple_of(count) {
                return Err(uneven(flag, chains as u64));
            }
            if !spp.is_multiple_of(count) {
                return Err(uneven("--spp (mutations per pixel)", spp as u64));
            }
            Ok(ShardPlan {
                first_pass: 0,
                spp: spp / count,
                seed: shard.mlt_seed(seed),
                chains: Some(chains / count),
            })
        }
        ShardSplit::Passes => {
            let passes = plan::passes(spp as u64);
            if passes < count as u64 {
                return Err(ShardError::TooFewPasses {
                    index,
                    count,
                    spp,
                    passes,
                });
            }
            Ok(ShardPlan {
                first_pass: shard.passes(spp).start,
                spp: shard.spp(spp),
                seed,
                chains: None,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_the_passes_once_and_their_spp_add_up() {
        for spp in [1, 4, 7, 64, 65, 4096] {
            let passes = plan::passes(spp as u64);
            for count in (1..=7).filter(|&n| n as u64 <= passes) {
                let mut next = 0;
                let mut sum = 0;
                for index in 1..=count {
                    let s = Shard { index, count };
                    assert_eq!(s.passes(spp).start, next, "{s} of {spp} spp");
                    next = s.passes(spp).end;
                    sum += s.spp(spp);
                }
                assert_eq!((next, sum), (passes, spp), "{count} shards of {spp} spp");
            }
        }
    }

    #[test]
    fn bad_shards_are_refused() {
        assert_eq!(Shard::parse("0/4"), Err(ShardError::Zero(0, 4)));
        assert_eq!(Shard::parse("5/4"), Err(ShardError::Beyond(5, 4)));
        for bad in ["a/b", "3", "1/0", "-1/4", "1/4/2", ""] {
            assert_eq!(
                Shard::parse(bad),
                Err(ShardError::Format(bad.into())),
                "{bad}"
            );
        }
        assert_eq!(Shard::parse(" 2/4 "), Ok(Shard { index: 2, count: 4 }));
    }
}
