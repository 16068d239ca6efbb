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

use crate::stage::{process, ProcessInfo};

/// The pipeline's topology, declared once: every process with what it takes in and puts out.
/// The launcher derives from it the start order and when each process is up
/// ([`crate::stage::start_order`]); `deckwatch doctor` and the cleanup take the names from it.
pub const PROCESSES: [ProcessInfo; 6] = [
    process::<capture::Capture>(),
    process::<DetectStage>(),
    process::<EstimateStage>(),
    process::<DecideStage>(),
    process::<link::Link>(),
    process::<record::Recorder>(),
];
