//! Which received bytes the link believes, and the frames it sends.
//!
//! Every frame that reaches the link passes, in this order, a per-sender rate limit, the
//! MAVLink 2 framing and checksum, the message signature (MAVLink 2 signing: a shared 32-byte key,
//! SHA-256, a timestamp per stream that must only grow) and the pinned sender (the autopilot's
//! system and component id from `[link]`). A frame refused at any step is counted by its cause
//! ([`Refusal`]) and never reaches [`crate::incoming`]: nobody else on the network steers the
//! vehicle attitude, the clock or the reply address. The signature itself is the mavlink crate's
//! (`SigningData`); this module decides what to do with its verdict and names the cause.

use crate::config::LinkConfig;
use crate::dialect::MavMessage;
use crate::signing::{SignatureFault, Signing};
use mavlink::consts::{self, v2};
use mavlink::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavHeader, MavlinkVersion, Message};
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;

const STX_V1: u8 = 0xFE;
const STX_V2: u8 = 0xFD;
/// STX, the length and the incompatibility flags: enough to know a MAVLink 2 frame's size.
const V2_PREFIX: usize = 3;

/// Why a received frame was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Refusal {
    /// Cut short, or flags this implementation does not know.
    Malformed,
    /// The checksum does not match the bytes.
    BadCrc,
    /// MAVLink 1 (cannot be signed; deckwatch speaks MAVLink 2 only).
    Mavlink1,
    /// A message id outside the common dialect.
    Unknown,
    /// Not signed, while signing is required.
    Unsigned,
    /// Signed with another key (or altered).
    BadSignature,
    /// Correctly signed but not newer than the last frame of its stream: a replay, or a new
    /// stream more than a minute older than the newest time seen (the specification's rule).
    Replay,
    /// Not the autopilot named in `[link]`.
    WrongSender,
    /// Beyond its sender's share (`[link] sender_rate_hz`), dropped before any other check.
    RateLimited,
}

deckwatch_common::named_enum!(
    Refusal,
    [
        Malformed => "malformed",
        BadCrc => "bad-crc",
        Mavlink1 => "mavlink1",
        Unknown => "unknown-message",
        Unsigned => "unsigned",
        BadSignature => "bad-signature",
        Replay => "replay",
        WrongSender => "wrong-sender",
        RateLimited => "rate-limited",
    ]
);

/// Refused frames, by cause.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RefusalCounts([u64; Refusal::ALL.len()]);

impl RefusalCounts {
    pub fn add(&mut self, r: Refusal) {
        self.0[r as usize] += 1;
    }

    pub fn get(&self, r: Refusal) -> u64 {
        self.0[r as usize]
    }

    pub fn total(&self) -> u64 {
        self.0.iter().sum()
    }

    /// What was refused since `earlier`.
    pub fn since(&self, earlier: &RefusalCounts) -> RefusalCounts {
        RefusalCounts(std::array::from_fn(|k| self.0[k].saturating_sub(earlier.0[k])))
    }

    /// `unsigned 12, bad-signature 3` (causes with none left out); `none` when empty.
    pub fn describe(&self) -> String {
        let parts: Vec<String> = Refusal::ALL
            .iter()
            .filter(|r| self.get(**r) > 0)
            .map(|r| format!("{} {}", r.name(), self.get(*r)))
            .collect();
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join(", ")
        }
    }
}

/// A frame that passed every check.
#[derive(Debug, Clone)]
pub struct Admitted {
    pub header: MavHeader,
    pub message: MavMessage,
    /// The frame as received (with its signature, if any), for the recorder.
    pub frame: FrameBytes,
}

/// One sender's token bucket: `rate_hz` frames a second, bursts of a quarter second.
#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    last_ns: u64,
}

/// Frames a second for each source address; an unknown sender past `MAX_SENDERS` shares one
/// bucket with the others like it (a flood from many ports cannot grow the table).
#[derive(Debug, Clone)]
struct RateLimit {
    rate_hz: f64,
    burst: f64,
    buckets: HashMap<Option<SocketAddr>, Bucket>,
}

