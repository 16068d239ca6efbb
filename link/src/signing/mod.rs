//! MAVLink 2 signing (a shared 32-byte key, SHA-256, and a 48-bit timestamp in 10 us units
//! since 2015-01-01 UTC that must grow in every stream), with its state kept across restarts.
//!
//! The signature itself is the mavlink crate's (`calculate_signature`); the timestamps are kept
//! here because the crate holds them in memory only: a restarted link would otherwise believe any
//! authentic frame captured in the minute before the restart (the specification's window for a
//! new stream), and, on a board whose clock is not set yet, any frame ever captured.

mod kept;
mod key;

pub use kept::{KeptState, StateError, MAX_STATE_BYTES, MAX_STREAMS};
pub use key::{load_key, owner_only, weakness, KeyError, NotOwnerOnly};

use crate::config::{LinkConfig, SigningMode};
use mavlink::consts::v2;
use mavlink::MAVLinkV2MessageRaw;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// One signed stream: link id, system id, component id (the specification's tuple).
pub type StreamId = (u8, u32, u8);

/// A new stream may start at most this much before the newest time seen (the specification's
/// one minute, in 10 us units).
const NEW_STREAM_WINDOW_10US: u64 = 60 * 100_000;
/// The state is written at most this often while it changes (the specification asks for at
/// least once a minute); after a stop that could not write it (a crash, a power cut), every
/// kept timestamp is taken to be this much newer, so that no frame of the unwritten interval
/// passes (the cost: an autopilot restarted within the same second waits that second).
pub const KEEP_INTERVAL_NS: u64 = 1_000_000_000;
const KEEP_INTERVAL_10US: u64 = KEEP_INTERVAL_NS / 10_000;

/// Why an authentic-looking frame's signature was not believed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignatureFault {
    /// Not signed.
    Unsigned,
    /// Signed with another key, or altered.
    BadSignature,
    /// Correctly signed but not newer than its stream's newest (kept across restarts), or a new
    /// stream more than a minute older than the newest time seen.
    Replay,
}

#[derive(Debug, Default)]
struct State {
    newest_10us: u64,
    streams: HashMap<StreamId, u64>,
    /// Changed since the state file was last written.
    changed: bool,
    last_kept_ns: Option<u64>,
}

/// The signing shared by the receiving and the sending side of one link.
pub struct Signing {
    key: [u8; 32],
    link_id: u8,
    state: Mutex<State>,
    /// Where the state is kept (None: in memory only, for evaluations and tests).
    kept_file: Option<PathBuf>,
}

/// The time on this machine's clock in signing units; 0 when the clock is before 2015 (not
/// set), where the kept state alone orders the frames.
pub fn clock_10us() -> u64 {
    const EPOCH_2015_S: u64 = 1_420_070_400;
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| (d.as_micros() / 10) as u64)
        .unwrap_or(0)
        .saturating_sub(EPOCH_2015_S * 100_000)
}

impl Signing {
    /// Signing with nothing kept: a fresh state in memory.
    pub fn new(key: [u8; 32], link_id: u8) -> Self {
        Self {
            key,
            link_id,
            state: Mutex::new(State::default()),
            kept_file: None,
        }
    }

    /// Signing that starts from the state kept in `path` (if there is one) and keeps it there.
    /// A state written while the link ran (not at its stop) is taken one keep interval newer.
    pub fn kept_in(key: [u8; 32], link_id: u8, path: &Path) -> Result<Self, StateError> {
        let mut signing = Self::new(key, link_id);
        signing.kept_file = Some(path.to_path_buf());
        if let Some(k) = kept::read(path)? {
            let margin = if k.clean { 0 } else { KEEP_INTERVAL_10US };
            let state = signing.state.get_mut().unwrap_or_else(|p| p.into_inner());
            state.newest_10us = k.newest_10us + margin;
            state.streams = k.streams.into_iter().map(|(s, t)| (s, t + margin)).collect();
        }
        Ok(signing)
    }

