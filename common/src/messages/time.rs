//! Time and counting: the one monotonic clock, the wall-clock base, each frame's stage times,
//! drop counts and sequence gaps, and the stamp every message starts with. The per-stage
//! values are indexed by the stage table ([`PipelineStage`], `messages/stages.rs`).

use super::stages::{PipelineStage, SOURCE, STAGES};
#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;

/// Nanoseconds of `CLOCK_MONOTONIC`: one clock for every process on the machine (unlike
/// `Instant`, its values can be compared across processes), never set back.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec we pass; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The offset from the pipeline's `CLOCK_MONOTONIC` to UNIX time, measured once (per flight
/// recording, per rerun logging thread): what turns the messages' times into wall-clock times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TimeBase {
    pub unix_minus_monotonic_ns: i64,
}

impl TimeBase {
    /// Now: the system clock less the monotonic one.
    pub fn measure() -> Self {
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64);
        Self {
            unix_minus_monotonic_ns: unix.saturating_sub(monotonic_ns() as i64),
        }
    }

    /// No offset: times are already what the file should show (a converted recording's).
    pub const IDENTITY: Self = Self {
        unix_minus_monotonic_ns: 0,
    };

    pub fn to_unix_ns(&self, monotonic_ns: u64) -> u64 {
        (monotonic_ns as i64)
            .saturating_add(self.unix_minus_monotonic_ns)
            .max(0) as u64
    }
}

/// When one stage had a frame: `CLOCK_MONOTONIC` nanoseconds, 0 = not (yet). (`Pod`, which
/// gives `AnyBitPattern`: an array of it is one too.)
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.StageSpan.v1"))]
pub struct StageSpan {
    pub received_ns: u64,
    pub finished_ns: u64,
}

/// When a frame passed the source and each stage: `CLOCK_MONOTONIC` nanoseconds, 0 = not (yet)
/// passed. A stage's times are `times[stage]` ([`PipelineStage`]); they are named (a
/// recording's JSON, the decisions CSV) by [`StageTimes::NAMES`], in this order.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.StageTimes.v1"))]
pub struct StageTimes {
    /// The frame was captured: exposure (camera), start of rendering (simulator), start of
    /// reading (replay).
    pub captured_ns: u64,
    /// The frame was in shared memory and sent to the first stage.
    pub published_ns: u64,
    /// When each stage received and finished the frame, by its place in the pipeline.
    pub stages: [StageSpan; STAGES],
}

/// The values of [`StageTimes`], in order: the source's two, each stage's two.
pub const TIME_VALUES: usize = 2 + 2 * STAGES;

// The same bytes as a time per stage and end, in pipeline order (`deckwatch.StageTimes.v1`).
const _: () = assert!(std::mem::size_of::<StageTimes>() == 8 * TIME_VALUES);

impl std::ops::Index<PipelineStage> for StageTimes {
    type Output = StageSpan;
    fn index(&self, stage: PipelineStage) -> &StageSpan {
        &self.stages[stage.index()]
    }
}

impl std::ops::IndexMut<PipelineStage> for StageTimes {
    fn index_mut(&mut self, stage: PipelineStage) -> &mut StageSpan {
        &mut self.stages[stage.index()]
    }
}

/// The latency intervals deckwatch reports, in pipeline order ([`LatencyInterval::ALL`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatencyInterval {
    /// Capturing the frame into shared memory (render, decode or copy).
    Capture,
    /// From publication to the first stage's receipt: the frame hop through shared memory
    /// (`capture->detect`).
    Hop,
    /// A stage: the first one's processing (received -> finished); each later one's hop and
    /// processing (the stage before finished -> finished).
    Stage(PipelineStage),
    /// Frame published -> decision made: what the pipeline adds after the frame exists.
    EndToEnd,
}

impl LatencyInterval {
    /// Every interval, in pipeline order: capture, the hop, each stage, end to end.
    pub const ALL: [Self; STAGES + 3] = {
        let mut all = [Self::Capture; STAGES + 3];
        all[1] = Self::Hop;
        let mut i = 0;
        while i < STAGES {
            all[2 + i] = Self::Stage(PipelineStage::ALL[i]);
            i += 1;
        }
        all[STAGES + 2] = Self::EndToEnd;
        all
    };

