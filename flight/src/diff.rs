//! Where two runs' outputs part: per stage (markers, attitudes, decisions) and frame, which
//! fields differ and by how much. `deckwatch diff A.mcap B.mcap` prints it; re-simulation's
//! test asserts that a replay through the same build differs nowhere.

use crate::json::JsonField;
use crate::reader::FlightMessages;
use deckwatch_common::messages::PipelineStage;
use serde_json::Value;
use std::collections::BTreeMap;

/// One field that differs in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldDifference {
    /// Dotted path (`rpy.roll`, `markers.markers.3.u`).
    pub path: String,
    pub a: Value,
    pub b: Value,
}

/// How one stage's outputs compare.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StageDiff {
    pub stage: &'static str,
    /// Frames (outputs) both runs have.
    pub compared: u64,
    pub identical: u64,
    /// Outputs only one run has (their frame sequence numbers).
    pub only_a: Vec<u64>,
    pub only_b: Vec<u64>,
    /// The frames whose outputs differ.
    pub differing: Vec<u64>,
    /// The first differing frame's fields.
    pub first: Option<(u64, Vec<FieldDifference>)>,
    /// Over every differing frame: per numeric field, the largest absolute difference; per
    /// other field, how many frames differ in it.
    pub largest: BTreeMap<String, f64>,
    pub changed: BTreeMap<String, u64>,
}

impl StageDiff {
    pub fn same(&self) -> bool {
        self.only_a.is_empty() && self.only_b.is_empty() && self.differing.is_empty()
    }
}

/// What to leave out of the comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DiffOptions {
    /// Compare the stage times too (by default they are left out: two runs never take the same
    /// microseconds, and a re-simulation stamps its own).
    pub with_times: bool,
}

/// Compares the stages' outputs of two recordings.
pub fn diff(a: &FlightMessages, b: &FlightMessages, options: DiffOptions) -> Vec<StageDiff> {
    vec![
        diff_stage(PipelineStage::Detect.name(), &a.markers, &b.markers, options),
        diff_stage(
            PipelineStage::Estimate.name(),
            &a.attitudes,
            &b.attitudes,
            options,
        ),
        diff_stage(PipelineStage::Decide.name(), &a.decisions, &b.decisions, options),
    ]
}

/// A stage's outputs keyed by frame: (sequence number, the how-manieth output for that frame:
/// the watchdog repeats its last frame).
fn keyed<T: JsonField>(items: &[T], options: DiffOptions) -> BTreeMap<(u64, u32), Value> {
    let mut out = BTreeMap::new();
    let mut seen: BTreeMap<u64, u32> = BTreeMap::new();
    for item in items {
        let mut v = item.to_json();
        let seq = v["stamp"]["seq"].as_u64().unwrap_or(u64::MAX);
        if !options.with_times {
            strip_times(&mut v);
        }
        let n = seen.entry(seq).or_insert(0);
        out.insert((seq, *n), v);
        *n += 1;
    }
    out
}

/// Removes every `stamp.times` (the decision carries its attitude's stamp too).
fn strip_times(v: &mut Value) {
    if let Value::Object(m) = v {
        if let Some(Value::Object(stamp)) = m.get_mut("stamp") {
            stamp.remove("times");
        }
        for child in m.values_mut() {
            strip_times(child);
        }
    }
}

fn diff_stage<T: JsonField>(stage: &'static str, a: &[T], b: &[T], options: DiffOptions) -> StageDiff {
    let (ka, kb) = (keyed(a, options), keyed(b, options));
    let mut d = StageDiff {
        stage,
        ..StageDiff::default()
    };
    for (key, va) in &ka {
        let Some(vb) = kb.get(key) else {
            d.only_a.push(key.0);
            continue;
        };
        d.compared += 1;
        let mut fields = Vec::new();
        leaf_differences("", va, vb, &mut fields);
        if fields.is_empty() {
            d.identical += 1;
            continue;
        }
        d.differing.push(key.0);
        for f in &fields {
            match (f.a.as_f64(), f.b.as_f64()) {
                (Some(x), Some(y)) => {
                    let e = d.largest.entry(f.path.clone()).or_insert(0.0);
                    *e = e.max((x - y).abs());
                }
                _ => *d.changed.entry(f.path.clone()).or_insert(0) += 1,
            }
        }
        if d.first.is_none() {
            d.first = Some((key.0, fields));
        }
    }
    d.only_b = kb.keys().filter(|k| !ka.contains_key(k)).map(|k| k.0).collect();
    d
}

fn leaf_differences(path: &str, a: &Value, b: &Value, out: &mut Vec<FieldDifference>) {
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match (a, b) {
        (Value::Object(ma), Value::Object(mb)) => {
            for (k, va) in ma {
                match mb.get(k) {
                    Some(vb) => leaf_differences(&join(k), va, vb, out),
                    None => out.push(FieldDifference {
                        path: join(k),
                        a: va.clone(),
                        b: Value::Null,
                    }),
                }
            }
        }
        (Value::Array(xa), Value::Array(xb)) if xa.len() == xb.len() => {
            for (i, (va, vb)) in xa.iter().zip(xb).enumerate() {
                leaf_differences(&join(&i.to_string()), va, vb, out);
            }
        }
        _ if a != b => out.push(FieldDifference {
            path: path.to_string(),
            a: a.clone(),
            b: b.clone(),
        }),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{AttitudeMessage, DecisionState, LandingDecision};

    #[test]
    fn finds_the_first_frame_where_outputs_part() {
        let mut a = FlightMessages::default();
        for seq in 0..5 {
            let mut m = AttitudeMessage::default();
            m.stamp.seq = seq;
            m.rpy.roll = seq as f64 * 0.01;
            m.stamp.times[PipelineStage::Estimate].finished_ns = 100 + seq;
            a.attitudes.push(m);
            let mut d = LandingDecision::default();
            d.stamp.seq = seq;
            a.decisions.push(d);
        }
        let mut b = a.clone();
        // Other times only: no difference.
        b.attitudes[1].stamp.times[PipelineStage::Estimate].finished_ns = 7;
        assert!(diff(&a, &b, DiffOptions::default()).iter().all(StageDiff::same));
        assert!(!diff(&a, &b, DiffOptions { with_times: true })[1].same());
        b.attitudes[3].rpy.roll += 1e-9;
        b.decisions[4].state = DecisionState::ClearToLand.into();
        b.decisions.pop();
        let d = diff(&a, &b, DiffOptions::default());
        let est = &d[1];
        assert_eq!(
            (est.compared, est.identical, est.differing.clone()),
            (5, 4, vec![3])
        );
        let (seq, fields) = est.first.clone().unwrap();
        assert_eq!((seq, fields[0].path.as_str()), (3, "rpy.roll"));
        assert!((est.largest["rpy.roll"] - 1e-9).abs() < 1e-12);
        assert_eq!(d[2].only_a, vec![4]);
    }
}
