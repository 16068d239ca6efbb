//! What a run did: the report `deckwatch run` and `deckwatch latency` print (as a table or JSON).

use deckwatch_common::messages::DropCounts;
use serde::Serialize;

/// Latency percentiles of one interval (milliseconds).
#[derive(Debug, Clone, Serialize)]
pub struct LatencyRow {
    pub interval: String,
    pub count: u64,
    pub p50_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

/// Frames lost, by where (summed over stage restarts), and the decisions the launcher missed.
#[derive(Debug, Clone, Default, Serialize)]
pub struct DropReport {
    #[serde(flatten)]
    pub counts: DropCounts,
    /// Decisions the launcher itself missed (its queue overflowed).
    pub observer: u64,
}

/// What a run did.
#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    pub decisions: u64,
    /// Stale-data decisions of decide's watchdog (no attitude in time), not answers to frames.
    pub watchdog_decisions: u64,
    pub duration_s: f64,
    pub latency: Vec<LatencyRow>,
    pub drops: DropReport,
    pub restarts: Vec<(String, u32)>,
    pub states: Vec<(String, u64)>,
    pub valid_attitudes: u64,
    /// Roll, pitch, yaw RMSE and max error (deg) over frames with truth and an attitude.
    pub rmse_deg: Option<[f64; 3]>,
    pub max_error_deg: Option<[f64; 3]>,
    /// Frames with an attitude although the source says no deck was in view.
    pub attitudes_without_deck: u64,
    /// Whether the run ended because of a signal (else: the source was exhausted).
    pub interrupted: bool,
    /// The decisions CSV could not be written to the end (it is incomplete): why.
    pub decisions_csv_error: Option<String>,
    /// Decisions the launcher received with a bad enum or boolean (a corrupt publisher):
    /// skipped, not counted above.
    pub bad_decisions_skipped: u64,
}

/// The report as a table for people.
pub fn print_report(r: &RunReport) {
    outln!(
        "{} decisions in {:.1} s ({:.1} per s){}",
        r.decisions,
        r.duration_s,
        r.decisions as f64 / r.duration_s.max(1e-9),
        if r.interrupted { ", stopped by signal" } else { "" }
    );
    outln!("latency (ms)        count      p50      p90      p99      max");
    for l in &r.latency {
        outln!(
            "  {:<16} {:>7} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
            l.interval,
            l.count,
            l.p50_ms,
            l.p90_ms,
            l.p99_ms,
            l.max_ms
        );
    }
    let d = &r.drops.counts;
    let by_place: Vec<String> = d
        .named()
        .iter()
        .map(|(name, n)| format!("{} {n}", name.replace('_', " ")))
        .collect();
    outln!(
        "drops: {} ({}); decisions missed by the launcher: {}",
        d.total(),
        by_place.join(", "),
        r.drops.observer
    );
    let states: Vec<String> = r.states.iter().map(|(n, c)| format!("{n} {c}")).collect();
    outln!(
        "decisions: {}; watchdog (stale) decisions: {}; bad decisions skipped: {}",
        states.join(", "),
        r.watchdog_decisions,
        r.bad_decisions_skipped
    );
    let restarts: Vec<String> = r.restarts.iter().map(|(n, c)| format!("{n} {c}")).collect();
    outln!("restarts: {}", restarts.join(", "));
    if let (Some(rmse), Some(max)) = (r.rmse_deg, r.max_error_deg) {
        outln!(
            "attitude vs truth (deg): RMSE roll {:.4} pitch {:.4} yaw {:.4}; max {:.4} {:.4} {:.4}",
            rmse[0],
            rmse[1],
            rmse[2],
            max[0],
            max[1],
            max[2]
        );
    }
    outln!(
        "valid attitudes: {} of {}; attitudes on frames without a deck: {}",
        r.valid_attitudes,
        r.decisions,
        r.attitudes_without_deck
    );
}
