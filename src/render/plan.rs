//! The pass plan: a fixed-spp render of T samples per pixel is P = ceil(T / [`PASS_SPP`])
//! passes, pass p drawing the streams `Sampler::new(seed, pixel, p)` and the last one short
//! when T is no multiple of [`PASS_SPP`]. The session runs the passes, a shard takes a
//! contiguous range of them, the memory estimate holds one pass's records: all of them count
//! passes here, so that a shard's passes are the single run's.
//! Book: "Measuring a renderer" (shards).

use std::ops::Range;

/// Samples per pixel in one pass of a fixed-spp render (smaller passes: finer progress).
pub const PASS_SPP: u32 = 4;

/// The passes of a render of `spp` samples per pixel.
pub fn passes(spp: u64) -> u64 {
    spp.div_ceil(PASS_SPP as u64)
}

/// The samples per pixel of the next pass of a render of `spp` that has done `done`, or `None`
/// when it is complete.
pub fn next_pass_spp(done: u64, spp: u32) -> Option<u32> {
    (done < spp as u64).then(|| PASS_SPP.min(spp - done as u32))
}

/// The samples per pixel that the passes `range` of a render of `spp` hold.
pub fn spp_of(range: Range<u64>, spp: u32) -> u32 {
    let end = (range.end * PASS_SPP as u64).min(spp as u64);
    (end - range.start * PASS_SPP as u64) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_cover_the_samples_once() {
        for spp in 1..40u32 {
            let p = passes(spp as u64);
            assert_eq!(spp_of(0..p, spp), spp);
            let (mut done, mut n) = (0u64, 0u64);
            while let Some(s) = next_pass_spp(done, spp) {
                assert_eq!(s, spp_of(n..n + 1, spp));
                done += s as u64;
                n += 1;
            }
            assert_eq!((done, n), (spp as u64, p));
        }
    }
}
