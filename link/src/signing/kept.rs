//! The signing state kept across restarts: each stream's newest timestamp and the newest time
//! seen or sent, in a small text file the link rewrites (MAVLink's signing guide: the timestamp
//! is stored at least once a minute and a system starts from the larger of its clock and the
//! stored value). Without it a restarted link would take any frame captured in the minute before
//! as new, and on a board whose clock is not yet set (a Raspberry Pi before NTP) any frame ever
//! captured.
//!
//! ```text
//! # deckwatch MAVLink signing state (10 us since 2015-01-01 UTC); written by the link
//! version 1
//! clean 1
//! newest 372519083311
//! stream 0 1 1 372519080042
//! ```

use super::key::{owner_only, NotOwnerOnly};
use super::StreamId;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// A state file is a few hundred bytes; more is not ours.
pub const MAX_STATE_BYTES: u64 = 64 * 1024;
/// Streams kept (the newest ones): one per authentic sender and link id, a handful in practice.
pub const MAX_STREAMS: usize = 256;
const HEADER: &str = "# deckwatch MAVLink signing state (10 us since 2015-01-01 UTC); written by the link";
const VERSION: &str = "1";

/// What a state file says.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct KeptState {
    /// The newest timestamp seen or sent (10 us units since 2015-01-01 UTC).
    pub newest_10us: u64,
    /// Each stream's newest authentic timestamp.
    pub streams: BTreeMap<StreamId, u64>,
    /// Written when the link stopped (exact); otherwise written while it ran, up to one keep
    /// interval before it stopped.
    pub clean: bool,
}

/// Why the state file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum StateError {
    #[error("link.signing_state_file `{path}`: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("link.signing_state_file `{path}`: {why}; it must be this user's alone (the link writes it with mode 600)")]
    NotOwnerOnly { path: PathBuf, why: NotOwnerOnly },
    #[error("link.signing_state_file `{path}`: {bytes} bytes, more than the {MAX_STATE_BYTES} a state file can be")]
    TooLarge { path: PathBuf, bytes: u64 },
    #[error("link.signing_state_file `{path}` line {line}: {what}")]
    Format {
        path: PathBuf,
        line: usize,
        what: String,
    },
}

/// The kept state at `path`; None when there is none yet (the first start).
pub fn read(path: &Path) -> Result<Option<KeptState>, StateError> {
    use deckwatch_common::files::{bound_in, open_bounded, FileReadError};
    let io = |source| StateError::Io {
        path: path.into(),
        source,
    };
    let too_large = |bytes| StateError::TooLarge {
        path: path.into(),
        bytes,
    };
    let mut file = match open_bounded(path, MAX_STATE_BYTES) {
        Ok(f) => f,
        Err(FileReadError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            return Ok(None)
        }
        Err(FileReadError::Io { source, .. }) => return Err(io(source)),
        Err(FileReadError::TooLarge { size_bytes, .. }) => return Err(too_large(size_bytes)),
        Err(e) => {
            return Err(StateError::Format {
                path: path.into(),
                line: e.line().unwrap_or(0) as usize,
                what: e.problem(),
            })
        }
    };
    let meta = file.metadata().map_err(io)?;
    owner_only(&meta).map_err(|why| StateError::NotOwnerOnly {
        path: path.into(),
        why,
    })?;
    let mut text = String::new();
    file.read_to_string(&mut text).map_err(|e| match bound_in(&e) {
        Some(_) => too_large(MAX_STATE_BYTES + 1),
        None => io(e),
    })?;
    parse(&text).map(Some).map_err(|(line, what)| StateError::Format {
        path: path.into(),
        line,
        what,
    })
}

/// The state in `text`, or the line (from 1) that is wrong and why.
pub fn parse(text: &str) -> Result<KeptState, (usize, String)> {
    let mut state = KeptState::default();
    let (mut version, mut newest, mut clean) = (false, false, false);
    for (k, line) in text.lines().enumerate() {
        let n = k + 1;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        let number = |w: &str| -> Result<u64, (usize, String)> {
            w.parse::<u64>()
                .ok()
                .filter(|v| *v < 1 << 48)
                .ok_or((n, format!("`{w}` is no 48-bit timestamp")))
        };
        let byte = |w: &str| -> Result<u8, (usize, String)> {
            w.parse::<u8>()
                .map_err(|_| (n, format!("`{w}` is no id from 0 to 255")))
        };
        match words.as_slice() {
            ["version", v] if *v == VERSION => version = true,
            ["version", v] => return Err((n, format!("version {v}; this link reads version {VERSION}"))),
            ["clean", c @ ("0" | "1")] => {
                state.clean = *c == "1";
                clean = true;
            }
            ["newest", t] => {
                state.newest_10us = number(t)?;
                newest = true;
            }
            ["stream", link, system, component, t] => {
                if state.streams.len() >= MAX_STREAMS {
                    return Err((n, format!("more than {MAX_STREAMS} streams")));
                }
                let system = system
                    .parse::<u32>()
                    .map_err(|_| (n, format!("`{system}` is no system id")))?;
                state
                    .streams
                    .insert((byte(link)?, system, byte(component)?), number(t)?);
            }
            _ => {
                return Err((
                    n,
                    format!("`{line}` is not `version`, `clean`, `newest` or `stream`"),
                ))
            }
        }
    }
    let missing = [(version, "version"), (clean, "clean"), (newest, "newest")]
        .into_iter()
        .find(|(seen, _)| !seen);
    match missing {
        Some((_, what)) => Err((text.lines().count(), format!("no `{what}` line (a cut file?)"))),
        None => Ok(state),
    }
}

