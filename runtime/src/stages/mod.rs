//! The pipeline's processes: capture (the source); detect, estimate and decide, each a
//! [`crate::stage::Stage`] around its algorithm crate; the MAVLink link and the flight recorder.

pub mod capture;
pub mod decide;
pub mod detect;
pub mod estimate;
pub mod link;
pub mod record;

pub use decide::DecideStage;
pub use detect::DetectStage;
pub use estimate::EstimateStage;

use crate::row::{places_follow_the_table, StageRow};
use crate::stage::{process, ProcessInfo};
use deckwatch_common::messages::STAGES;

/// The stages a frame passes after capture, in pipeline order, each one's input the output of
/// the one before: declared once, here. The process table lists them and the in-process chain
/// ([`crate::chain::StageChain`]) runs them from this row; their places ([`crate::stage::Stage::PLACE`])
/// are the stage table's (`deckwatch_common::messages::PipelineStage`), in its order.
pub type FrameStages = (DetectStage, EstimateStage, DecideStage);

const _: () = assert!(
    places_follow_the_table::<FrameStages>(),
    "FrameStages must hold every stage of the stage table (PipelineStage), in its order"
);

/// The pipeline's topology, declared once: every process with what it takes in and puts out
/// (capture, the stages of [`FrameStages`], the link, the recorder). The launcher derives from
/// it the start order and when each process is up ([`crate::stage::start_order`]), the
/// recorder what it subscribes to ([`record::recorded_services`]); `deckwatch doctor` and the
/// cleanup take the names from it.
pub const PROCESSES: [ProcessInfo; STAGES + 3] = topology(
    process::<capture::Capture>(),
    <FrameStages as StageRow>::PROCESSES,
    [process::<link::Link>(), process::<record::Recorder>()],
);

/// The source, the stages, the sinks: one table.
const fn topology<const N: usize>(
    source: ProcessInfo,
    stages: &[ProcessInfo],
    sinks: [ProcessInfo; 2],
) -> [ProcessInfo; N] {
    assert!(N == 1 + stages.len() + sinks.len(), "the topology's size");
    let mut all = [source; N];
    let mut i = 0;
    while i < stages.len() {
        all[1 + i] = stages[i];
        i += 1;
    }
    let mut j = 0;
    while j < sinks.len() {
        all[1 + stages.len() + j] = sinks[j];
        j += 1;
    }
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::PipelineConfig;
    use deckwatch_common::messages::{Channel, FrameHeader, PipelineStage, SOURCE};

    /// The process table and the row of stages come from the stage table: the names in its
    /// order, and each stage takes in what the place before it puts out (the row the
    /// in-process chain runs).
    #[test]
    fn the_topology_follows_the_stage_table() {
        let names: Vec<&str> = PROCESSES.iter().map(|p| p.name).collect();
        assert_eq!(names[0], SOURCE);
        assert_eq!(names[1..=STAGES], PipelineStage::ALL.map(PipelineStage::name));
        assert_eq!(names[STAGES + 1..], ["link", "record"]);
        assert_eq!(<FrameStages as StageRow>::PLACES, PipelineStage::ALL);
        assert_eq!(PROCESSES[0].outputs, [FrameHeader::SERVICE]);
        let config = PipelineConfig::default();
        for w in PROCESSES[..=STAGES].windows(2) {
            assert_eq!(
                (w[1].inputs)(&config),
                w[0].outputs,
                "{} after {}",
                w[1].name,
                w[0].name
            );
        }
    }
}