    /// Its name, as reports and the viewer write it (`capture`, `capture->detect`, a stage's
    /// name, `end-to-end`).
    pub fn name(&self) -> &'static str {
        match self {
            Self::Capture => SOURCE,
            Self::Hop => super::stages::HOP_NAME,
            Self::Stage(s) => s.name(),
            Self::EndToEnd => "end-to-end",
        }
    }

    /// The interval [`Self::name`] calls `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == name)
    }
}

impl StageTimes {
    /// The names of the times, in order (`captured_ns`, `published_ns`, then each stage's
    /// `<stage>_received_ns`, `<stage>_finished_ns`): a recording's JSON fields, the decisions
    /// CSV's columns.
    pub const NAMES: [&'static str; TIME_VALUES] = {
        let mut names = ["captured_ns"; TIME_VALUES];
        names[1] = "published_ns";
        let mut i = 0;
        while i < STAGES {
            names[2 + 2 * i] = PipelineStage::ALL[i].received_name();
            names[3 + 2 * i] = PipelineStage::ALL[i].finished_name();
            i += 1;
        }
        names
    };

    /// The times in the order of [`Self::NAMES`].
    pub fn values(&self) -> [u64; TIME_VALUES] {
        std::array::from_fn(|i| match i {
            0 => self.captured_ns,
            1 => self.published_ns,
            i if i % 2 == 0 => self.stages[(i - 2) / 2].received_ns,
            i => self.stages[(i - 2) / 2].finished_ns,
        })
    }

    /// The times from their values in the order of [`Self::NAMES`].
    pub fn from_values(values: [u64; TIME_VALUES]) -> Self {
        Self {
            captured_ns: values[0],
            published_ns: values[1],
            stages: std::array::from_fn(|k| StageSpan {
                received_ns: values[2 + 2 * k],
                finished_ns: values[3 + 2 * k],
            }),
        }
    }

    /// The times with their names, in order.
    pub fn named(&self) -> [(&'static str, u64); TIME_VALUES] {
        let values = self.values();
        std::array::from_fn(|i| (Self::NAMES[i], values[i]))
    }

    /// The interval in nanoseconds, when both of its ends are stamped and in order.
    pub fn interval_ns(&self, which: LatencyInterval) -> Option<u64> {
        let (a, b) = match which {
            LatencyInterval::Capture => (self.captured_ns, self.published_ns),
            LatencyInterval::Hop => (self.published_ns, self[PipelineStage::FIRST].received_ns),
            LatencyInterval::Stage(s) => {
                let start = match s.previous() {
                    None => self[s].received_ns,
                    Some(p) => self[p].finished_ns,
                };
                (start, self[s].finished_ns)
            }
            LatencyInterval::EndToEnd => (self.published_ns, self[PipelineStage::LAST].finished_ns),
        };
        (a != 0 && b >= a).then(|| b - a)
    }
}

/// Frames lost so far, by where (cumulative counts of the process that counted them; they
/// restart at 0 when that stage is restarted). A stage's count is `drops[stage]`
/// ([`PipelineStage`]); the counts are named (the launcher's report, a recording's JSON, the
/// viewer) by [`DropCounts::NAMES`], in this order.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.DropCounts.v1"))]
pub struct DropCounts {
    /// Frames the source delivered that capture could not publish (no free shared-memory
    /// sample, or capture fell behind the camera).
    pub capture: u64,
    /// Frames capture could not read (bad file, decode error); skipped, not published.
    pub bad_frames: u64,
    /// Frames published but never processed by each stage (it was busy; latest-frame
    /// semantics), by its place in the pipeline.
    pub stages: [u64; STAGES],
}

/// The counts of [`DropCounts`], in order: the source's two, one per stage.
pub const DROP_VALUES: usize = 2 + STAGES;

// The same bytes as a count per place, in pipeline order (`deckwatch.DropCounts.v1`).
const _: () = assert!(std::mem::size_of::<DropCounts>() == 8 * DROP_VALUES);

impl std::ops::Index<PipelineStage> for DropCounts {
    type Output = u64;
    fn index(&self, stage: PipelineStage) -> &u64 {
        &self.stages[stage.index()]
    }
}

impl std::ops::IndexMut<PipelineStage> for DropCounts {
    fn index_mut(&mut self, stage: PipelineStage) -> &mut u64 {
        &mut self.stages[stage.index()]
    }
}

impl DropCounts {
    /// The counts' names, in pipeline order (`capture`, `bad_frames`, then each stage's name).
    pub const NAMES: [&'static str; DROP_VALUES] = {
        let mut names = [SOURCE; DROP_VALUES];
        names[1] = "bad_frames";
        let mut i = 0;
        while i < STAGES {
            names[2 + i] = PipelineStage::ALL[i].name();
            i += 1;
        }
        names
    };