    /// The `[link]` signing: None with `signing = "off"`; otherwise the key, and the state kept
    /// in `signing_state_file` (or the default one, [`state_file`]).
    pub fn configured(config: &LinkConfig) -> Result<Option<Arc<Signing>>, SigningError> {
        match config.signing {
            SigningMode::Off => Ok(None),
            SigningMode::Required => {
                let key = load_key(Path::new(&config.signing_key_file))?;
                let path = state_file(config, &key)?;
                Ok(Some(Arc::new(Signing::kept_in(
                    key,
                    config.signing_link_id,
                    &path,
                )?)))
            }
        }
    }

    /// Where the state is kept, if anywhere.
    pub fn kept_file(&self) -> Option<&Path> {
        self.kept_file.as_deref()
    }

    /// The newest time seen or sent (10 us units since 2015), kept state included.
    pub fn newest_10us(&self) -> u64 {
        self.lock().newest_10us
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Checks a received frame: signed, with this key, and newer than its stream's newest;
    /// records its timestamp when it passes.
    pub fn verify(&self, raw: &MAVLinkV2MessageRaw) -> Result<(), SignatureFault> {
        self.verify_at(raw, clock_10us())
    }

    fn verify_at(&self, raw: &MAVLinkV2MessageRaw, now_10us: u64) -> Result<(), SignatureFault> {
        if raw.incompatibility_flags() & v2::IFLAG_SIGNED == 0 {
            return Err(SignatureFault::Unsigned);
        }
        let mut value = [0u8; v2::SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(&self.key, &mut value);
        if value != raw.signature_value() {
            return Err(SignatureFault::BadSignature);
        }
        let timestamp = raw.signature_timestamp();
        let stream = (raw.signature_link_id(), raw.system_id(), raw.component_id());
        let mut state = self.lock();
        state.newest_10us = state.newest_10us.max(now_10us);
        let fresh = match state.streams.get(&stream) {
            Some(&newest) => timestamp > newest,
            None => timestamp.saturating_add(NEW_STREAM_WINDOW_10US) >= state.newest_10us,
        };
        if !fresh {
            return Err(SignatureFault::Replay);
        }
        state.streams.insert(stream, timestamp);
        state.newest_10us = state.newest_10us.max(timestamp);
        state.changed = true;
        Ok(())
    }

    /// Signs a frame serialised for signing (`serialize_message_for_signing`): our link id, a
    /// timestamp newer than any seen or sent (kept state included), the signature.
    pub fn sign(&self, raw: &mut MAVLinkV2MessageRaw) {
        let mut state = self.lock();
        state.newest_10us = state.newest_10us.max(clock_10us());
        let timestamp = state.newest_10us.to_le_bytes();
        raw.signature_timestamp_bytes_mut()
            .copy_from_slice(&timestamp[..v2::SIGNATURE_TIMESTAMP_SIZE]);
        *raw.signature_link_id_mut() = self.link_id;
        let mut value = [0u8; v2::SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(&self.key, &mut value);
        raw.signature_value_mut().copy_from_slice(&value);
        state.newest_10us += 1;
        state.changed = true;
    }

    /// Writes the state when it changed and the last write is a keep interval old (`now_ns` on
    /// any monotonic clock); `stopping`: now, whatever the interval, marked as a clean stop.
    /// Ok(true) when it wrote.
    pub fn keep(&self, now_ns: u64, stopping: bool) -> Result<bool, StateError> {
        let Some(path) = &self.kept_file else {
            return Ok(false);
        };
        let snapshot = {
            let mut state = self.lock();
            let due = state
                .last_kept_ns
                .is_none_or(|t| now_ns.saturating_sub(t) >= KEEP_INTERVAL_NS);
            if !(stopping || (state.changed && due)) {
                return Ok(false);
            }
            state.changed = false;
            state.last_kept_ns = Some(now_ns);
            KeptState {
                newest_10us: state.newest_10us,
                streams: state.streams.iter().map(|(s, t)| (*s, *t)).collect(),
                clean: stopping,
            }
        };
        kept::write(path, &snapshot).map(|()| true)
    }
}

impl std::fmt::Debug for Signing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never the key.
        f.write_str("Signing { .. }")
    }
}

/// Why the link's signing could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum SigningError {
    #[error(transparent)]
    Key(#[from] KeyError),
    #[error(transparent)]
    State(#[from] StateError),
    #[error("link.signing_state_file: {0}")]
    NoStateFolder(String),
}

/// The file the signing state is kept in: `[link] signing_state_file`, or by default
/// `signing-KEYID.state` (KEYID: the first 8 bytes of the key's SHA-256, so that a new key
/// starts a new state and the name tells nothing of the key) in the service's state directory
/// (systemd's `StateDirectory=`, `$STATE_DIRECTORY`), else `$XDG_STATE_HOME/deckwatch`, else
/// `~/.local/state/deckwatch` (made, owner-only, when missing).
pub fn state_file(config: &LinkConfig, key: &[u8; 32]) -> Result<PathBuf, SigningError> {
    if !config.signing_state_file.is_empty() {
        return Ok(PathBuf::from(&config.signing_state_file));
    }
    let folder = if let Some(d) = std::env::var_os("STATE_DIRECTORY").filter(|d| !d.is_empty()) {
        // systemd may list several, colon-separated: the first is ours.
        let d = d
            .to_string_lossy()
            .split(':')
            .next()
            .unwrap_or_default()
            .to_string();
        PathBuf::from(d)
    } else if let Some(d) = std::env::var_os("XDG_STATE_HOME").filter(|d| !d.is_empty()) {
        PathBuf::from(d).join("deckwatch")
    } else if let Some(h) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
        PathBuf::from(h).join(".local/state/deckwatch")
    } else {
        return Err(SigningError::NoStateFolder(
            "empty, and neither STATE_DIRECTORY, XDG_STATE_HOME nor HOME is set: name the file".into(),
        ));
    };
    {
        use std::os::unix::fs::DirBuilderExt;
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(&folder)
            .map_err(|e| SigningError::NoStateFolder(format!("making {}: {e}", folder.display())))?;
    }
    use sha2::Digest;
    let digest = sha2::Sha256::digest(key);
    let id: String = digest[..8].iter().map(|b| format!("{b:02x}")).collect();
    Ok(folder.join(format!("signing-{id}.state")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{MavMessage, ATTITUDE_QUATERNION_DATA};
    use mavlink::MavHeader;

    const KEY: [u8; 32] = [
        0x3c, 0x91, 0x5e, 0x07, 0xd2, 0x48, 0xaf, 0x16, 0x8b, 0xe4, 0x2d, 0x70, 0xc9, 0x35, 0x5a, 0xf1, 0x0e,
        0x67, 0xb8, 0x23, 0x9d, 0x44, 0xea, 0x1f, 0x86, 0x52, 0xcb, 0x39, 0x7e, 0xa0, 0x14, 0xdd,
    ];

    /// The autopilot's signed attitude, as its own signing makes it.
    fn signed(by: &Signing) -> MAVLinkV2MessageRaw {
        let mut raw = MAVLinkV2MessageRaw::new();
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 0,
        };
        let m = MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            q1: 1.0,
            ..Default::default()
        });
        raw.serialize_message_for_signing(header, &m);
        by.sign(&mut raw);
        raw
    }