/// `state` as the file's text (the newest streams first when there are too many).
pub fn render(state: &KeptState) -> String {
    let mut out = format!(
        "{HEADER}\nversion {VERSION}\nclean {}\nnewest {}\n",
        u8::from(state.clean),
        state.newest_10us
    );
    let mut streams: Vec<_> = state.streams.iter().collect();
    streams.sort_by(|a, b| b.1.cmp(a.1));
    for ((link, system, component), t) in streams.into_iter().take(MAX_STREAMS) {
        out.push_str(&format!("stream {link} {system} {component} {t}\n"));
    }
    out
}

/// Writes `state` to `path` so that a power cut leaves the old file or the new one, never a
/// part: a private temporary file beside it, flushed to the disk, renamed over it, and the
/// folder flushed.
pub fn write(path: &Path, state: &KeptState) -> Result<(), StateError> {
    use std::os::unix::fs::OpenOptionsExt;
    let io = |source| StateError::Io {
        path: path.into(),
        source,
    };
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".new");
    let temporary = folder.join(name);
    // A temporary left by a power cut is ours to replace.
    let _ = std::fs::remove_file(&temporary);
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&temporary)
        .map_err(io)?;
    file.write_all(render(state).as_bytes()).map_err(io)?;
    file.sync_all().map_err(io)?;
    drop(file);
    std::fs::rename(&temporary, path).map_err(io)?;
    std::fs::File::open(folder).and_then(|d| d.sync_all()).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> KeptState {
        KeptState {
            newest_10us: 372_519_083_311,
            streams: [((0, 1, 1), 372_519_080_042), ((3, 255, 190), 7)].into(),
            clean: true,
        }
    }

    #[test]
    fn a_state_is_written_privately_and_read_back() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("signing.state");
        assert_eq!(read(&path).unwrap(), None, "no file: the first start");
        write(&path, &state()).unwrap();
        let meta = std::fs::metadata(&path).unwrap();
        assert_eq!(meta.permissions().mode() & 0o777, 0o600);
        assert_eq!(read(&path).unwrap(), Some(state()));
        // Rewritten in place, no temporary left.
        let mut s = state();
        s.clean = false;
        s.newest_10us += 5;
        write(&path, &s).unwrap();
        assert_eq!(read(&path).unwrap(), Some(s));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_file_others_may_write_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("signing.state");
        write(&path, &state()).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o666)).unwrap();
        let e = read(&path).unwrap_err();
        assert!(matches!(e, StateError::NotOwnerOnly { .. }), "{e}");
        assert!(e.to_string().contains("link.signing_state_file"), "{e}");
    }

    #[test]
    fn a_damaged_file_is_refused_naming_its_line() {
        let text = render(&state());
        for (bad, line, what) in [
            (
                text.replace("newest 372519083311", "newest 12x"),
                4,
                "no 48-bit timestamp",
            ),
            (
                text.replace("newest 372519083311", "newest 281474976710656"),
                4,
                "48-bit",
            ),
            (
                text.replace("stream 3 255 190 7", "stream 300 1 1 7"),
                6,
                "no id from 0 to 255",
            ),
            (text.replace("version 1", "version 2"), 2, "version 2"),
            (text.replace("clean 1\n", ""), 0, "no `clean` line"),
            (format!("{text}lorem ipsum\n"), 7, "`lorem ipsum`"),
        ] {
            let (n, why) = parse(&bad).unwrap_err();
            assert!(why.contains(what), "{why}");
            if line > 0 {
                assert_eq!(n, line, "{why}");
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big");
        {
            use std::os::unix::fs::OpenOptionsExt;
            let f = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .mode(0o600)
                .open(&path)
                .unwrap();
            f.set_len(MAX_STATE_BYTES + 1).unwrap();
        }
        assert!(matches!(read(&path), Err(StateError::TooLarge { .. })));
    }

    #[test]
    fn the_newest_streams_are_kept_when_there_are_too_many() {
        let mut s = KeptState::default();
        for k in 0..(MAX_STREAMS as u32 + 10) {
            s.streams.insert((0, k, 1), u64::from(k));
        }
        s.clean = true;
        let back = parse(&render(&s)).unwrap();
        assert_eq!(back.streams.len(), MAX_STREAMS);
        assert!(!back.streams.contains_key(&(0, 0, 1)));
        assert!(back.streams.contains_key(&(0, MAX_STREAMS as u32 + 9, 1)));
    }
}
