//! Executable specification of the primary-sample-space Markov chain (Kelemen et al. 2002;
//! `math::primary_sample`), the engine of the Metropolis particle sampler.
//!
//! - Detailed balance: a chain started from its target distribution is still distributed by
//!   the target after any number of steps (chi-square over many independent chains, each
//!   contributing its final state), for the small step alone, the large step alone and their
//!   mixture, with a target that lives on a varying number of coordinates.
//! - A rejected proposal restores the state to the bit.
//! - A sampler in primary-sample mode is a deterministic function of the chain: the same chain
//!   gives the same numbers.

use crate::common;

use pathspace::math::{PrimarySamples, Sampler};
use rand_pcg::Pcg32;

/// An unnormalized target over (u0, u1) and a third coordinate read only when u0 > 1/2 (a
/// "path" whose length depends on its first number): T = (1 + 3 u0^2) (0.2 + sin^2(pi u1)),
/// times 2 u2 when u2 is read.
fn target(s: &mut Sampler) -> (f64, [f64; 2]) {
    s.set_stream(0);
    let u0 = s.next_f64();
    s.set_stream(2);
    let u1 = s.next_f64();
    let mut t = (1.0 + 3.0 * u0 * u0) * (0.2 + (std::f64::consts::PI * u1).sin().powi(2));
    if u0 > 0.5 {
        s.set_stream(1);
        t *= 2.0 * s.next_f64();
    }
    (t, [u0, u1])
}

/// Bins of (u0, u1): 8 x 8.
const BINS: usize = 8;

/// The target's probability of each bin (the third coordinate integrates to 1), by midpoint
/// quadrature on a fine grid.
fn expected(n: u64) -> Vec<f64> {
    let fine = 64;
    let mut p = vec![0.0; BINS * BINS];
    let mut total = 0.0;
    for a in 0..BINS * fine {
        for b in 0..BINS * fine {
            let u0 = (a as f64 + 0.5) / (BINS * fine) as f64;
            let u1 = (b as f64 + 0.5) / (BINS * fine) as f64;
            let t = (1.0 + 3.0 * u0 * u0) * (0.2 + (std::f64::consts::PI * u1).sin().powi(2));
            p[(a / fine) * BINS + b / fine] += t;
            total += t;
        }
    }
    p.iter().map(|x| x / total * n as f64).collect()
}

/// One Metropolis step of the chain in `s` from a state of target value `t_x` (a large step
/// with probability `large_step`); returns the new state's target value.
fn step(s: &mut Sampler, t_x: f64, large_step: f64) -> f64 {
    let chain = s.chain().unwrap();
    let large = chain.uniform() < large_step;
    chain.start_iteration(large);
    let (t_y, _) = target(s);
    let chain = s.chain().unwrap();
    if chain.uniform() < (t_y / t_x).min(1.0) {
        chain.accept();
        t_y
    } else {
        chain.reject();
        t_x
    }
}

/// Runs `chains` chains of `steps` steps, each started from an exact sample of the target
/// (rejection sampling on large steps), and bins their final states.
fn final_states(chains: u64, steps: u32, large_step: f64, sigma: f64) -> Vec<u64> {
    let mut counts = vec![0u64; BINS * BINS];
    for c in 0..chains {
        let mut s = Sampler::primary(PrimarySamples::new(Pcg32::new(c, 7), sigma));
        // rejection sampling from T <= 4 * 1.2 * 2 = 9.6 with the chain's large steps
        let mut t_x = loop {
            s.chain().unwrap().start_iteration(true);
            let (t, _) = target(&mut s);
            let chain = s.chain().unwrap();
            if chain.uniform() * 9.6 < t {
                chain.accept();
                break t;
            }
            chain.reject();
        };
        for _ in 0..steps {
            t_x = step(&mut s, t_x, large_step);
        }
        let (a, b) = last_state(&mut s);
        counts[a * BINS + b] += 1;
    }
    counts
}

/// The accepted state's (u0, u1) bin, read without moving the chain (both numbers are read by
/// every state, so their stored values are the state's).
fn last_state(s: &mut Sampler) -> (usize, usize) {
    let chain = s.chain().unwrap();
    let (u0, u1) = (chain.value(0, 0).unwrap(), chain.value(2, 0).unwrap());
    (
        ((u0 * BINS as f64) as usize).min(BINS - 1),
        ((u1 * BINS as f64) as usize).min(BINS - 1),
    )
}

/// The small step by hand: n steps of deviation sigma at once are one offset sigma sqrt(n) z,
/// wrapped into [0, 1) on both sides (a clamp would pile the chain up at 0 and 1), and a tiny
/// negative result wraps to 0, never to 1.
#[test]
fn small_step_by_hand() {
    use pathspace::math::primary_sample::small_step;
    for (value, sigma, n, z, expected) in [
        (0.5, 0.1, 1.0, 1.0, 0.6),
        (0.5, 0.1, 4.0, 1.0, 0.7),
        (0.5, 0.01, 9.0, -2.0, 0.44),
        (0.95, 0.1, 1.0, 1.0, 0.05),
        (0.02, 0.1, 1.0, -1.0, 0.92),
        (0.3, 0.5, 4.0, -1.0, 0.3),
        (0.0, 1e-20, 1.0, -1.0, 0.0),
    ] {
        let got = small_step(value, sigma, n, z);
        assert!(
            (got - expected).abs() < 1e-12 && (0.0..1.0).contains(&got),
            "small_step(value {value}, sigma {sigma}, n {n}, z {z}): got {got}, expected \
             {expected}"
        );
    }
}

