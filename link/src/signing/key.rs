//! The MAVLink 2 signing key: read from a file only its owner can read, and refused when it is
//! guessable.

use std::path::{Path, PathBuf};

/// Why the signing key could not be used.
#[derive(Debug, thiserror::Error)]
pub enum KeyError {
    #[error("link.signing_key_file `{path}`: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("link.signing_key_file `{path}`: readable by others (mode {mode:o}); `chmod 600` it: a key others can read signs for them too")]
    NotPrivate { path: PathBuf, mode: u32 },
    #[error("link.signing_key_file `{path}`: owned by uid {owner}, not by this user (uid {us})")]
    NotOurs { path: PathBuf, owner: u32, us: u32 },
    #[error("link.signing_key_file `{path}`: {what}; it must hold the 32-byte key, raw or as 64 hexadecimal digits")]
    Format { path: PathBuf, what: String },
    #[error("link.signing_key_file `{path}`: a weak key: {what}; make a random one (`openssl rand -hex 32 > FILE`) and give the autopilot the same")]
    Weak { path: PathBuf, what: String },
}

/// The 32-byte signing key from `path`: owner-only (mode 0600 or stricter, owned by this user),
/// raw 32 bytes or 64 hexadecimal digits (a trailing newline allowed).
pub fn load_key(path: &Path) -> Result<[u8; 32], KeyError> {
    use deckwatch_common::files::{open_bounded, FileReadError};
    use std::io::Read;
    let read = |source| KeyError::Read {
        path: path.into(),
        source,
    };
    let bounded = |e: FileReadError| match e {
        FileReadError::Io { source, .. } => read(source),
        other => KeyError::Format {
            path: path.into(),
            what: other.problem(),
        },
    };
    // A key file is 64 bytes at most (hex and a newline); more is not a key. Checked and read
    // through one open file: the name cannot be swapped in between.
    let mut file = open_bounded(path, MAX_KEY_FILE_BYTES).map_err(bounded)?;
    let meta = file.metadata().map_err(read)?;
    owner_only(&meta).map_err(|why| match why {
        NotOwnerOnly::Mode(mode) => KeyError::NotPrivate {
            path: path.into(),
            mode,
        },
        NotOwnerOnly::Owner { owner, us } => KeyError::NotOurs {
            path: path.into(),
            owner,
            us,
        },
    })?;
    let mut bytes = Vec::with_capacity(80);
    file.read_to_end(&mut bytes)
        .map_err(|e| match deckwatch_common::files::bound_in(&e) {
            Some(b) => KeyError::Format {
                path: path.into(),
                what: b.problem(),
            },
            None => read(e),
        })?;
    let key = parse_key(&bytes).map_err(|what| KeyError::Format {
        path: path.into(),
        what,
    })?;
    match weakness(&key) {
        Some(what) => Err(KeyError::Weak {
            path: path.into(),
            what: what.into(),
        }),
        None => Ok(key),
    }
}

/// A key file holds 64 hex digits and a newline, or 32 raw bytes: anything this long is no key.
const MAX_KEY_FILE_BYTES: u64 = 4096;

/// Why a file is not this user's alone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum NotOwnerOnly {
    #[error("open to others (mode {0:o}); `chmod 600` it")]
    Mode(u32),
    #[error("owned by uid {owner}, not by this user (uid {us})")]
    Owner { owner: u32, us: u32 },
}

/// A file only its owner may read or write (mode 0600 or stricter), and that owner this user:
/// the key signs for whoever reads it, and the kept signing state reopens replays for whoever
/// rewrites it.
pub fn owner_only(meta: &std::fs::Metadata) -> Result<(), NotOwnerOnly> {
    use std::os::unix::fs::MetadataExt;
    if meta.mode() & 0o077 != 0 {
        return Err(NotOwnerOnly::Mode(meta.mode() & 0o7777));
    }
    // SAFETY: geteuid has no preconditions and cannot fail.
    let us = unsafe { libc::geteuid() };
    if meta.uid() != us {
        return Err(NotOwnerOnly::Owner {
            owner: meta.uid(),
            us,
        });
    }
    Ok(())
}

/// Fewer distinct bytes than this in 32 is no random key: 32 random bytes have about 30, and
/// fewer than 12 comes once in more than 10^20 keys.
const MIN_DISTINCT_KEY_BYTES: usize = 12;