const MAX_SENDERS: usize = 64;
/// The shared bucket's key: no address is `None` except a byte stream's single sender, which
/// is never over the table's size.
const OVERFLOW: Option<SocketAddr> = Some(SocketAddr::V4(std::net::SocketAddrV4::new(
    std::net::Ipv4Addr::UNSPECIFIED,
    0,
)));

impl RateLimit {
    fn new(rate_hz: f64) -> Self {
        Self {
            rate_hz,
            burst: (rate_hz / 4.0).max(1.0),
            buckets: HashMap::new(),
        }
    }

    /// Takes one frame's token from `sender` at `now_ns`; false: over its rate.
    fn take(&mut self, sender: Option<SocketAddr>, now_ns: u64) -> bool {
        if self.rate_hz <= 0.0 {
            return true;
        }
        let key = if self.buckets.contains_key(&sender) || self.buckets.len() < MAX_SENDERS {
            sender
        } else {
            // Forget senders silent for 10 s before sending this one to the shared bucket.
            self.buckets
                .retain(|_, b| now_ns.saturating_sub(b.last_ns) < 10_000_000_000);
            if self.buckets.len() < MAX_SENDERS {
                sender
            } else {
                OVERFLOW
            }
        };
        let (rate, burst) = (self.rate_hz, self.burst);
        let b = self.buckets.entry(key).or_insert(Bucket {
            tokens: burst,
            last_ns: now_ns,
        });
        let dt_s = now_ns.saturating_sub(b.last_ns) as f64 / 1e9;
        b.tokens = (b.tokens + dt_s * rate).min(burst);
        b.last_ns = now_ns.max(b.last_ns);
        if b.tokens >= 1.0 {
            b.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

/// Admitted frames an address must send before replies go to it on a listening UDP socket.
pub const FRAMES_TO_TAKE_REPLIES: u8 = 3;
/// Addresses counted at once while the reply address is chosen.
const MAX_ADDRESSES_CHOOSING: usize = 4;

/// The receiving checks of one link, and its reply address.
pub struct Admission {
    signing: Option<Arc<Signing>>,
    autopilot: (u32, u8),
    limit: RateLimit,
    /// A byte stream's bytes not yet a whole frame.
    pending: Vec<u8>,
    /// Where replies go on a listening UDP socket: the autopilot's address, the first to send
    /// [`FRAMES_TO_TAKE_REPLIES`] admitted frames; it moves only once it has been silent for the
    /// heartbeat timeout (a restarted router's new port), never with a frame from elsewhere
    /// while it is heard.
    peer: Option<SocketAddr>,
    /// While no address holds the replies (at the start, or after the reply address fell
    /// silent): the admitted frames each address sent so far.
    choosing: Vec<(SocketAddr, u8)>,
    /// When the reply address last sent an admitted frame, and how long its silence may last
    /// before another address of the autopilot takes its place (`heartbeat_timeout_ms`).
    peer_heard_ns: Option<u64>,
    peer_timeout_ns: u64,
    pub refused: RefusalCounts,
    pub admitted: u64,
    /// Admitted frames that came from another address than the reply address while it was
    /// heard: authentic (signed and fresh, or unsigned on a trusted network) but relayed or
    /// sent from elsewhere. Their data is the autopilot's; the replies stay where they were.
    pub from_other_address: u64,
    /// The autopilot's frames that never arrived, from the gaps in its sequence numbers (one
    /// counter per sender in MAVLink): lost on the way, or in a full receive buffer.
    pub autopilot_lost: u64,
    last_sequence: Option<u8>,
}

impl Admission {
    /// `signing`: the link's signing (None: `signing = "off"`).
    pub fn new(config: &LinkConfig, signing: Option<Arc<Signing>>) -> Self {
        Self {
            signing,
            autopilot: (
                u32::from(config.autopilot_system_id),
                config.autopilot_component_id,
            ),
            limit: RateLimit::new(config.sender_rate_hz),
            pending: Vec::new(),
            peer: None,
            choosing: Vec::new(),
            peer_heard_ns: None,
            peer_timeout_ns: (config.heartbeat_timeout_ms * 1e6) as u64,
            refused: RefusalCounts::default(),
            admitted: 0,
            from_other_address: 0,
            autopilot_lost: 0,
            last_sequence: None,
        }
    }

    /// The address replies go to on a listening socket: the autopilot's, once it was heard.
    pub fn reply_address(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// An admitted frame from `sender`: where the replies go. The address that first sends
    /// [`FRAMES_TO_TAKE_REPLIES`] of the autopilot's frames takes them, not merely the first
    /// frame's: a relay or a second route that forwards some of its frames (authentic and
    /// fresh) may deliver the first one the link reads, and would otherwise hold the replies
    /// for the whole flight. Once taken, a frame from elsewhere while the address is heard
    /// does not move them (relayed, or replayed through another host); silent for the
    /// heartbeat timeout (a restarted router's new port), the choice starts again, the
    /// replies staying where they were until another address has sent enough.
    fn heard_from(&mut self, sender: SocketAddr, now_ns: u64) {
        if self.peer == Some(sender) {
            self.peer_heard_ns = Some(now_ns);
            self.choosing.clear();
            return;
        }
        let silent = self
            .peer_heard_ns
            .is_none_or(|t| now_ns.saturating_sub(t) > self.peer_timeout_ns);
        if !silent {
            self.from_other_address += 1;
            return;
        }
        let count = match self.choosing.iter().position(|(a, _)| *a == sender) {
            Some(k) => {
                self.choosing[k].1 += 1;
                self.choosing[k].1
            }
            // Only authentic frames are counted, so few addresses compete; beyond a handful a
            // newcomer waits until the choice is made.
            None if self.choosing.len() < MAX_ADDRESSES_CHOOSING => {
                self.choosing.push((sender, 1));
                1
            }
            None => 0,
        };
        if count >= FRAMES_TO_TAKE_REPLIES {
            self.peer = Some(sender);
            self.peer_heard_ns = Some(now_ns);
            self.choosing.clear();
        }
    }

    /// Every frame of one datagram from `sender` (UDP: a frame never spans two datagrams).
    pub fn datagram(&mut self, bytes: &[u8], sender: SocketAddr, now_ns: u64) -> Vec<Admitted> {
        let mut out = Vec::new();
        let mut at = 0;
        while at < bytes.len() {
            match self.next_frame(&bytes[at..], Some(sender), now_ns, &mut out) {
                Step::Consumed(n) => at += n,
                // A frame cut by the datagram's end, or a start marker inside other bytes whose
                // "length" runs past it: counted, and the rest still looked at.
                Step::Incomplete => {
                    self.refused.add(Refusal::Malformed);
                    at += 1;
                }
            }
        }
        out
    }

    /// Bytes from a stream (serial, TCP): the frames they complete; a frame's beginning waits
    /// for the rest.
    pub fn stream(&mut self, bytes: &[u8], now_ns: u64) -> Vec<Admitted> {
        let mut out = Vec::new();
        self.pending.extend_from_slice(bytes);
        let mut at = 0;
        while at < self.pending.len() {
            let rest = std::mem::take(&mut self.pending);
            let step = self.next_frame(&rest[at..], None, now_ns, &mut out);
            self.pending = rest;
            match step {
                Step::Consumed(n) => at += n,
                Step::Incomplete => break,
            }
        }
        self.pending.drain(..at);
        out
    }

    /// Looks at the bytes from a frame's possible start: skips junk up to the next start
    /// marker, or judges one whole frame. A candidate that turns out not to be a frame (a start
    /// marker inside other bytes) moves on by one byte, so the frames after it are still found.
    fn next_frame(
        &mut self,
        bytes: &[u8],
        sender: Option<SocketAddr>,
        now_ns: u64,
        out: &mut Vec<Admitted>,
    ) -> Step {
        match bytes[0] {
            STX_V2 => {}
            STX_V1 => {
                // STX, length, then 4 header bytes, the payload and the checksum.
                let Some(&len) = bytes.get(1) else {
                    return Step::Incomplete;
                };
                let size = 6 + usize::from(len) + consts::CHECKSUM_SIZE;
                if bytes.len() < size {
                    return Step::Incomplete;
                }
                let mut raw = MAVLinkV1MessageRaw::new();
                raw.as_mut_slice()[..size].copy_from_slice(&bytes[..size]);
                if !raw.has_valid_crc::<MavMessage>() {
                    // Not a MAVLink 1 frame after all: a byte of junk.
                    return Step::Consumed(1);
                }
                let refusal = if self.limit.take(sender, now_ns) {
                    Refusal::Mavlink1
                } else {
                    Refusal::RateLimited
                };
                self.refused.add(refusal);
                return Step::Consumed(size);
            }
            _ => {
                // Not a frame: up to the next start marker (junk is not a frame to count).
                let n = bytes[1..]
                    .iter()
                    .position(|b| *b == STX_V1 || *b == STX_V2)
                    .map_or(bytes.len(), |p| p + 1);
                return Step::Consumed(n);
            }
        }
        if bytes.len() < V2_PREFIX {
            return Step::Incomplete;
        }
        let flags = bytes[v2::INCOMPAT_FLAGS_OFFSET];
        if flags & !v2::SUPPORTED_IFLAGS != 0 {
            // An unknown incompatibility flag: the frame cannot be read; resynchronise.
            self.refused.add(Refusal::Malformed);
            return Step::Consumed(1);
        }
        let header = v2::MIN_HEADER_SIZE
            + if flags & v2::IFLAG_SYSID32 != 0 {
                v2::SYSID32_EXTRA_HEADER_SIZE
            } else {
                0
            };
        let signature = if flags & v2::IFLAG_SIGNED != 0 {
            v2::SIGNATURE_SIZE
        } else {
            0
        };
        let size = consts::STX_SIZE + header + usize::from(bytes[1]) + consts::CHECKSUM_SIZE + signature;
        if bytes.len() < size {
            return Step::Incomplete;
        }
        // Without signing, the rate limit comes first (nothing can be authenticated, and the
        // checks it spares cost more). With signing, the signature is checked first (a quarter
        // of a microsecond: BENCHMARKS) and only what is not the autopilot's authentic frames
        // is charged to its sender's share: a flood forged from the autopilot's address cannot
        // crowd its signed frames out.
        let signing = self.signing.is_some();
        if !signing && !self.limit.take(sender, now_ns) {
            self.refused.add(Refusal::RateLimited);
            return Step::Consumed(size);
        }
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.as_mut_slice()[..size].copy_from_slice(&bytes[..size]);
        let verdict = self.judge(&raw);
        match verdict.authentic_autopilot_sequence {
            Some(sequence) => self.count_sequence(sequence),
            None if signing && !self.limit.take(sender, now_ns) => {
                self.refused.add(Refusal::RateLimited);
                return Step::Consumed(size);
            }
            None => {}
        }
        match verdict.result {
            Ok(admitted) => {
                if let Some(s) = sender {
                    self.heard_from(s, now_ns);
                }
                self.admitted += 1;
                out.push(admitted);
                Step::Consumed(size)
            }
            // A bad checksum, or an id outside the dialect (whose checksum cannot be checked),
            // may be a start marker inside other bytes: look again one byte on.
            Err(r @ (Refusal::BadCrc | Refusal::Unknown)) => {
                self.refused.add(r);
                Step::Consumed(1)
            }
            Err(r) => {
                self.refused.add(r);
                Step::Consumed(size)
            }
        }
    }

    /// One authentic frame of the autopilot's numbered `sequence`: the frames missing before it
    /// are lost. A number behind the newest (a reordered or repeated frame) counts nothing and
    /// leaves the newest.
    fn count_sequence(&mut self, sequence: u8) {
        match self.last_sequence {
            Some(last) => {
                let gap = sequence.wrapping_sub(last).wrapping_sub(1);
                if gap < 128 {
                    self.autopilot_lost += u64::from(gap);
                    self.last_sequence = Some(sequence);
                }
            }
            None => self.last_sequence = Some(sequence),
        }
    }

    /// One whole MAVLink 2 frame: the signature first when signing (it covers any message, known
    /// or not; the replay check last, as it records the stream's newest timestamp, which only an
    /// authentic frame may move), then the message id, the checksum, the sender.
    fn judge(&self, raw: &MAVLinkV2MessageRaw) -> Verdict {
        let pinned = (raw.system_id(), raw.component_id()) == self.autopilot;
        let refuse = |r: Refusal, authentic: bool| Verdict {
            result: Err(r),
            authentic_autopilot_sequence: (authentic && pinned).then(|| raw.sequence()),
        };
        if let Some(signing) = &self.signing {
            match signing.verify(raw) {
                Ok(()) => {}
                Err(SignatureFault::Unsigned) => return refuse(Refusal::Unsigned, false),
                Err(SignatureFault::BadSignature) => return refuse(Refusal::BadSignature, false),
                Err(SignatureFault::Replay) => return refuse(Refusal::Replay, false),
            }
        }
        let signed = self.signing.is_some();
        let id = raw.message_id();
        if MavMessage::default_message_from_id(id).is_none() {
            return refuse(Refusal::Unknown, signed);
        }
        if !raw.has_valid_crc::<MavMessage>() {
            return refuse(Refusal::BadCrc, false);
        }
        if !pinned {
            return refuse(Refusal::WrongSender, false);
        }
        let result = MavMessage::parse(MavlinkVersion::V2, id, raw.payload())
            .map(|message| Admitted {
                header: MavHeader {
                    system_id: raw.system_id(),
                    component_id: raw.component_id(),
                    sequence: raw.sequence(),
                },
                message,
                frame: FrameBytes::of(raw.raw_bytes()),
            })
            .map_err(|_| Refusal::Malformed);
        Verdict {
            result,
            authentic_autopilot_sequence: Some(raw.sequence()),
        }
    }
}

/// What [`Admission::judge`] found: the frame or why not, and the autopilot's sequence number
/// when the frame is authentically the autopilot's (signed, or passing its checksum).
struct Verdict {
    result: Result<Admitted, Refusal>,
    authentic_autopilot_sequence: Option<u8>,
}

enum Step {
    Consumed(usize),
    Incomplete,
}

/// One MAVLink frame's bytes, held without an allocation (a frame is 283 bytes at most).
#[derive(Clone)]
pub struct FrameBytes {
    bytes: [u8; consts::MAX_FRAME_SIZE],
    len: usize,
}

impl FrameBytes {
    /// The first `MAX_FRAME_SIZE` bytes of `bytes`.
    fn of(bytes: &[u8]) -> Self {
        let mut out = Self {
            bytes: [0; consts::MAX_FRAME_SIZE],
            len: bytes.len().min(consts::MAX_FRAME_SIZE),
        };
        out.bytes[..out.len].copy_from_slice(&bytes[..out.len]);
        out
    }
}

impl std::ops::Deref for FrameBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
}

impl std::ops::DerefMut for FrameBytes {
    fn deref_mut(&mut self) -> &mut [u8] {
        &mut self.bytes[..self.len]
    }
}

impl PartialEq for FrameBytes {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for FrameBytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FrameBytes({:02x?})", &**self)
    }
}

/// A message as the bytes the link sends: MAVLink 2, signed when the link signs.
pub fn frame(header: MavHeader, message: &MavMessage, signing: Option<&Signing>) -> FrameBytes {
    let mut out = FrameBytes {
        bytes: [0; consts::MAX_FRAME_SIZE],
        len: 0,
    };
    let mut raw = MAVLinkV2MessageRaw::new();
    match signing {
        Some(s) => {
            raw.serialize_message_for_signing(header, message);
            s.sign(&mut raw);
        }
        None => raw.serialize_message(header, message),
    }
    let bytes = raw.raw_bytes();
    // A whole frame always fits its largest size.
    out.len = bytes.len().min(consts::MAX_FRAME_SIZE);
    out.bytes[..out.len].copy_from_slice(&bytes[..out.len]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SigningMode;
    use crate::dialect::{ATTITUDE_QUATERNION_DATA, HEARTBEAT_DATA};

    /// A key as random as any (`weakness` finds nothing in it).
    const KEY: [u8; 32] = [
        0x3c, 0x91, 0x5e, 0x07, 0xd2, 0x48, 0xaf, 0x16, 0x8b, 0xe4, 0x2d, 0x70, 0xc9, 0x35, 0x5a, 0xf1, 0x0e,
        0x67, 0xb8, 0x23, 0x9d, 0x44, 0xea, 0x1f, 0x86, 0x52, 0xcb, 0x39, 0x7e, 0xa0, 0x14, 0xdd,
    ];

    fn header(system_id: u32, component_id: u8) -> MavHeader {
        MavHeader {
            system_id,
            component_id,
            sequence: 0,
        }
    }

    fn attitude() -> MavMessage {
        MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: 10,
            q1: 1.0,
            ..Default::default()
        })
    }

    fn signed_config() -> LinkConfig {
        LinkConfig {
            signing: SigningMode::Required,
            signing_key_file: "unused-here".into(),
            ..LinkConfig::default()
        }
    }

    fn addr(port: u16) -> SocketAddr {
        ([127, 0, 0, 1], port).into()
    }

    #[test]
    fn with_signing_only_the_autopilots_fresh_signed_frames_pass_and_each_refusal_is_named() {
        let ours = Arc::new(Signing::new(KEY, 0));
        let mut a = Admission::new(&signed_config(), Some(ours));
        // The autopilot signs with the same key on its own side (its own timestamp state).
        let autopilot = Signing::new(KEY, 3);
        // A relay forwarding some of the autopilot's frames delivers the first one read.
        let relayed = frame(header(1, 1), &attitude(), Some(&autopilot));
        assert_eq!(a.datagram(&relayed, addr(5001), 0).len(), 1);
        assert_eq!(a.reply_address(), None, "one frame takes no replies");
        let good = frame(header(1, 1), &attitude(), Some(&autopilot));
        let got = a.datagram(&good, addr(5000), 0);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].frame, good, "the frame as received, signature included");
        for _ in 1..FRAMES_TO_TAKE_REPLIES {
            assert_eq!(a.reply_address(), None);
            let next = frame(header(1, 1), &attitude(), Some(&autopilot));
            assert_eq!(a.datagram(&next, addr(5000), 0).len(), 1);
        }
        // The address that sent the autopilot's frames first takes the replies, not the relay.
        assert_eq!(a.reply_address(), Some(addr(5000)));
        assert_eq!(a.from_other_address, 0, "counted only once an address holds them");

