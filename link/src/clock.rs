//! The autopilot's clock on this machine's `CLOCK_MONOTONIC`.
//!
//! TIMESYNC: we send `ts1 = now` (ns), the autopilot answers with `tc1` = its time (ns) and our
//! `ts1`; at the answer's arrival `now2`, the offset (autopilot - local) is
//! `tc1 - (ts1 + now2) / 2`, off by at most half the round trip's asymmetry. Offsets of the
//! quickest round trips of a window are fitted with a line (offset and drift). Without TIMESYNC
//! answers the offset comes from arrival times (the largest `remote - arrival` of a window, late
//! by the link's smallest latency), and says so.

use deckwatch_common::messages::ClockMethod;
use std::collections::VecDeque;

/// Samples kept (at 2 Hz: the last 32 s).
const WINDOW: usize = 64;
/// A TIMESYNC answer slower than this is a stale or confused one.
const MAX_RTT_NS: i64 = 200_000_000;

/// The estimate at one moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockEstimate {
    /// autopilot time - local time (ns) at `at_local_ns`.
    pub offset_ns: f64,
    pub at_local_ns: f64,
    /// d(offset)/d(local time), parts per million.
    pub drift_ppm: f64,
    /// The smallest round trip of the window (ns; 0 for arrival times).
    pub rtt_ns: u64,
    pub method: ClockMethod,
}

impl ClockEstimate {
    /// autopilot time - local time at local time `t_ns`.
    pub fn offset_at(&self, t_ns: f64) -> f64 {
        self.offset_ns + self.drift_ppm * 1e-6 * (t_ns - self.at_local_ns)
    }

    /// The local time of an autopilot time (ns).
    pub fn to_local_ns(&self, remote_ns: f64) -> f64 {
        // remote = local + offset(local); one fixed-point step is exact to ppm^2.
        let guess = remote_ns - self.offset_at(remote_ns - self.offset_ns);
        remote_ns - self.offset_at(guess)
    }

    /// The autopilot time of a local time (ns).
    pub fn to_remote_ns(&self, local_ns: f64) -> f64 {
        local_ns + self.offset_at(local_ns)
    }
}

/// The clock estimator.
#[derive(Debug, Clone, Default)]
pub struct ClockSync {
    /// (local mid-point ns, offset ns, rtt ns) of answered TIMESYNCs.
    exchanges: VecDeque<(i64, i64, i64)>,
    /// (local arrival ns, remote - arrival ns) of timestamped messages.
    arrivals: VecDeque<(i64, i64)>,
    /// Our requests awaiting an answer (their ts1).
    pending: VecDeque<i64>,
    pub answered: u64,
    pub refused: u64,
}

impl ClockSync {
    /// A TIMESYNC request we send at `now_ns`: its `ts1`.
    pub fn request(&mut self, now_ns: i64) -> i64 {
        if self.pending.len() == 8 {
            self.pending.pop_front();
        }
        self.pending.push_back(now_ns);
        now_ns
    }

    /// Whether `ts1` is one of ours (a TIMESYNC with `tc1 != 0` answers a request; only ours
    /// count, other components' answers pass by on a shared link).
    pub fn is_ours(&self, ts1: i64) -> bool {
        self.pending.contains(&ts1)
    }

    /// An answer (`tc1` remote ns, our `ts1`) that arrived at `now_ns`; false when refused.
    pub fn answer(&mut self, tc1: i64, ts1: i64, now_ns: i64) -> bool {
        let Some(i) = self.pending.iter().position(|&p| p == ts1) else {
            self.refused += 1;
            return false;
        };
        self.pending.remove(i);
        let rtt = now_ns - ts1;
        if !(0..=MAX_RTT_NS).contains(&rtt) || tc1 <= 0 {
            self.refused += 1;
            return false;
        }
        let mid = ts1 + rtt / 2;
        if self.exchanges.len() == WINDOW {
            self.exchanges.pop_front();
        }
        self.exchanges.push_back((mid, tc1 - mid, rtt));
        self.answered += 1;
        true
    }

    /// A message stamped `remote_ns` by the autopilot arrived at `now_ns`.
    pub fn arrival(&mut self, remote_ns: i64, now_ns: i64) {
        // A reboot of the autopilot restarts its clock: start over.
        if let Some(&(_, last)) = self.arrivals.back() {
            if (remote_ns - now_ns) < last - 1_000_000_000 {
                self.arrivals.clear();
                self.exchanges.clear();
            }
        }
        if self.arrivals.len() == 4 * WINDOW {
            self.arrivals.pop_front();
        }
        self.arrivals.push_back((now_ns, remote_ns - now_ns));
    }