#[test]
fn small_steps_keep_the_target_invariant() {
    let n = 4000;
    let counts = final_states(n, 40, 0.0, 1.0 / 16.0);
    let mut fam = common::stats::Family::new("primary sample: small steps keep the target");
    fam.chi_square("small steps", &counts, &expected(n));
    fam.finish();
}

#[test]
fn large_steps_keep_the_target_invariant() {
    let n = 4000;
    let counts = final_states(n, 10, 1.0, 1.0 / 16.0);
    let mut fam = common::stats::Family::new("primary sample: large steps keep the target");
    fam.chi_square("large steps", &counts, &expected(n));
    fam.finish();
}

#[test]
fn mixed_steps_keep_the_target_invariant() {
    let n = 4000;
    let counts = final_states(n, 40, 0.3, 1.0 / 32.0);
    let mut fam = common::stats::Family::new("primary sample: mixed steps keep the target");
    fam.chi_square("mixed steps", &counts, &expected(n));
    fam.finish();
}

/// The chain must move: after 40 small steps most chains have left their starting bin (a chain
/// that never accepted would pass the invariance tests above trivially).
#[test]
fn small_steps_move_the_state() {
    let mut moved = 0;
    let chains = 200;
    for c in 0..chains {
        let mut s = Sampler::primary(PrimarySamples::new(Pcg32::new(c, 3), 1.0 / 16.0));
        s.chain().unwrap().start_iteration(true);
        let (mut t_x, _) = target(&mut s);
        s.chain().unwrap().accept();
        let start = last_state(&mut s);
        for _ in 0..40 {
            t_x = step(&mut s, t_x, 0.0);
        }
        if last_state(&mut s) != start {
            moved += 1;
        }
    }
    assert!(moved > chains / 2, "only {moved} of {chains} chains moved");
}

/// A rejected proposal restores the state: every number the state reads (u0, u1, and u2 when
/// u0 > 1/2) is back to the bit, whatever the proposal read, redrew or read for the first time.
/// (A number the state does not read may now hold the value it has in the state: a uniform
/// draw, moved by the small steps it missed; see the next test.)
#[test]
fn rejection_restores_the_state_to_the_bit() {
    let mut s = Sampler::primary(PrimarySamples::new(Pcg32::new(11, 1), 0.05));
    s.chain().unwrap().start_iteration(true);
    let _ = target(&mut s);
    s.chain().unwrap().accept();
    // storage index of number j of stream k
    let at = |k: usize, j: usize| k + pathspace::math::primary_sample::STREAMS * j;
    for step in 0..200u32 {
        let before = s.chain().unwrap().values();
        let u0 = before[at(0, 0)].expect("every state reads u0");
        let mut read = vec![at(0, 0), at(2, 0)];
        if u0 > 0.5 {
            read.push(at(1, 0));
        }
        let large = step % 3 == 0;
        s.chain().unwrap().start_iteration(large);
        let _ = target(&mut s);
        // more numbers on another stream than the state ever read
        for k in 0..5 {
            s.set_stream(3);
            let _ = s.next_f32() + k as f32;
        }
        s.chain().unwrap().reject();
        let after = s.chain().unwrap().values();
        for &i in &read {
            assert_eq!(
                before[i], after[i],
                "step {step}: a rejection changed number {i} of the state"
            );
        }
        // accept something now and then so the state moves on
        if step % 7 == 0 {
            s.chain().unwrap().start_iteration(false);
            let _ = target(&mut s);
            s.chain().unwrap().accept();
        }
    }
}

/// A target whose states read 1 or 6 numbers past the first: T(u) = prod 2 u_i over the
/// numbers read (1 of them when u0 < 1/2, 6 otherwise), so each half holds half the mass.
fn uneven_target(s: &mut Sampler) -> f64 {
    s.set_stream(0);
    let n = if s.next_f64() < 0.5 { 1 } else { 6 };
    s.set_stream(1);
    (0..n).map(|_| 2.0 * s.next_f64()).product()
}

/// A rejected proposal must not forget the numbers it read: they were already part of the
/// state (as of the last large step, moved by the small steps since). A chain that draws them
/// afresh after each rejection favours the states that read more numbers: chains started from
/// the target and moved by small steps alone then end in the 6-number half more often than half
/// the time (53% against 50% at 20,000 chains, about 8 standard errors).
#[test]
fn a_state_that_reads_more_numbers_is_not_favoured() {
    let chains = 20_000u64;
    let mut in_long_half = 0;
    for c in 0..chains {
        let mut s = Sampler::primary(PrimarySamples::new(Pcg32::new(c, 11), 1.0 / 64.0));
        // rejection sampling from T <= 2^6 with the chain's large steps
        let mut t_x = loop {
            s.chain().unwrap().start_iteration(true);
            let t = uneven_target(&mut s);
            let chain = s.chain().unwrap();
            if chain.uniform() * 64.0 < t {
                chain.accept();
                break t;
            }
            chain.reject();
        };
        for _ in 0..64 {
            let chain = s.chain().unwrap();
            chain.start_iteration(false);
            let t_y = uneven_target(&mut s);
            let chain = s.chain().unwrap();
            if chain.uniform() < (t_y / t_x).min(1.0) {
                chain.accept();
                t_x = t_y;
            } else {
                chain.reject();
            }
        }
        in_long_half += u64::from(s.chain().unwrap().value(0, 0).unwrap() >= 0.5);
    }
    let mut fam = common::stats::Family::new("primary sample: more numbers are not favoured");
    fam.binomial("states in the 6-number half", in_long_half, chains, 0.5);
    fam.finish();
}
