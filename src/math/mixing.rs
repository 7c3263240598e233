//! Whether Markov chains have mixed: the rank-normalized split-R-hat and the bulk effective
//! sample size of Vehtari, Gelman, Simpson, Carpenter and Buerkner (2021), "Rank-normalization,
//! folding, and localization: an improved R-hat for assessing convergence of MCMC".
//!
//! M chains of N draws of one scalar. Each chain is split in halves (a chain that drifts has
//! halves that disagree), the draws are replaced by the normal quantiles of their pooled ranks
//! (so heavy tails and ties do not matter), and then
//!
//! - R-hat = sqrt(((N - 1) / N W + B / N) / W), W the mean within-chain variance and B / N the
//!   variance of the chain means: about 1 when every chain samples the same distribution,
//!   above 1 when they disagree; the reported value is the larger of the bulk R-hat and the
//!   R-hat of the folded draws |x - median| (chains that agree in location but not in scale);
//! - ESS = M N / tau, tau = 1 + 2 sum_t rho_t the integrated autocorrelation time, with the
//!   autocorrelations rho_t estimated over all chains and summed by Geyer's initial monotone
//!   sequence (paper eq. 10 and sec. 3.2).
//!
//! Each function returns `None` where the quantity is undefined: fewer than two chains after
//! the split, fewer than two draws per half, or draws that never vary.
//! Book: "Metropolis light transport", section "Have the chains mixed?".

/// Each chain's two halves (the middle draw of an odd length left out), chains in order.
pub fn split_chains(chains: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(2 * chains.len());
    for c in chains {
        let half = c.len() / 2;
        out.push(c[..half].to_vec());
        out.push(c[c.len() - half..].to_vec());
    }
    out
}

/// The standard normal quantile Phi^-1(p), 0 < p < 1 (Acklam's rational approximation, relative
/// error below 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// The draws replaced by the normal scores of their ranks among all draws of all chains:
/// z = Phi^-1((r - 3/8) / (S + 1/4)) (Blom's offset, paper eq. 14), ties given their mean rank.
pub fn rank_normalize(chains: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut all: Vec<(f64, usize, usize)> = chains
        .iter()
        .enumerate()
        .flat_map(|(c, v)| v.iter().enumerate().map(move |(i, &x)| (x, c, i)))
        .collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    let s = all.len() as f64;
    let mut out: Vec<Vec<f64>> = chains.iter().map(|c| vec![0.0; c.len()]).collect();
    let mut i = 0;
    while i < all.len() {
        let mut j = i;
        while j + 1 < all.len() && all[j + 1].0 == all[i].0 {
            j += 1;
        }
        // ranks i + 1 ..= j + 1 share their mean
        let r = (i + j) as f64 / 2.0 + 1.0;
        let z = normal_quantile((r - 0.375) / (s + 0.25));
        for &(_, c, k) in &all[i..=j] {
            out[c][k] = z;
        }
        i = j + 1;
    }
    out
}

/// The draws folded about their pooled median: |x - median| (paper sec. 4.1).
pub fn fold(chains: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    let n = all.len();
    let median = if n == 0 {
        0.0
    } else if n % 2 == 1 {
        all[n / 2]
    } else {
        (all[n / 2 - 1] + all[n / 2]) / 2.0
    };
    chains
        .iter()
        .map(|c| c.iter().map(|x| (x - median).abs()).collect())
        .collect()
}

/// Mean and unbiased variance of one chain (Welford's update: exactly 0 for a constant chain).
fn mean_var(x: &[f64]) -> (f64, f64) {
    let (mut mean, mut m2) = (0.0, 0.0);
    for (k, &v) in x.iter().enumerate() {
        let d = v - mean;
        mean += d / (k + 1) as f64;
        m2 += d * (v - mean);
    }
    (mean, m2 / (x.len() as f64 - 1.0))
}

/// Chain count and common length, if there are at least two chains of at least two draws.
fn shape(chains: &[Vec<f64>]) -> Option<(usize, usize)> {
    let n = chains.first()?.len();
    (chains.len() >= 2 && n >= 2 && chains.iter().all(|c| c.len() == n))
        .then_some((chains.len(), n))
}

