//! Where the pipeline keeps its run folders and iceoryx2 its service, node and event files: a
//! folder no other user can enter, make first or replace.
//!
//! iceoryx2's own default, `/tmp/iceoryx2`, is shared by every user of the machine: whoever makes
//! it first owns it, and could then refuse the pipeline its services or swap their files. Here it
//! is `dw-ipc/` in the service's runtime directory (systemd's `RuntimeDirectory=`, mode 0700), or
//! in the user's (`XDG_RUNTIME_DIR`, 0700 by the login manager), or, without either,
//! `dw-ipc-UID/` in the temporary folder; in every case a folder this user made, mode 0700, and
//! refused otherwise. The shared-memory segments stay in `/dev/shm`, created 0600 by iceoryx2, but
//! for one: its node counter (`…_node.<version>.global_mgmt`), which iceoryx2 opens to every user
//! (mode 0666) so that users can share a domain. A deckwatch domain is one user's: the counter is
//! closed to others once made ([`close_shared_counters`]), and one another user made first is
//! refused.

use crate::bus::BusError;
use deckwatch_common::InvalidField;
use std::path::{Path, PathBuf};

/// The folder run folders and the iceoryx2 root go in: the service's runtime directory, else the
/// user's, else the temporary folder.
pub fn runtime_base() -> PathBuf {
    ["RUNTIME_DIRECTORY", "XDG_RUNTIME_DIR"]
        .iter()
        .filter_map(std::env::var_os)
        .map(PathBuf::from)
        .find(|p| p.is_absolute() && p.is_dir())
        .unwrap_or_else(std::env::temp_dir)
}

/// The iceoryx2 root under [`runtime_base`] (not made or checked: see [`ipc_root`]).
pub fn ipc_root_path() -> PathBuf {
    let base = runtime_base();
    if base == std::env::temp_dir() {
        // SAFETY: geteuid has no preconditions and cannot fail.
        base.join(format!("dw-ipc-{}", unsafe { libc::geteuid() }))
    } else {
        base.join("dw-ipc")
    }
}

/// A Unix socket's path holds 107 bytes; an iceoryx2 event socket is the root, the domain's
/// prefix (`iox2_dw_` and the domain and `_`), up to 39 digits and `.event`.
const SOCKET_PATH_BYTES: usize = 107;
const EVENT_NAME_BYTES_BESIDES_DOMAIN: usize = 8 + 1 + 39 + 6;

/// The iceoryx2 root for `domain`, made (mode 0700) when missing and checked: a folder, not a
/// link, this user's, open to nobody else. The error names the folder and what is wrong.
pub fn ipc_root(domain: &str) -> Result<PathBuf, BusError> {
    let root = ipc_root_path();
    let refuse = |problem: String| {
        BusError::Settings(InvalidField::new(
            "domain",
            format!("iceoryx2 root {}: {problem}", root.display()),
        ))
    };
    let longest = root.as_os_str().len() + 1 + EVENT_NAME_BYTES_BESIDES_DOMAIN + domain.len();
    if longest > SOCKET_PATH_BYTES {
        return Err(refuse(format!(
            "with the domain `{domain}` an event socket's path could be {longest} bytes, more than a Unix socket takes ({SOCKET_PATH_BYTES}): shorten the domain, or XDG_RUNTIME_DIR"
        )));
    }
    {
        use std::os::unix::fs::DirBuilderExt;
        match std::fs::DirBuilder::new().mode(0o700).create(&root) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(refuse(format!("cannot be made: {e}"))),
        }
    }
    check_private_folder(&root).map_err(refuse)?;
    Ok(root)
}

/// Where iceoryx2's shared-memory segments are (POSIX `shm_open` on Linux).
pub const SHARED_MEMORY_DIR: &str = "/dev/shm";

/// Closes the domain's shared node counters to other users (mode 0600); refuses one that another
/// user made first (it could hand out node ids to our stages at will).
pub fn close_shared_counters(domain: &str) -> Result<(), BusError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let prefix = crate::bus::domain_prefix(domain);
    // SAFETY: geteuid has no preconditions and cannot fail.
    let us = unsafe { libc::geteuid() };
    let Ok(entries) = std::fs::read_dir(SHARED_MEMORY_DIR) else {
        return Ok(());
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if !(name.starts_with(&prefix) && name.ends_with(".global_mgmt")) {
            continue;
        }
        let path = e.path();
        let refuse = |problem: String| {
            BusError::Settings(InvalidField::new(
                "domain",
                format!("shared memory {}: {problem}", path.display()),
            ))
        };
        let meta = std::fs::symlink_metadata(&path).map_err(|e| refuse(e.to_string()))?;
        if meta.uid() != us {
            return Err(refuse(format!(
                "owned by uid {}, not by this user (uid {us}): another user made it first; remove it (as root) or use another domain",
                meta.uid()
            )));
        }
        if meta.mode() & 0o077 != 0 {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600))
                .map_err(|e| refuse(format!("closing it to others: {e}")))?;
        }
    }
    Ok(())
}

/// A folder (not a link to one), owned by this user, with no permission for anyone else.
fn check_private_folder(path: &Path) -> Result<(), String> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::symlink_metadata(path).map_err(|e| e.to_string())?;
    // SAFETY: geteuid has no preconditions and cannot fail.
    let us = unsafe { libc::geteuid() };
    if !meta.is_dir() {
        return Err("not a folder (a link, or a file another user put there?): remove it".into());
    }
    if meta.uid() != us {
        return Err(format!(
            "owned by uid {}, not by this user (uid {us}): another user made it first; remove it, or set XDG_RUNTIME_DIR",
            meta.uid()
        ));
    }
    if meta.mode() & 0o077 != 0 {
        return Err(format!(
            "open to others (mode {:o}): `chmod 700` it",
            meta.mode() & 0o7777
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_private_folder_of_ours_is_a_root() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let ok = dir.path().join("ok");
        std::fs::create_dir(&ok).unwrap();
        std::fs::set_permissions(&ok, std::fs::Permissions::from_mode(0o700)).unwrap();
        assert_eq!(check_private_folder(&ok), Ok(()));
        std::fs::set_permissions(&ok, std::fs::Permissions::from_mode(0o777)).unwrap();
        assert!(check_private_folder(&ok).unwrap_err().contains("mode 777"));
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&ok, &link).unwrap();
        assert!(check_private_folder(&link).unwrap_err().contains("not a folder"));
    }
}
