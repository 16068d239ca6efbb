//! Small accumulators for accuracy and timing reports.

/// Per-axis error accumulator (e.g. roll, pitch, yaw in degrees): count, maximum and RMS.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ErrorStats {
    pub n: usize,
    pub max: [f64; 3],
    sum_sq: [f64; 3],
}

impl ErrorStats {
    /// Adds one sample of absolute errors.
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
