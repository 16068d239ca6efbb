//! What a safety case needs from a campaign of approaches: exact (Clopper-Pearson) binomial
//! bounds on a rate. Exact because the counts that matter are small (zero
//! unsafe touchdowns in N): a normal approximation says nothing there. (Percentiles are
//! `deckwatch_common::stats::Percentiles`.)

/// P(X <= k) for X ~ Binomial(n, p), summed in log space (n up to millions without overflow).
fn binomial_cdf(k: u64, n: u64, p: f64) -> f64 {
    if k >= n {
        return 1.0;
    }
    if p <= 0.0 {
        return 1.0;
    }
    if p >= 1.0 {
        return 0.0;
    }
    let (ln_p, ln_q) = (p.ln(), (1.0 - p).ln());
    // ln C(n, i) built up term by term; the largest term first scales the sum (log-sum-exp).
    let mut ln_choose = 0.0;
    let mut terms = Vec::with_capacity(k as usize + 1);
    for i in 0..=k {
        if i > 0 {
            ln_choose += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        terms.push(ln_choose + i as f64 * ln_p + (n - i) as f64 * ln_q);
    }
    let top = terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (top + terms.iter().map(|t| (t - top).exp()).sum::<f64>().ln())
        .exp()
        .min(1.0)
}

/// The `p` in [0, 1] where the decreasing `f` crosses `target` (bisection to 1e-12).
fn solve_decreasing(f: impl Fn(f64) -> f64, target: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The exact one-sided upper bound on a rate with `k` events in `n` trials at `confidence`
/// (e.g. 0.95): the largest rate under which seeing `k` or fewer has probability 1 - confidence.
/// Zero events in `n` gives 1 - (1 - confidence)^(1/n) (about 3/n at 95 %). 1 without trials.
pub fn upper_bound(k: u64, n: u64, confidence: f64) -> f64 {
    if n == 0 || k >= n {
        return 1.0;
    }
    let alpha = 1.0 - confidence;
    solve_decreasing(|p| binomial_cdf(k, n, p), alpha)
}

/// The exact two-sided Clopper-Pearson interval of a rate with `k` events in `n` trials at
/// `confidence`: [0, 1] without trials.
pub fn interval(k: u64, n: u64, confidence: f64) -> [f64; 2] {
    if n == 0 {
        return [0.0, 1.0];
    }
    let alpha = 1.0 - confidence;
    let lower = if k == 0 {
        0.0
    } else {
        // P(X >= k; p) = 1 - P(X <= k - 1; p) rises with p: the p where it is alpha / 2.
        solve_decreasing(|p| binomial_cdf(k - 1, n, p), 1.0 - alpha / 2.0)
    };
    let upper = if k == n {
        1.0
    } else {
        solve_decreasing(|p| binomial_cdf(k, n, p), alpha / 2.0)
    };
    [lower, upper]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_match_the_closed_forms_and_published_values() {
        // Zero events: 1 - alpha^(1/n). 212 safe touchdowns bound the rate below 1.4 % (the
        // issue's figure); about 30 000 are needed for 1 in 10 000.
        for n in [1u64, 10, 212, 30_000] {
            let closed = 1.0 - 0.05f64.powf(1.0 / n as f64);
            assert!((upper_bound(0, n, 0.95) - closed).abs() < 1e-9, "{n}");
        }
        assert!((upper_bound(0, 212, 0.95) - 0.01403).abs() < 1e-4);
        assert!(upper_bound(0, 30_000, 0.95) < 1e-4 && upper_bound(0, 29_000, 0.95) > 1e-4);
        // The textbook Clopper-Pearson interval of 5 in 20 at 95 %: [0.0866, 0.4910].
        let [lo, hi] = interval(5, 20, 0.95);
        assert!(
            (lo - 0.0866).abs() < 1e-4 && (hi - 0.4910).abs() < 1e-4,
            "{lo} {hi}"
        );
        // All successes: [alpha/2 ^ (1/n), 1].
        let [lo, hi] = interval(20, 20, 0.95);
        assert!((lo - 0.025f64.powf(1.0 / 20.0)).abs() < 1e-9 && hi == 1.0);
        // One event in 1000: its one-sided 95 % bound is 4.73 per 1000 (Poisson 4.74 / n).
        assert!((upper_bound(1, 1000, 0.95) - 0.00473).abs() < 2e-5);
        assert_eq!(upper_bound(0, 0, 0.95), 1.0);
        // Large n with many events stays finite and ordered.
        let [lo, hi] = interval(90_000, 100_000, 0.95);
        assert!(lo < 0.9 && 0.9 < hi && hi - lo < 0.005, "{lo} {hi}");
    }
}