/// The R-hat of Gelman and Rubin as the chains are given (no split, no ranks), paper eq. 4;
/// infinite for constant chains that differ (every chain stuck at its own value).
pub fn basic_rhat(chains: &[Vec<f64>]) -> Option<f64> {
    let (m, n) = shape(chains)?;
    let stats: Vec<(f64, f64)> = chains.iter().map(|c| mean_var(c)).collect();
    let w = stats.iter().map(|s| s.1).sum::<f64>() / m as f64;
    let means: Vec<f64> = stats.iter().map(|s| s.0).collect();
    let b_over_n = mean_var(&means).1;
    let n = n as f64;
    if w == 0.0 {
        // constant chains: infinitely apart if they differ, undefined if they agree
        return (b_over_n > 0.0).then_some(f64::INFINITY);
    }
    let r = (((n - 1.0) / n * w + b_over_n) / w).sqrt();
    r.is_finite().then_some(r)
}

/// The rank-normalized split-R-hat: the larger of the bulk and the folded R-hat (paper sec.
/// 4.2). Vehtari et al. recommend trusting the chains when it is below 1.01.
pub fn rhat(chains: &[Vec<f64>]) -> Option<f64> {
    let split = split_chains(chains);
    let bulk = basic_rhat(&rank_normalize(&split))?;
    let folded = basic_rhat(&rank_normalize(&fold(&split)));
    Some(folded.map_or(bulk, |f| bulk.max(f)))
}

/// The effective sample size of the chains as given: M N / tau, the autocorrelations pooled over
/// chains (paper eq. 10) and summed by Geyer's initial monotone sequence, as `posterior`'s
/// `ess_basic` computes it (tau floored at 1 / log10(M N)). The autocovariances are the biased
/// ones (divided by N, as Geyer 1992 recommends), computed for the lags the sum reaches.
pub fn ess(chains: &[Vec<f64>]) -> Option<f64> {
    let (m, n) = shape(chains)?;
    if n < 6 {
        return None;
    }
    let nf = n as f64;
    let means: Vec<f64> = chains.iter().map(|c| c.iter().sum::<f64>() / nf).collect();
    let centred: Vec<Vec<f64>> = chains
        .iter()
        .zip(&means)
        .map(|(c, mean)| c.iter().map(|v| v - mean).collect())
        .collect();
    let mean_acov = |t: usize| {
        let per_chain = |d: &Vec<f64>| (0..n - t).map(|i| d[i] * d[i + t]).sum::<f64>() / nf;
        centred.iter().map(per_chain).sum::<f64>() / m as f64
    };
    let mean_var = mean_acov(0) * nf / (nf - 1.0);
    let var_plus = mean_var * (nf - 1.0) / nf + mean_var_of(&means);
    if !(var_plus > 0.0 && var_plus.is_finite()) {
        return None;
    }
    let rho_at = |t: usize| 1.0 - (mean_var - mean_acov(t)) / var_plus;
    let mut rho = vec![0.0; n];
    rho[0] = 1.0;
    rho[1] = rho_at(1);
    let (mut even, mut odd) = (1.0, rho[1]);
    let mut t = 0;
    // Geyer's initial positive sequence: pairs of lags while their sum stays positive
    while t + 5 < n && even + odd > 0.0 {
        t += 2;
        even = rho_at(t);
        odd = rho_at(t + 1);
        if even + odd >= 0.0 {
            rho[t] = even;
            rho[t + 1] = odd;
        }
    }
    let max_t = t;
    if even > 0.0 {
        rho[max_t] = even;
    }
    // Geyer's initial monotone sequence: the pair sums made non-increasing
    let mut t = 0;
    while t + 4 <= max_t {
        t += 2;
        if rho[t] + rho[t + 1] > rho[t - 2] + rho[t - 1] {
            rho[t] = (rho[t - 2] + rho[t - 1]) / 2.0;
            rho[t + 1] = rho[t];
        }
    }
    let total = (m * n) as f64;
    let tau = -1.0 + 2.0 * rho[..max_t].iter().sum::<f64>() + rho[max_t];
    let tau = tau.max(1.0 / total.log10());
    Some(total / tau)
}

/// The unbiased variance of a list (0 for a single value).
fn mean_var_of(x: &[f64]) -> f64 {
    if x.len() < 2 {
        0.0
    } else {
        mean_var(x).1
    }
}

/// The bulk effective sample size: the ESS of the rank-normalized split chains (paper sec. 4.3);
/// Vehtari et al. ask for at least 100 per chain before trusting R-hat and the estimates.
pub fn bulk_ess(chains: &[Vec<f64>]) -> Option<f64> {
    ess(&rank_normalize(&split_chains(chains)))
}
