//! Small accumulators for accuracy and timing reports.

/// Per-axis error accumulator (e.g. roll, pitch, yaw in degrees): count, maximum and RMS.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ErrorStats {
    pub n: usize,
    pub max: [f64; 3],
    sum_sq: [f64; 3],
}

impl ErrorStats {
    /// Adds one sample of errors, signed or not (the RMS and the largest take their size).
    pub fn add(&mut self, e: [f64; 3]) {
        self.n += 1;
        for ((max, sum_sq), e) in self.max.iter_mut().zip(&mut self.sum_sq).zip(e) {
            *max = max.max(e.abs());
            *sum_sq += e * e;
        }
    }

    /// Root mean square per axis (0 when empty).
    pub fn rmse(&self) -> [f64; 3] {
        self.sum_sq.map(|s| {
            if self.n == 0 {
                0.0
            } else {
                (s / self.n as f64).sqrt()
            }
        })
    }

    /// Largest error over all axes.
    pub fn max_all(&self) -> f64 {
        self.max.iter().cloned().fold(0.0, f64::max)
    }
}

/// Percentiles of a sample (nearest-rank).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Percentiles {
    pub n: usize,
    pub p50: f64,
    pub p90: f64,
    pub p99: f64,
    pub max: f64,
}

impl Percentiles {
    /// None for an empty sample; sorts `values` in place.
    pub fn of(values: &mut [f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        values.sort_by(f64::total_cmp);
        let n = values.len();
        let rank = |p: f64| values[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
        Some(Self {
            n,
            p50: rank(0.50),
            p90: rank(0.90),
            p99: rank(0.99),
            max: values[n - 1],
        })
    }
}

/// The standard normal quantile: `z` with `P(N(0,1) <= z) = p`, for `p` in (0, 1) (Acklam's
/// rational approximation, relative error below 1.2e-9); NaN outside. The decision's bands and
/// the renderer's noise table both use it.
pub fn normal_quantile(p: f64) -> f64 {
    if !(p > 0.0 && p < 1.0) {
        return f64::NAN;
    }
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
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

/// The chi-square quantile: `x` with `P(chi2(dof) <= x) = p`, for `p` in (0, 1) and `dof` > 0
/// (the Wilson-Hilferty cube-root normal approximation; exact for 2 degrees of freedom, within
/// 7 % of the table from 3 up, smaller than the truth at 1 so that a bound on it is wider);
/// NaN outside. The decision bounds the deviation its history's rate regression leaves with
/// it, over the few seconds of sea that regression has seen.
pub fn chi_square_quantile(p: f64, dof: f64) -> f64 {
    if !(p > 0.0 && p < 1.0 && dof > 0.0) {
        return f64::NAN;
    }
    if dof == 2.0 {
        return -2.0 * (1.0 - p).ln();
    }
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + normal_quantile(p) * a.sqrt()).max(0.0).powi(3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_quantiles_match_the_table() {
        // (p, dof, table value)
        for (p, dof, x) in [
            (0.1, 2.0, 0.2107),
            (0.1, 3.0, 0.5844),
            (0.1, 4.0, 1.0636),
            (0.1, 10.0, 4.8652),
            (0.9, 10.0, 15.987),
            (0.25, 5.0, 2.6746),
            (0.5, 20.0, 19.337),
        ] {
            let q = chi_square_quantile(p, dof);
            assert!((q / x - 1.0).abs() < 0.07, "p {p} dof {dof}: {q} against {x}");
        }
        assert!(chi_square_quantile(0.1, 1.0) < 0.0158);
        assert!(chi_square_quantile(0.0, 3.0).is_nan());
        assert!(chi_square_quantile(0.5, 0.0).is_nan());
    }

    #[test]
    fn error_stats() {
        let mut s = ErrorStats::default();
        assert_eq!(s.rmse(), [0.0; 3]);
        s.add([3.0, -1.0, 0.0]);
        s.add([4.0, 1.0, 0.0]);
        assert_eq!(s.max, [4.0, 1.0, 0.0]);
        assert!((s.rmse()[0] - 12.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(s.max_all(), 4.0);
    }

    #[test]
    fn nearest_rank_percentiles() {
        assert!(Percentiles::of(&mut []).is_none());
        let mut v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let p = Percentiles::of(&mut v).unwrap();
        assert_eq!((p.p50, p.p90, p.p99, p.max, p.n), (50.0, 90.0, 99.0, 100.0, 100));
        let p = Percentiles::of(&mut [7.0]).unwrap();
        assert_eq!((p.p50, p.p99), (7.0, 7.0));
    }
    #[test]
    fn normal_quantiles() {
        for (p, z) in [
            (0.5, 0.0),
            (0.975, 1.959_963_985),
            (0.0002, -3.540_083_799),
            (0.999, 3.090_232_306),
        ] {
            assert!(
                (normal_quantile(p) - z).abs() < 1e-6,
                "{p}: {}",
                normal_quantile(p)
            );
        }
        assert!(normal_quantile(0.0).is_nan() && normal_quantile(1.0).is_nan());
        // The renderer's noise table was checked against these too.
        assert!(normal_quantile(0.5).abs() < 1e-12);
        assert!((normal_quantile(0.975) - 1.959963984540054).abs() < 1e-8);
        assert!((normal_quantile(0.001) + 3.090232306167813).abs() < 1e-8);
    }
}