        let cases: [(Vec<u8>, Refusal); 5] = [
            (frame(header(1, 1), &attitude(), None).to_vec(), Refusal::Unsigned),
            (
                frame(header(1, 1), &attitude(), Some(&Signing::new([9; 32], 3))).to_vec(),
                Refusal::BadSignature,
            ),
            // The same bytes again: correctly signed, not newer than its stream's last.
            (good.to_vec(), Refusal::Replay),
            // Another system with the key (a second vehicle): not the pinned autopilot.
            (
                frame(header(2, 1), &attitude(), Some(&Signing::new(KEY, 4))).to_vec(),
                Refusal::WrongSender,
            ),
            (
                {
                    let mut v1 = Vec::new();
                    let _ = mavlink::write_v1_msg(&mut v1, header(1, 1), &attitude());
                    v1
                },
                Refusal::Mavlink1,
            ),
        ];
        for (bytes, cause) in cases {
            let before = a.refused;
            assert!(a.datagram(&bytes, addr(6000), 1_000).is_empty(), "{cause:?}");
            assert_eq!(
                a.refused.since(&before).get(cause),
                1,
                "{cause:?}: {}",
                a.refused.describe()
            );
            assert_eq!(a.refused.since(&before).total(), 1, "{cause:?}");
        }
        // None of them moved the reply address.
        assert_eq!(a.reply_address(), Some(addr(5000)));
        // A newer signed frame of the autopilot relayed through another host passes (its data
        // is authentic and fresh) but is counted and does not take the replies while the
        // autopilot's own address is heard.
        let next = frame(header(1, 1), &attitude(), Some(&autopilot));
        assert_eq!(a.datagram(&next, addr(5001), 2_000).len(), 1);
        assert_eq!(a.reply_address(), Some(addr(5000)));
        assert_eq!(a.from_other_address, 1);
        // Silent past the heartbeat timeout: the autopilot's new address takes the replies once
        // it has sent enough; until then they stay where they were.
        for k in 0..FRAMES_TO_TAKE_REPLIES {
            assert_eq!(a.reply_address(), Some(addr(5000)));
            let later = frame(header(1, 1), &attitude(), Some(&autopilot));
            let now_ns = 4_000_000_000 + u64::from(k) * 1_000;
            assert_eq!(a.datagram(&later, addr(5001), now_ns).len(), 1);
        }
        assert_eq!(a.reply_address(), Some(addr(5001)));
        assert_eq!(a.from_other_address, 1);
    }

    #[test]
    fn damaged_cut_unknown_and_junk_bytes_are_counted_not_believed() {
        let mut a = Admission::new(&LinkConfig::default(), None);
        let good = frame(header(1, 1), &attitude(), None);
        let mut bad_crc = good.clone();
        let last = bad_crc.len() - 1;
        bad_crc[last] ^= 0xFF;
        assert!(a.datagram(&bad_crc, addr(1), 0).is_empty());
        assert_eq!(a.refused.get(Refusal::BadCrc), 1);
        // A message id outside the dialect (ids are bytes 7..10).
        let mut unknown = good.clone();
        unknown[7..10].copy_from_slice(&[0x10, 0x27, 0x00]);
        assert!(a.datagram(&unknown, addr(1), 0).is_empty());
        assert_eq!(a.refused.get(Refusal::Unknown), 1);
        assert!(a.datagram(&good[..good.len() - 3], addr(1), 0).is_empty());
        assert_eq!(a.refused.get(Refusal::Malformed), 1);
        // Junk around two good frames in one datagram: both found, the junk is no frame.
        let mut mixed = vec![0x00, 0x42, 0x13];
        mixed.extend_from_slice(&good);
        mixed.extend_from_slice(&[0xAA; 7]);
        mixed.extend_from_slice(&good);
        assert_eq!(a.datagram(&mixed, addr(1), 0).len(), 2);
        assert_eq!(a.refused.total(), 3, "{}", a.refused.describe());
        // A stray MAVLink 1 start marker with a "length" (junk), then a good frame: still found.
        let mut stray = vec![0xFE, 0x05, 0x01];
        stray.extend_from_slice(&good);
        assert_eq!(a.datagram(&stray, addr(1), 0).len(), 1);
        assert_eq!(a.refused.get(Refusal::Mavlink1), 0, "junk is no MAVLink 1 frame");
        // A start marker whose length runs past the datagram, then a good frame: still found.
        let mut cut = vec![0xFD, 0xF0, 0x00];
        cut.extend_from_slice(&good);
        assert_eq!(a.datagram(&cut, addr(1), 0).len(), 1);
        // Without signing, the reply address is the autopilot's first and stays while it is
        // heard, whatever another address sends, a frame flagged as signed included.
        assert_eq!(a.reply_address(), Some(addr(1)));
        a.datagram(&good, addr(2), 1_000);
        let flagged = frame(header(1, 1), &attitude(), Some(&Signing::new([1; 32], 0)));
        a.datagram(&flagged, addr(3), 2_000);
        assert_eq!(a.reply_address(), Some(addr(1)));
        // Silent past the heartbeat timeout (3 s): the autopilot's new address (a restarted
        // router) takes its place once it has sent enough frames.
        for k in 0..u64::from(FRAMES_TO_TAKE_REPLIES) {
            assert_eq!(a.reply_address(), Some(addr(1)));
            a.datagram(&good, addr(2), 4_000_000_000 + k);
        }
        assert_eq!(a.reply_address(), Some(addr(2)));
    }

    #[test]
    fn a_forged_flood_from_the_autopilots_address_does_not_crowd_out_its_signed_frames() {
        let config = LinkConfig {
            sender_rate_hz: 1000.0,
            ..signed_config()
        };
        let mut a = Admission::new(&config, Some(Arc::new(Signing::new(KEY, 0))));
        let autopilot = Signing::new(KEY, 1);
        let forged = frame(header(1, 1), &attitude(), None);
        let mut admitted = 0;
        for k in 0..20_000u64 {
            let now = k * 50_000;
            a.datagram(&forged, addr(14550), now);
            if k % 200 == 0 {
                let mut h = header(1, 1);
                h.sequence = (k / 200) as u8;
                admitted += a
                    .datagram(&frame(h, &attitude(), Some(&autopilot)), addr(14550), now)
                    .len();
            }
        }
        assert_eq!(admitted, 100);
        assert_eq!(a.autopilot_lost, 0);
        assert!(
            a.refused.get(Refusal::RateLimited) > 18_000,
            "{}",
            a.refused.describe()
        );
    }

    #[test]
    fn a_stream_keeps_a_frame_cut_between_reads() {
        let mut a = Admission::new(&LinkConfig::default(), None);
        let hb = frame(
            header(1, 1),
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
            None,
        );
        let mut bytes = hb.to_vec();
        bytes.extend_from_slice(&frame(header(1, 1), &attitude(), None));
        let (x, y) = bytes.split_at(hb.len() + 5);
        assert_eq!(a.stream(x, 0).len(), 1);
        let got = a.stream(y, 0);
        assert_eq!(got.len(), 1);
        assert!(matches!(got[0].message, MavMessage::ATTITUDE_QUATERNION(_)));
        assert_eq!(a.refused.total(), 0);
        // Sequence numbers 0 and 0 (frame() in this test numbers nothing): a repeat, not a loss;
        // a jump from 0 to 5 is four frames lost.
        let mut h = header(1, 1);
        h.sequence = 5;
        a.stream(&frame(h, &attitude(), None), 0);
        assert_eq!(a.autopilot_lost, 4);
    }

    #[test]
    fn a_flooding_sender_gets_its_share_and_the_autopilot_keeps_its_own() {
        let config = LinkConfig {
            sender_rate_hz: 1000.0,
            ..LinkConfig::default()
        };
        let mut a = Admission::new(&config, None);
        let spoof = frame(header(1, 1), &attitude(), None);
        let real = frame(header(1, 1), &attitude(), None);
        // One second: the flooder sends 20 000 frames, the autopilot 100.
        let (mut real_in, mut spoof_in) = (0, 0);
        for k in 0..20_000u64 {
            let now = k * 50_000;
            spoof_in += a.datagram(&spoof, addr(9999), now).len();
            if k % 200 == 0 {
                real_in += a.datagram(&real, addr(14550), now).len();
            }
        }
        assert_eq!(real_in, 100, "every autopilot frame passed");
        assert_eq!(
            a.autopilot_lost, 0,
            "(both senders' frames here carry sequence 0)"
        );
        // A quarter second of burst and a second at the rate.
        assert!((1000..=1300).contains(&spoof_in), "{spoof_in}");
        assert_eq!(a.refused.get(Refusal::RateLimited), 20_000 - spoof_in as u64);
        // Many senders cannot grow the table past its size.
        for port in 0..1000 {
            a.datagram(&spoof, addr(20_000 + port), 2_000_000_000);
        }
        assert!(a.limit.buckets.len() <= MAX_SENDERS + 1);
    }
}
