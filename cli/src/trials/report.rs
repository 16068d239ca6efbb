//! The trials' report: the approach records of a run (or of merged shards) summed per sea state
//! and rule, as a table or as JSON lines.

use super::{ApproachRecord, MergeArgs, Rule};
use deckwatch_trials::RuleSummary;
use std::collections::BTreeMap;

/// The report of `records` (in job order): with `json`, each record, every unsafe touchdown, one
/// object per sea state and rule and the totals; otherwise the table (unsafe touchdowns on
/// stderr). The totals per rule, back.
pub(super) fn report(records: &[ApproachRecord], json: bool) -> Result<BTreeMap<Rule, RuleSummary>, String> {
    let mut per_sea: BTreeMap<u32, BTreeMap<Rule, RuleSummary>> = Default::default();
    for r in records {
        let rule = Rule::of(&r.rule)?;
        if json {
            outln!("{}", serde_json::json!({ "approach": r }));
        }
        // Every unsafe touchdown, with what it broke, to look into.
        if let Some(v) = r.outcome.touchdown.as_ref().filter(|v| !v.safe()) {
            let record = serde_json::json!({"unsafe_touchdown": {
                "sea_state": r.sea_state, "seed": r.seed, "heading_deg": r.heading_deg,
                "index": r.index, "rule": r.rule, "verdict": v}});
            if json {
                outln!("{record}");
            } else {
                errln!("{record}");
            }
        }
        per_sea
            .entry(r.sea_state)
            .or_default()
            .entry(rule)
            .or_default()
            .add(&r.outcome);
    }
    let mut totals: BTreeMap<Rule, RuleSummary> = Default::default();
    let summary_json = |sea: serde_json::Value, rule: Rule, s: &RuleSummary| {
        serde_json::json!({"sea_state": sea, "rule": rule.name(), "summary": s,
            "aborts_per_commit": s.aborts_per_commit(), "median_arrival_to_touchdown_s": s.median_arrival_to_touchdown_s(),
            "safety_case": s.safety_case()})
    };
    for (ss, per_rule) in &per_sea {
        for (rule, s) in per_rule {
            if json {
                outln!("{}", summary_json((*ss).into(), *rule, s));
            } else {
                outln!("{}", row(&ss.to_string(), *rule, s));
            }
            totals.entry(*rule).or_default().merge(s);
        }
    }
    for (rule, s) in &totals {
        if json {
            outln!("{}", summary_json("all".into(), *rule, s));
            continue;
        }
        outln!("{}", row("all", *rule, s));
        let c = s.safety_case();
        let descent = deckwatch_common::stats::Percentiles::of(&mut s.descent_mps.clone());
        outln!(
            "     {:<10} unsafe {} of {} touchdowns (95 % upper bound {:.3} %); landed {:.1} % of approaches (95 %: {:.1}-{:.1} %); arrival to touchdown p50/p90/p99 {:.1}/{:.1}/{:.1} s{}",
            rule.name(),
            s.unsafe_touchdowns,
            s.touchdowns,
            100.0 * c.unsafe_rate_upper_95,
            100.0 * c.landing_rate,
            100.0 * c.landing_rate_95[0],
            100.0 * c.landing_rate_95[1],
            c.arrival_to_touchdown_s_p50_p90_p99[0],
            c.arrival_to_touchdown_s_p50_p90_p99[1],
            c.arrival_to_touchdown_s_p50_p90_p99[2],
            // The oracle's touchdowns are judged without a flown descent.
            descent.map_or(String::new(), |p| format!(
                "; descent over the deck p50/max {:.2}/{:.2} m/s",
                p.p50, p.max
            ))
        );
        if !s.abort_reasons.is_empty() || !s.violations.is_empty() {
            outln!(
                "     {:<10} go-arounds by reason: {:?}; unsafe by limit: {:?}",
                rule.name(),
                s.abort_reasons,
                s.violations
            );
        }
        if !s.too_late_reasons.is_empty() {
            outln!(
                "     {:<10} go-arounds ordered past the point of no return (not flown) by reason: {:?}",
                rule.name(),
                s.too_late_reasons
            );
        }
        if !s.decisions_by_reason.is_empty() {
            outln!("     {:<10} decisions: {:?}", rule.name(), s.decisions_by_reason);
        }
    }
    Ok(totals)
}