/// Why `key` is guessable, if it is: one byte repeated (the all-zero key among them), a few
/// bytes repeated, or 32 printable characters (a passphrase written as the raw key: its
/// strength is the passphrase's, and PX4's and ArduPilot's tools hash a passphrase instead).
/// A random key is printable throughout once in 10^13.
pub fn weakness(key: &[u8; 32]) -> Option<&'static str> {
    let mut seen = [false; 256];
    for &b in key {
        seen[usize::from(b)] = true;
    }
    let distinct = seen.iter().filter(|&&s| s).count();
    if distinct == 1 {
        Some("every byte is the same (an all-zero key is the best known of these)")
    } else if distinct < MIN_DISTINCT_KEY_BYTES {
        Some("a few bytes repeated")
    } else if key.iter().all(|b| (0x20..0x7f).contains(b)) {
        Some("32 printable characters: a passphrase used as the raw key")
    } else {
        None
    }
}

fn parse_key(bytes: &[u8]) -> Result<[u8; 32], String> {
    if let Ok(raw) = <[u8; 32]>::try_from(bytes) {
        return Ok(raw);
    }
    let text = std::str::from_utf8(bytes)
        .map_err(|_| format!("{} bytes that are not text", bytes.len()))?
        .trim();
    if text.len() != 64 || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!(
            "{} bytes, not 32 raw bytes or 64 hex digits",
            bytes.len()
        ));
    }
    let mut key = [0u8; 32];
    for (k, pair) in text.as_bytes().chunks(2).enumerate() {
        // Two ASCII hex digits: always valid UTF-8 and a valid u8.
        let s = std::str::from_utf8(pair).unwrap_or("00");
        key[k] = u8::from_str_radix(s, 16).unwrap_or(0);
    }
    Ok(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A key as random as any (`weakness` finds nothing in it).
    const KEY: [u8; 32] = [
        0x3c, 0x91, 0x5e, 0x07, 0xd2, 0x48, 0xaf, 0x16, 0x8b, 0xe4, 0x2d, 0x70, 0xc9, 0x35, 0x5a, 0xf1, 0x0e,
        0x67, 0xb8, 0x23, 0x9d, 0x44, 0xea, 0x1f, 0x86, 0x52, 0xcb, 0x39, 0x7e, 0xa0, 0x14, 0xdd,
    ];

    #[test]
    fn the_key_file_must_be_ours_alone_and_32_bytes() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("key");
        std::fs::write(&path, KEY).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = load_key(&path).unwrap_err();
        assert!(matches!(e, KeyError::NotPrivate { mode: 0o644, .. }), "{e}");
        assert!(e.to_string().contains("link.signing_key_file"), "{e}");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
        assert!(matches!(
            load_key(&path),
            Err(KeyError::NotPrivate { mode: 0o640, .. })
        ));
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(load_key(&path).unwrap(), KEY);
        let hex: String = KEY.iter().map(|b| format!("{b:02x}")).collect();
        std::fs::write(&path, format!("{hex}\n")).unwrap();
        assert_eq!(load_key(&path).unwrap(), KEY);
        std::fs::write(&path, "secret").unwrap();
        assert!(matches!(load_key(&path), Err(KeyError::Format { .. })));
        assert!(matches!(
            load_key(&dir.path().join("missing")),
            Err(KeyError::Read { .. })
        ));
    }

    /// Keys anyone could guess are refused with why: the all-zero key, one byte repeated, a
    /// pattern of a few bytes, a 32-character passphrase written as the raw key (raw or hex).
    #[test]
    fn a_weak_key_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("key");
        let pattern: [u8; 32] = std::array::from_fn(|k| [0xde, 0xad, 0xbe, 0xef][k % 4]);
        let passphrase = *b"correct horse battery staple 123";
        for (key, why) in [
            ([0u8; 32], "every byte is the same"),
            ([0x5a; 32], "every byte is the same"),
            (pattern, "a few bytes repeated"),
            (passphrase, "passphrase"),
        ] {
            for text in [
                key.to_vec(),
                key.iter()
                    .map(|b| format!("{b:02x}"))
                    .collect::<String>()
                    .into_bytes(),
            ] {
                std::fs::write(&path, &text).unwrap();
                std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
                let e = load_key(&path).unwrap_err();
                assert!(
                    matches!(e, KeyError::Weak { .. }) && e.to_string().contains(why),
                    "{e}"
                );
                assert!(e.to_string().contains("link.signing_key_file"), "{e}");
            }
        }
        assert_eq!(weakness(&KEY), None);
    }
}