    /// The counts in the order of [`Self::NAMES`].
    pub fn values(&self) -> [u64; DROP_VALUES] {
        std::array::from_fn(|i| match i {
            0 => self.capture,
            1 => self.bad_frames,
            i => self.stages[i - 2],
        })
    }

    /// The counts from their values in the order of [`Self::NAMES`].
    pub fn from_values(values: [u64; DROP_VALUES]) -> Self {
        Self {
            capture: values[0],
            bad_frames: values[1],
            stages: std::array::from_fn(|k| values[2 + k]),
        }
    }

    /// Every frame lost before the stage that reports these counts. Saturating: the counts
    /// come from other processes over shared memory, and a corrupt one must not overflow here.
    pub fn total(&self) -> u64 {
        self.values().iter().fold(0u64, |sum, n| sum.saturating_add(*n))
    }

    /// The counts with their names, in pipeline order.
    pub fn named(&self) -> [(&'static str, u64); DROP_VALUES] {
        let values = self.values();
        std::array::from_fn(|i| (Self::NAMES[i], values[i]))
    }
}

/// The counts by name (`{"capture": .., "bad_frames": .., "detect": .., ...}`), as the
/// launcher's JSON report has them.
impl serde::Serialize for DropCounts {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = serializer.serialize_map(Some(DROP_VALUES))?;
        for (name, n) in self.named() {
            map.serialize_entry(name, &n)?;
        }
        map.end()
    }
}

/// Counts the frames a stage never saw: gaps in the sequence numbers of its input, minus the
/// gaps its upstream stages already counted.
#[derive(Debug, Default, Clone)]
pub struct GapCounter {
    last: Option<(u64, u64)>,
    from_start: bool,
}

impl GapCounter {
    /// For a stage that was there when capture started: frames before the first one it sees
    /// (from sequence 0) were missed too.
    pub fn from_start() -> Self {
        Self {
            last: None,
            from_start: true,
        }
    }

    /// For a stage that joined a running pipeline (a restart): counting starts at the first
    /// frame it sees.
    pub fn joining() -> Self {
        Self::default()
    }

    /// `joining()` or `from_start()`.
    pub fn new(joined_late: bool) -> Self {
        if joined_late {
            Self::joining()
        } else {
            Self::from_start()
        }
    }

    /// Feed the next input's sequence number and its upstream drop total; returns the frames
    /// this stage missed since the previous input. A sequence going backwards (capture was
    /// restarted) starts counting afresh.
    pub fn observe(&mut self, seq: u64, upstream_total: u64) -> u64 {
        let missed = match self.last {
            Some((last_seq, last_up)) if seq > last_seq => {
                let gap = seq - last_seq - 1;
                gap.saturating_sub(upstream_total.saturating_sub(last_up))
            }
            None if self.from_start => seq.saturating_sub(upstream_total),
            _ => 0,
        };
        self.last = Some((seq, upstream_total));
        missed
    }
}

/// Identity and timing of one frame, at the start of every message.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.FrameStamp.v1"))]
pub struct FrameStamp {
    /// Capture's count of published frames, from 0; consecutive unless frames were dropped.
    pub seq: u64,
    pub times: StageTimes,
    pub drops: DropCounts,
}