    /// The current estimate: TIMESYNC when answered, else arrival times, else none.
    pub fn estimate(&self) -> Option<ClockEstimate> {
        if !self.exchanges.is_empty() {
            return Some(self.fit_exchanges());
        }
        let &(at, _) = self.arrivals.back()?;
        let offset = self.arrivals.iter().map(|a| a.1).max()?;
        Some(ClockEstimate {
            offset_ns: offset as f64,
            at_local_ns: at as f64,
            drift_ppm: 0.0,
            rtt_ns: 0,
            method: ClockMethod::Arrival,
        })
    }

    fn fit_exchanges(&self) -> ClockEstimate {
        let min_rtt = self.exchanges.iter().map(|e| e.2).min().unwrap_or(0);
        // The quickest round trips are the most symmetric.
        let limit = 2 * min_rtt + 200_000;
        let good: Vec<(f64, f64)> = self
            .exchanges
            .iter()
            .filter(|e| e.2 <= limit)
            .map(|e| (e.0 as f64, e.1 as f64))
            .collect();
        let n = good.len() as f64;
        let t_mean = good.iter().map(|g| g.0).sum::<f64>() / n;
        let o_mean = good.iter().map(|g| g.1).sum::<f64>() / n;
        let stt: f64 = good.iter().map(|g| (g.0 - t_mean).powi(2)).sum();
        // A drift needs a few seconds of baseline to mean anything.
        let slope = if good.len() >= 4 && stt > 4.0 * 1e18 {
            good.iter().map(|g| (g.0 - t_mean) * (g.1 - o_mean)).sum::<f64>() / stt
        } else {
            0.0
        };
        ClockEstimate {
            offset_ns: o_mean,
            at_local_ns: t_mean,
            drift_ppm: slope * 1e6,
            rtt_ns: min_rtt.max(0) as u64,
            method: ClockMethod::Timesync,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An autopilot clock `offset + (1 + drift) * local`, answering after `up` and `down` ns.
    fn exchange(s: &mut ClockSync, local: i64, offset: i64, drift: f64, up: i64, down: i64) {
        let ts1 = s.request(local);
        let remote_at = local + up;
        let tc1 = remote_at + offset + (drift * remote_at as f64) as i64;
        assert!(s.answer(tc1, ts1, remote_at + down));
    }

    #[test]
    fn offset_and_drift_from_round_trips() {
        let mut s = ClockSync::default();
        assert!(s.estimate().is_none());
        let (offset, drift) = (7_000_000_000i64, 20e-6);
        for k in 0..40i64 {
            let local = 1_000_000_000 + k * 500_000_000;
            // A slow, asymmetric answer now and then: filtered out by its round trip.
            let (up, down) = if k % 5 == 0 {
                (9_000_000, 1_000_000)
            } else {
                (300_000, 300_000)
            };
            exchange(&mut s, local, offset, drift, up, down);
        }
        let e = s.estimate().unwrap();
        assert_eq!(e.method, ClockMethod::Timesync);
        assert_eq!(e.rtt_ns, 600_000);
        assert!((e.drift_ppm - 20.0).abs() < 0.5, "{e:?}");
        let t = 21_000_000_000.0;
        let truth = offset as f64 + drift * t;
        assert!(
            (e.offset_at(t) - truth).abs() < 20_000.0,
            "{} vs {truth}",
            e.offset_at(t)
        );
        let remote = e.to_remote_ns(t);
        assert!((e.to_local_ns(remote) - t).abs() < 1.0);
    }

    #[test]
    fn answers_not_ours_or_too_slow_are_refused() {
        let mut s = ClockSync::default();
        assert!(!s.answer(5, 12345, 20000));
        let ts1 = s.request(1_000);
        assert!(s.is_ours(ts1));
        assert!(!s.answer(5_000, ts1, 1_000 + 300_000_000));
        assert_eq!(s.refused, 2);
        assert!(s.estimate().is_none());
    }

    #[test]
    fn arrival_times_give_an_offset_late_by_the_smallest_latency() {
        let mut s = ClockSync::default();
        let offset = 3_000_000_000i64;
        for k in 0..100i64 {
            let local_measured = k * 10_000_000;
            let latency = 2_000_000 + (k % 7) * 1_000_000;
            s.arrival(local_measured + offset, local_measured + latency);
        }
        let e = s.estimate().unwrap();
        assert_eq!(e.method, ClockMethod::Arrival);
        assert_eq!(e.offset_ns as i64, offset - 2_000_000);
    }
}