    #[test]
    fn a_frame_captured_before_a_restart_is_refused_after_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("signing.state");
        let autopilot = Signing::new(KEY, 3);
        let captured: Vec<_> = (0..5).map(|_| signed(&autopilot)).collect();
        let link = Signing::kept_in(KEY, 0, &path).unwrap();
        // The last three reach the link before its stop; the first two were captured earlier.
        for raw in &captured[2..] {
            assert_eq!(link.verify(raw), Ok(()));
        }
        assert!(link.keep(0, true).unwrap());
        // Without the kept state (the attack): every captured frame is a new stream's, within
        // the minute, and believed.
        let forgetful = Signing::new(KEY, 0);
        assert_eq!(forgetful.verify(&captured[0]), Ok(()));
        // With it: refused, all of them; the autopilot's next frame passes.
        let restarted = Signing::kept_in(KEY, 0, &path).unwrap();
        for raw in &captured {
            assert_eq!(restarted.verify(raw), Err(SignatureFault::Replay));
        }
        assert_eq!(restarted.verify(&signed(&autopilot)), Ok(()));
    }

    /// A board whose clock is not set (0 here, as before 2015) still refuses what is older than
    /// the kept state, and signs newer than anything it sent before.
    #[test]
    fn without_a_set_clock_the_kept_state_orders_the_frames() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("signing.state");
        let autopilot = Signing::new(KEY, 3);
        let old = signed(&autopilot);
        let link = Signing::kept_in(KEY, 0, &path).unwrap();
        let mut ours = MAVLinkV2MessageRaw::new();
        ours.serialize_message_for_signing(MavHeader::default(), &MavMessage::HEARTBEAT(Default::default()));
        link.sign(&mut ours);
        link.keep(0, true).unwrap();
        let restarted = Signing::kept_in(KEY, 0, &path).unwrap();
        // A new stream (another link id of the autopilot) from long before: refused at clock 0.
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message_for_signing(MavHeader::default(), &MavMessage::HEARTBEAT(Default::default()));
        *raw.signature_link_id_mut() = 9;
        // Stamped an hour before the kept newest.
        let stamp = (restarted.newest_10us() - 3600 * 100_000).to_le_bytes();
        raw.signature_timestamp_bytes_mut().copy_from_slice(&stamp[..6]);
        let mut value = [0u8; 6];
        raw.calculate_signature(&KEY, &mut value);
        raw.signature_value_mut().copy_from_slice(&value);
        assert_eq!(restarted.verify_at(&raw, 0), Err(SignatureFault::Replay));
        assert_eq!(
            restarted.verify_at(&old, 0),
            Ok(()),
            "the autopilot's stream was not seen before"
        );
        // Our next frame is newer than the one before the restart.
        let mut next = MAVLinkV2MessageRaw::new();
        next.serialize_message_for_signing(MavHeader::default(), &MavMessage::HEARTBEAT(Default::default()));
        restarted.sign(&mut next);
        assert!(next.signature_timestamp() > ours.signature_timestamp());
    }

    #[test]
    fn after_a_crash_the_kept_timestamps_are_taken_one_interval_newer() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("signing.state");
        let autopilot = Signing::new(KEY, 3);
        let link = Signing::kept_in(KEY, 0, &path).unwrap();
        let first = signed(&autopilot);
        link.verify(&first).unwrap();
        assert!(link.keep(5, false).unwrap());
        // Frames after the last write, up to the crash: not kept, but within the interval.
        let unkept = signed(&autopilot);
        link.verify(&unkept).unwrap();
        assert!(!link.keep(6, false).unwrap(), "written at most once a second");
        let restarted = Signing::kept_in(KEY, 0, &path).unwrap();
        assert_eq!(restarted.verify(&unkept), Err(SignatureFault::Replay));
    }

    #[test]
    fn a_bad_signature_is_told_from_a_replay() {
        let link = Signing::new(KEY, 0);
        let other = Signing::new([7; 32], 3);
        assert_eq!(link.verify(&signed(&other)), Err(SignatureFault::BadSignature));
        let mut raw = signed(&Signing::new(KEY, 3));
        // A byte of the payload changed (STX, 9 header bytes, then the payload).
        raw.as_mut_slice()[10] ^= 1;
        assert_eq!(link.verify(&raw), Err(SignatureFault::BadSignature));
    }

    #[test]
    fn the_default_state_file_is_named_by_the_keys_digest() {
        let mut config = LinkConfig {
            signing_state_file: "/somewhere/s.state".into(),
            ..LinkConfig::default()
        };
        assert_eq!(
            state_file(&config, &KEY).unwrap(),
            PathBuf::from("/somewhere/s.state")
        );
        config.signing_state_file.clear();
        let name = state_file(&config, &KEY).unwrap();
        let file = name.file_name().unwrap().to_string_lossy().to_string();
        assert!(
            file.starts_with("signing-") && file.ends_with(".state") && file.len() == 30,
            "{file}"
        );
        assert_ne!(state_file(&config, &[8; 32]).unwrap(), name);
    }
}
