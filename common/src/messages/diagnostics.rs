//! The processes' own messages: heartbeats, log lines and the link's traffic counts.

use super::*;

/// "This process is alive and its loop turns": every stage process sends one at least every
/// [`StageHeartbeat::PERIOD_NS`] from the loop that does its work (never from a helper thread,
/// which would beat on while the loop hangs). The launcher restarts a stage whose beats stop.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(
    feature = "shm",
    derive(ZeroCopySend),
    type_name("deckwatch.StageHeartbeat.v1")
)]
pub struct StageHeartbeat {
    /// The sender's process id (the launcher knows its children by it).
    pub pid: u32,
    /// The sender's count of beats, from 0.
    pub seq: u64,
    /// When it was sent (`CLOCK_MONOTONIC`, ns).
    pub sent_ns: u64,
}

impl StageHeartbeat {
    pub const PERIOD_NS: u64 = 100_000_000;
}

/// How serious a [`StageLog`] line is (Foxglove's `Log` levels).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LogLevel {
    Debug = 1,
    #[default]
    Info = 2,
    Warning = 3,
    Error = 4,
}

wire_enum!(LogLevel, on_bad_code: Error, [Debug, Info, Warning, Error]);

impl LogLevel {
    /// A stage's line, judged by its words (the stages write plain lines on stderr): failures
    /// are errors; restarts, unresponsive stages and a nonzero count of dropped or skipped
    /// things are warnings ("0 dropped" in a summary is not).
    pub fn of_line(line: &str) -> Self {
        let l = line.to_ascii_lowercase();
        if ["error", "failed", "panicked", "cannot", "killing", "killed"]
            .iter()
            .any(|w| l.contains(w))
        {
            return Self::Error;
        }
        if ["not responding", "restart", "stale", "warning"]
            .iter()
            .any(|w| l.contains(w))
        {
            return Self::Warning;
        }
        let words: Vec<&str> = l
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| !w.is_empty())
            .collect();
        let counted = words.windows(2).any(|w| {
            ["dropped", "skipped", "bad", "missed"].contains(&w[1])
                && w[0].parse::<u64>().is_ok_and(|n| n > 0)
        });
        if counted {
            Self::Warning
        } else {
            Self::Info
        }
    }
}

/// One line a process of the pipeline wrote on stderr, which the launcher passes on
/// (`deckwatch/log`) when a recorder runs.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.StageLog.v1"))]
pub struct StageLog {
    /// When the launcher read it (`CLOCK_MONOTONIC`, ns).
    pub time_ns: u64,
    pub pid: u32,
    pub level: WireCode<LogLevel>,
    /// The process's name (UTF-8, `name_len` bytes; longer names are cut).
    pub name: [u8; StageLog::NAME_BYTES],
    pub name_len: u32,
    /// The line (UTF-8, `text_len` bytes; longer lines are cut).
    pub text: [u8; StageLog::TEXT_BYTES],
    pub text_len: u32,
}

impl Default for StageLog {
    fn default() -> Self {
        Self::new(0, 0, "", "")
    }
}

impl StageLog {
    pub const NAME_BYTES: usize = 24;
    pub const TEXT_BYTES: usize = 480;

    pub fn new(time_ns: u64, pid: u32, name: &str, line: &str) -> Self {
        let mut out = Self {
            time_ns,
            pid,
            level: LogLevel::of_line(line).into(),
            name: [0; Self::NAME_BYTES],
            name_len: 0,
            text: [0; Self::TEXT_BYTES],
            text_len: 0,
        };
        out.name_len = copy_cut(name, &mut out.name);
        out.text_len = copy_cut(line, &mut out.text);
        out
    }

    /// The name, as far as it is UTF-8 (a length past the array is read as the whole array).
    pub fn name(&self) -> String {
        lossy(&self.name, self.name_len)
    }

    pub fn text(&self) -> String {
        lossy(&self.text, self.text_len)
    }
}

/// Copies as much of `s` as fits, cut at a character boundary; the bytes copied.
fn copy_cut(s: &str, out: &mut [u8]) -> u32 {
    let mut n = s.len().min(out.len());
    while !s.is_char_boundary(n) {
        n -= 1;
    }
    out[..n].copy_from_slice(&s.as_bytes()[..n]);
    n as u32
}

fn lossy(bytes: &[u8], len: u32) -> String {
    let n = (len as usize).min(bytes.len());
    String::from_utf8_lossy(&bytes[..n]).into_owned()
}

/// One MAVLink frame the link sent or received (`deckwatch/link`), for the recorder.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.LinkTraffic.v1"))]
pub struct LinkTraffic {
    /// When it was sent or received (`CLOCK_MONOTONIC`, ns).
    pub time_ns: u64,
    /// Sent by deckwatch (true) or received from the link (false).
    pub outgoing: WireBool,
    pub msg_id: u32,
    /// The message's name (`LANDING_TARGET`; ASCII, `name_len` bytes).
    pub name: [u8; LinkTraffic::NAME_BYTES],
    pub name_len: u32,
    /// The whole MAVLink 2 frame as on the wire (`frame_len` bytes).
    pub frame: [u8; LinkTraffic::FRAME_BYTES],
    pub frame_len: u32,
}

impl Default for LinkTraffic {
    fn default() -> Self {
        Self::new(0, false, 0, "", &[])
    }
}

impl LinkTraffic {
    pub const NAME_BYTES: usize = 48;
    /// The largest MAVLink 2 frame is 283 bytes (a 32-bit system id and a signature); 288 keeps
    /// the layout free of padding.
    pub const FRAME_BYTES: usize = 288;

    pub fn new(time_ns: u64, outgoing: bool, msg_id: u32, name: &str, frame: &[u8]) -> Self {
        let mut out = Self {
            time_ns,
            outgoing: outgoing.into(),
            msg_id,
            name: [0; Self::NAME_BYTES],
            name_len: 0,
            frame: [0; Self::FRAME_BYTES],
            frame_len: 0,
        };
        out.name_len = copy_cut(name, &mut out.name);
        let n = frame.len().min(Self::FRAME_BYTES);
        out.frame[..n].copy_from_slice(&frame[..n]);
        out.frame_len = n as u32;
        out
    }

    pub fn name(&self) -> String {
        lossy(&self.name, self.name_len)
    }

    /// The frame's bytes (a length past the array is read as the whole array).
    pub fn frame_bytes(&self) -> &[u8] {
        &self.frame[..(self.frame_len as usize).min(Self::FRAME_BYTES)]
    }
}
