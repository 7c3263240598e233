//! The chains' convergence diagnostics (`math::mixing`, Vehtari et al. 2021) against values
//! known in closed form:
//!
//! - the normal quantile against `statrs`, and the normal scores of tied ranks by hand;
//! - Gelman and Rubin's R-hat of chains built to have exact means and variances;
//! - i.i.d. normal chains: the split-R-hat follows the F law of the between / within ratio;
//! - chains with shifted means, a chain that drifts, chains of different scales: R-hat >> 1
//!   (the drift only after the split, the scales only with the folded draws);
//! - AR(1) chains: the ESS matches M N (1 - rho) / (1 + rho), for positive and negative rho.

use crate::common;

use common::stats::{runs_mean, Family};
use pathspace::math::mixing::{
    basic_rhat, bulk_ess, ess, fold, normal_quantile, rank_normalize, rhat, split_chains,
};
use statrs::distribution::{ContinuousCDF, FisherSnedecor, Normal};

/// `m` chains of `n` standard normal draws, stream `seed`.
fn normal_chains(seed: u64, m: usize, n: usize) -> Vec<Vec<f64>> {
    let normal = Normal::standard();
    (0..m)
        .map(|c| {
            let mut s = common::sampler(seed, c as u64);
            (0..n)
                .map(|_| normal.inverse_cdf(s.next_f64().clamp(1e-300, 1.0 - 1e-16)))
                .collect()
        })
        .collect()
}

/// `m` AR(1) chains x_t = rho x_{t-1} + sqrt(1 - rho^2) e_t of `n` draws, started stationary.
fn ar1_chains(seed: u64, m: usize, n: usize, rho: f64) -> Vec<Vec<f64>> {
    let innovations = normal_chains(seed, m, n);
    let k = (1.0 - rho * rho).sqrt();
    innovations
        .into_iter()
        .map(|e| {
            let mut x = e[0];
            let mut out = vec![x];
            for &ei in &e[1..] {
                x = rho * x + k * ei;
                out.push(x);
            }
            out
        })
        .collect()
}

