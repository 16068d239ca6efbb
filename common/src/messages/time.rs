//! Time and counting: the one monotonic clock, the wall-clock base, each frame's stage times,
//! drop counts and sequence gaps, and the stamp every message starts with.

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

/// When a frame passed each stage: `CLOCK_MONOTONIC` nanoseconds, 0 = not (yet) passed.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.StageTimes.v1"))]
pub struct StageTimes {
    /// The frame was captured: exposure (camera), start of rendering (simulator), start of
    /// reading (replay).
    pub captured_ns: u64,
    /// The frame was in shared memory and sent to detect.
    pub published_ns: u64,
    pub detect_received_ns: u64,
    pub detect_finished_ns: u64,
    pub estimate_received_ns: u64,
    pub estimate_finished_ns: u64,
    pub decide_received_ns: u64,
    pub decide_finished_ns: u64,
}

/// The latency intervals deckwatch reports, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatencyInterval {
    /// Capturing the frame into shared memory (render, decode or copy).
    Capture,
    /// From publication to detect's receipt: the frame hop through shared memory.
    CaptureToDetect,
    Detect,
    /// Hop and processing: detect finished -> estimate finished.
    Estimate,
    /// Hop and processing: estimate finished -> decide finished.
    Decide,
    /// Frame published -> decision made: what the pipeline adds after the frame exists.
    EndToEnd,
}

crate::named_enum!(
    LatencyInterval,
    [
        Capture => "capture",
        CaptureToDetect => "capture->detect",
        Detect => "detect",
        Estimate => "estimate",
        Decide => "decide",
        EndToEnd => "end-to-end",
    ]
);

impl StageTimes {
    /// The interval in nanoseconds, when both of its ends are stamped and in order.
    pub fn interval_ns(&self, which: LatencyInterval) -> Option<u64> {
        let (a, b) = match which {
            LatencyInterval::Capture => (self.captured_ns, self.published_ns),
            LatencyInterval::CaptureToDetect => (self.published_ns, self.detect_received_ns),
            LatencyInterval::Detect => (self.detect_received_ns, self.detect_finished_ns),
            LatencyInterval::Estimate => (self.detect_finished_ns, self.estimate_finished_ns),
            LatencyInterval::Decide => (self.estimate_finished_ns, self.decide_finished_ns),
            LatencyInterval::EndToEnd => (self.published_ns, self.decide_finished_ns),
        };
        (a != 0 && b >= a).then(|| b - a)
    }
}

/// Frames lost so far, by where (cumulative counts of the process that counted them; they
/// restart at 0 when that stage is restarted).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.DropCounts.v1"))]
pub struct DropCounts {
    /// Frames the source delivered that capture could not publish (no free shared-memory
    /// sample, or capture fell behind the camera).
    pub capture: u64,
    /// Frames capture could not read (bad file, decode error); skipped, not published.
    pub bad_frames: u64,
    /// Frames published but never processed by detect (it was busy; latest-frame semantics).
    pub detect: u64,
    pub estimate: u64,
    pub decide: u64,
}

impl DropCounts {
    /// Every frame lost before the stage that reports these counts. Saturating: the counts
    /// come from other processes over shared memory, and a corrupt one must not overflow here.
    pub fn total(&self) -> u64 {
        self.named()
            .iter()
            .fold(0u64, |sum, (_, n)| sum.saturating_add(*n))
    }

    /// The counts with their names, in pipeline order.
    pub fn named(&self) -> [(&'static str, u64); 5] {
        [
            ("capture", self.capture),
            ("bad_frames", self.bad_frames),
            ("detect", self.detect),
            ("estimate", self.estimate),
            ("decide", self.decide),
        ]
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
