//! The primer's checks (book chapter "A Monte Carlo primer"): the four ideas every later chapter
//! uses, each on an integral or a chain small enough to know its answer exactly.
//!
//! - Monte Carlo estimation: the mean of f(X)/p(X) is the integral, its variance is known;
//! - importance sampling: a density closer to f keeps the mean and lowers the variance;
//! - multiple importance sampling: two strategies, power-heuristic weights, still unbiased;
//! - Metropolis-Hastings: eq. (8)'s acceptance makes the chain satisfy detailed balance, so it
//!   keeps f / b stationary.

use crate::common;

use common::stats::Family;
use pathspace::integrator::mlt::acceptance::acceptance;
use pathspace::integrator::path::power_heuristic;
use pathspace::math::Sampler;

/// The integrand of the primer, f(x) = x^2 on [0, 1]: its integral is 1/3.
fn f(x: f64) -> f64 {
    x * x
}
const INTEGRAL: f64 = 1.0 / 3.0;
const N: u64 = 200_000;

/// The mean and the sample variance of `n` values.
fn mean_var(values: impl Iterator<Item = f64>) -> (f64, f64, u64) {
    let (mut n, mut sum, mut sum2) = (0u64, 0.0, 0.0);
    for v in values {
        n += 1;
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n as f64;
    (mean, (sum2 - n as f64 * mean * mean) / (n - 1) as f64, n)
}

/// Checks that one-sample estimates `y` have mean `INTEGRAL` and variance `variance`: the
/// variance by the mean of the squared deviations (y - I)^2, itself a Monte Carlo mean.
fn check_estimator(fam: &mut Family, what: &str, y: &[f64], variance: f64) {
    let (mean, var, n) = mean_var(y.iter().copied());
    fam.samples_are(&format!("{what}: mean"), mean, var, n, INTEGRAL);
    let (m2, v2, n2) = mean_var(y.iter().map(|v| (v - INTEGRAL).powi(2)));
    fam.samples_are(&format!("{what}: variance"), m2, v2, n2, variance);
}

// ANCHOR: monte_carlo
/// Uniform samples, p(x) = 1: F = f(X) / p(X) has mean 1/3 and variance
/// E[X^4] - 1/9 = 1/5 - 1/9 = 4/45.
#[test]
fn monte_carlo_estimates_the_integral_with_the_predicted_variance() {
    let mut fam = Family::new("primer: Monte Carlo estimation");
    let mut s = Sampler::new(1, 0, 0);
    let y: Vec<f64> = (0..N)
        .map(|_| {
            let x = s.next_f64();
            let p = 1.0;
            f(x) / p
        })
        .collect();
    check_estimator(&mut fam, "uniform", &y, 4.0 / 45.0);
    fam.finish();
}
// ANCHOR_END: monte_carlo

// ANCHOR: importance
/// Importance sampling with p(x) = 2x, drawn by inverting its CDF x^2 = u: F = x / 2 has the
/// same mean and the variance E[X^2] / 4 - 1/9 = 1/8 - 1/9 = 1/72, 6.4 times less.
#[test]
fn importance_sampling_keeps_the_mean_and_lowers_the_variance() {
    let mut fam = Family::new("primer: importance sampling");
    let mut s = Sampler::new(2, 0, 0);
    let y: Vec<f64> = (0..N)
        .map(|_| {
            let x = s.next_f64().sqrt();
            let p = 2.0 * x;
            if p > 0.0 {
                f(x) / p
            } else {
                0.0
            }
        })
        .collect();
    check_estimator(&mut fam, "p = 2x", &y, 1.0 / 72.0);
    fam.finish();
}
// ANCHOR_END: importance

// ANCHOR: mis
/// Multiple importance sampling: one sample from each of p1 = 1 and p2 = 2x, each weighted by
/// the power heuristic w_i = p_i^2 / (p1^2 + p2^2). The weights of a point sum to one, so the
/// sum of the two weighted estimates is unbiased.
#[test]
fn mis_with_the_power_heuristic_is_unbiased() {
    let mut fam = Family::new("primer: multiple importance sampling");
    let mut s = Sampler::new(3, 0, 0);
    let pdfs = |x: f64| (1.0, 2.0 * x);
    let y: Vec<f64> = (0..N)
        .map(|_| {
            let x1 = s.next_f64();
            let (p1, p2) = pdfs(x1);
            let from_uniform = power_heuristic(p1 as f32, p2 as f32) as f64 * f(x1) / p1;
            let x2 = s.next_f64().sqrt();
            let (p1, p2) = pdfs(x2);
            let from_linear = if p2 > 0.0 {
                power_heuristic(p2 as f32, p1 as f32) as f64 * f(x2) / p2
            } else {
                0.0
            };
            from_uniform + from_linear
        })
        .collect();
    let (mean, var, n) = mean_var(y.iter().copied());
    fam.samples_are("MIS: mean", mean, var, n, INTEGRAL);
    fam.finish();
}
// ANCHOR_END: mis

// ANCHOR: metropolis
/// A Metropolis-Hastings chain on the ring of states 0..8 with target f(i) = i + 1 and an
/// asymmetric proposal (one step up with probability 0.7, down with 0.3), accepted by eq. (8)'s
/// `acceptance`. Detailed balance f(x) K(x -> y) = f(y) K(y -> x) holds pair by pair, and 4000
/// independent chains started at state 0 end, after 1000 steps, distributed as f / b.
#[test]
fn metropolis_hastings_keeps_the_target_stationary() {
    const STATES: usize = 8;
    let target = |i: usize| (i + 1) as f64;
    let proposal = |x: usize, y: usize| {
        if y == (x + 1) % STATES {
            0.7
        } else if x == (y + 1) % STATES {
            0.3
        } else {
            0.0
        }
    };
    let kernel = |x: usize, y: usize| {
        proposal(x, y) * acceptance(target(x), target(y), proposal(x, y), proposal(y, x))
    };
    for x in 0..STATES {
        for y in 0..STATES {
            let (there, back) = (target(x) * kernel(x, y), target(y) * kernel(y, x));
            assert!(
                (there - back).abs() <= 1e-12 * there.max(back),
                "detailed balance {x} <-> {y}: f(x) K(x -> y) = {there}, f(y) K(y -> x) = {back}"
            );
        }
    }
    let mut fam = Family::new("primer: Metropolis-Hastings");
    let mut counts = [0u64; STATES];
    for chain in 0..4000 {
        let mut s = Sampler::new(4, chain, 0);
        let mut x = 0;
        for _ in 0..1000 {
            let y = if s.next_f64() < 0.7 {
                (x + 1) % STATES
            } else {
                (x + STATES - 1) % STATES
            };
            if s.next_f64() < acceptance(target(x), target(y), proposal(x, y), proposal(y, x)) {
                x = y;
            }
        }
        counts[x] += 1;
    }
    let b: f64 = (0..STATES).map(target).sum();
    let expected: Vec<f64> = (0..STATES).map(|i| 4000.0 * target(i) / b).collect();
    fam.chi_square("final states against f / b", &counts, &expected);
    fam.finish();
}
// ANCHOR_END: metropolis