#[test]
fn the_normal_quantile_is_the_inverse_of_the_normal_cdf() {
    let normal = Normal::standard();
    for i in 1..2000 {
        let p = i as f64 / 2000.0;
        for p in [p, p * 1e-6, 1.0 - p * 1e-6] {
            let (a, b) = (normal_quantile(p), normal.inverse_cdf(p));
            // Acklam's approximation: relative error below 1.15e-9
            assert!(
                (a - b).abs() <= 1.2e-9 * b.abs().max(1e-3),
                "p = {p}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn tied_draws_share_the_normal_score_of_their_mean_rank() {
    // four draws: three zeros (ranks 1, 2, 3: mean 2) and a one (rank 4), S = 4
    let z = rank_normalize(&[vec![0.0, 0.0], vec![0.0, 1.0]]);
    let normal = Normal::standard();
    let z0 = normal.inverse_cdf((2.0 - 0.375) / 4.25);
    let z1 = normal.inverse_cdf((4.0 - 0.375) / 4.25);
    for (got, want) in z.iter().flatten().zip([z0, z0, z0, z1]) {
        assert!((got - want).abs() < 1e-8, "{z:?}");
    }
    // folding about the pooled median (0)
    assert_eq!(
        fold(&[vec![-2.0, 0.0], vec![0.0, 5.0]]),
        vec![vec![2.0, 0.0], vec![0.0, 5.0]]
    );
    // halves in order; the middle of an odd chain is left out
    assert_eq!(
        split_chains(&[vec![1.0, 2.0, 3.0, 4.0, 5.0]]),
        vec![vec![1.0, 2.0], vec![4.0, 5.0]]
    );
}

#[test]
fn gelman_rubin_of_shifted_copies_is_its_closed_form() {
    // every chain holds the same values in its own order, half of them shifted by delta: the
    // within-chain variance is exactly W of the base values, the chain means differ by delta
    let n = 1000;
    let base: Vec<f64> = (0..n)
        .map(|i| normal_quantile((i as f64 + 0.5) / n as f64))
        .collect();
    let w = {
        let mean = base.iter().sum::<f64>() / n as f64;
        base.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n as f64 - 1.0)
    };
    for (m, delta) in [(4usize, 1.0), (8, 0.5), (2, 2.0)] {
        let chains: Vec<Vec<f64>> = (0..m)
            .map(|c| {
                let shift = if c < m / 2 { 0.0 } else { delta };
                let mut v: Vec<f64> = base.iter().map(|x| x + shift).collect();
                v.rotate_left(c * 37 % n);
                v
            })
            .collect();
        // B / N: the unbiased variance of m / 2 zeros and m / 2 deltas
        let b_over_n = delta * delta * m as f64 / (4.0 * (m as f64 - 1.0));
        let nf = n as f64;
        let want = (((nf - 1.0) / nf * w + b_over_n) / w).sqrt();
        let got = basic_rhat(&chains).unwrap();
        assert!((got - want).abs() < 1e-9 * want, "m {m}: {got} vs {want}");
        // and the rank-normalized split-R-hat sees the disagreement too
        assert!(rhat(&chains).unwrap() > 1.1, "m {m}: {:?}", rhat(&chains));
    }
}

#[test]
fn the_split_r_hat_of_iid_normal_chains_follows_the_f_law() {
    // for normal i.i.d. draws, n B / N / W = n var(chain means) / W ~ F(m - 1, m (n - 1)) with
    // m = 2M split chains of n = N / 2, so R-hat^2 = (n - 1) / n + F / n; the normal scores of
    // the ranks are normal in the limit. R-hat is the larger of two such values (bulk, folded)
    let (big_m, big_n) = (4usize, 2000usize);
    let (m, n) = (2 * big_m, big_n / 2);
    let f = FisherSnedecor::new((m - 1) as f64, (m * (n - 1)) as f64).unwrap();
    let mut fam = Family::new("mixing: split-R-hat of i.i.d. chains");
    let mut largest: f64 = 0.0;
    for seed in 0..24 {
        let r = rhat(&normal_chains(seed, big_m, big_n)).unwrap();
        largest = largest.max(r);
        let stat = n as f64 * (r * r - (n as f64 - 1.0) / n as f64);
        fam.p_value(
            &format!("seed {seed}: R-hat {r:.5}"),
            (2.0 * f.sf(stat)).min(1.0),
            format!("F statistic {stat:.3}"),
        );
    }
    fam.finish();
    // about 1: below Vehtari et al.'s threshold for a single quantity
    assert!(largest < 1.01, "{largest}");
}

#[test]
fn a_drift_needs_the_split_and_a_scale_needs_the_fold() {
    let mut chains = normal_chains(7, 4, 2000);
    // every chain drifts: its second half is shifted by one standard deviation; whole chains
    // agree with each other, halves do not
    let drifted: Vec<Vec<f64>> = chains
        .iter()
        .map(|c| {
            let h = c.len() / 2;
            c.iter()
                .enumerate()
                .map(|(i, x)| x + if i < h { 0.0 } else { 1.0 })
                .collect()
        })
        .collect();
    assert!(basic_rhat(&drifted).unwrap() < 1.01);
    assert!(rhat(&drifted).unwrap() > 1.1, "{:?}", rhat(&drifted));
    // two chains three times as wide: same location, so only the folded draws disagree
    for c in chains.iter_mut().take(2) {
        c.iter_mut().for_each(|x| *x *= 3.0);
    }
    let bulk = basic_rhat(&rank_normalize(&split_chains(&chains))).unwrap();
    assert!(bulk < 1.01, "{bulk}");
    assert!(rhat(&chains).unwrap() > 1.1, "{:?}", rhat(&chains));
}

#[test]
fn the_ess_of_ar1_chains_is_its_closed_form() {
    // an AR(1) chain has rho_t = rho^t, tau = (1 + rho) / (1 - rho): ESS = M N (1 - rho) / (1 + rho).
    // The estimate has an error of its own (a few percent here, and Geyer's truncated sum is
    // biased low by about that much for weakly correlated draws), so the closed form must lie
    // within one estimate's error: the mean of k runs against the truth with the standard error
    // of a single run, s sqrt(1 + 1 / k) (a prediction interval). A tau off by a factor, or a
    // sum that is not truncated, is off by many such errors.
    let (m, n, k) = (4usize, 4000usize, 12u64);
    let mut fam = Family::new("mixing: ESS of AR(1) chains");
    for rho in [0.0, 0.5, 0.9, -0.3] {
        let want = (m * n) as f64 * (1.0 - rho) / (1.0 + rho);
        let runs: Vec<Vec<Vec<f64>>> = (0..k).map(|s| ar1_chains(100 + s, m, n, rho)).collect();
        for (name, f) in [
            ("ESS", ess as fn(&[Vec<f64>]) -> Option<f64>),
            ("bulk ESS", bulk_ess),
        ] {
            let ratios: Vec<f64> = runs.iter().map(|c| f(c).unwrap() / want).collect();
            let (mean, se, dof) = runs_mean(&ratios);
            let one_run = se * (k as f64).sqrt() * (1.0 + 1.0 / k as f64).sqrt();
            fam.mean_is(
                &format!("rho {rho}: {name} / closed form"),
                mean,
                one_run,
                dof,
                1.0,
            );
        }
    }
    fam.finish();
}

#[test]
fn undefined_diagnostics_are_none() {
    assert_eq!(rhat(&[vec![1.0; 10], vec![1.0; 10]]), None);
    assert_eq!(ess(&[vec![1.0, 2.0, 3.0]]), None);
    assert_eq!(basic_rhat(&[vec![1.0, 2.0]]), None);
    assert_eq!(rhat(&[]), None);
    assert_eq!(bulk_ess(&[vec![0.0; 40], vec![0.0; 40]]), None);
}