/// The largest shard report `trials merge` reads (bytes): a record is ~1 KB, so this holds
/// 250 000 approaches (rules counted) in one shard, which takes a core weeks to fly.
const MAX_SHARD_REPORT_BYTES: u64 = 256 << 20;

/// `deckwatch trials merge`: the shards' approach records, in job order, reported as one run.
pub fn merge(m: &MergeArgs) -> Result<(), String> {
    let mut records: Vec<ApproachRecord> = Vec::new();
    // Per shard with lines left out: the file, how many, the first (1-based).
    let mut skipped: Vec<(String, usize, usize)> = Vec::new();
    for path in &m.files {
        let text = deckwatch_common::files::read_bounded_to_string(path, MAX_SHARD_REPORT_BYTES)
            .map_err(|e| e.to_string())?;
        // A line that is not JSON (a shard cut off mid-line, a log mixed in) is counted, named
        // and skipped: the report then says how much of the shard it left out.
        let (mut not_json, mut first_not_json) = (0usize, 0usize);
        for (n, line) in text.lines().enumerate() {
            let Ok(value) = serde_json::from_str::<serde_json::Value>(line) else {
                if !line.trim().is_empty() {
                    not_json += 1;
                    if first_not_json == 0 {
                        first_not_json = n + 1;
                    }
                }
                continue;
            };
            if let Some(r) = value.get("approach") {
                let r: ApproachRecord = serde_json::from_value(r.clone())
                    .map_err(|e| format!("{}:{}: an approach record: {e}", path.display(), n + 1))?;
                records.push(r);
            }
        }
        if not_json > 0 {
            errln!(
                "trials merge: {}: {not_json} line(s) not JSON skipped, the first at line {first_not_json}",
                path.display()
            );
            skipped.push((path.display().to_string(), not_json, first_not_json));
        }
    }
    if records.is_empty() {
        return Err("trials merge: no approach records (run the shards with --json)".into());
    }
    records.sort_by(|x, y| {
        x.job
            .cmp(&y.job)
            .then_with(|| rule_order(&x.rule).cmp(&rule_order(&y.rule)))
    });
    // The same job and rule twice: a shard given twice, or two runs of different lists.
    if let Some(w) = records
        .windows(2)
        .find(|w| w[0].job == w[1].job && w[0].rule == w[1].rule)
    {
        return Err(format!(
            "trials merge: job {} ({}) appears twice: the same shard given twice?",
            w[0].job, w[0].rule
        ));
    }
    report(&records, m.json)?;
    // A JSON report says it too: whoever reads only the report learns the merge left lines out.
    if m.json {
        for (file, lines, first_line) in &skipped {
            outln!(
                "{}",
                serde_json::json!({"skipped_lines": {"file": file, "lines": lines, "first_line": first_line}})
            );
        }
    }
    Ok(())
}

/// The order of the rules' records within a job, in a run's report and a merge's alike.
pub(super) fn rule_order(name: &str) -> usize {
    ["deckwatch", "naive", "oracle"]
        .iter()
        .position(|r| *r == name)
        .unwrap_or(usize::MAX)
}

fn row(sea: &str, rule: Rule, s: &RuleSummary) -> String {
    format!(
        "{:<4} {:<10} {:>10} {:>8} {:>10} {:>7} {:>7} {:>8.1}% {:>9} {:>9.1}",
        sea,
        rule.name(),
        s.approaches,
        s.commits,
        s.touchdowns,
        s.unsafe_touchdowns,
        s.aborts,
        100.0 * s.aborts_per_commit(),
        s.timeouts,
        s.median_arrival_to_touchdown_s()
    )
}
