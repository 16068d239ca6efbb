//! A process's lines on stderr that can never stall it.
//!
//! The launcher reads its stages' stderr through a pipe when it forwards their lines to the
//! flight recorder. If the launcher is stopped (SIGSTOP, a debugger, a swapped-out process), a
//! blocking write would stop the stage as soon as the pipe's 64 KiB fill: the launcher only
//! watches, and must never be able to stall the pipeline. So the launcher makes the writing end
//! of that pipe non-blocking, and every line goes through [`line`]: a line that does not fit is
//! dropped and counted, and the count is said with the next line that fits. (`eprintln!` would
//! panic on a full non-blocking pipe.)

use std::fmt;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::sync::atomic::{AtomicU64, Ordering};

/// Lines dropped since the last line that fitted.
static PENDING_DROPS: AtomicU64 = AtomicU64::new(0);
/// Lines dropped in this process's life.
static TOTAL_DROPS: AtomicU64 = AtomicU64::new(0);

/// POSIX: a pipe write of at most this many bytes is all or nothing.
const ATOMIC_WRITE_BYTES: usize = 4096;

/// Writes `args` and a newline to stderr in one write; drops (and counts) the line if stderr
/// would block or fails. Longer lines are cut to one atomic pipe write.
pub fn line(args: fmt::Arguments<'_>) {
    let pending = PENDING_DROPS.load(Ordering::Relaxed);
    if pending > 0 {
        let note = format!("({pending} stderr lines dropped: stderr was full)\n");
        if write_whole(note.as_bytes()) {
            PENDING_DROPS.fetch_sub(pending, Ordering::Relaxed);
        }
    }
    let mut text = args.to_string();
    if text.len() >= ATOMIC_WRITE_BYTES {
        let mut cut = ATOMIC_WRITE_BYTES - 4;
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        text.truncate(cut);
        text.push_str("...");
    }
    text.push('\n');
    if !write_whole(text.as_bytes()) {
        PENDING_DROPS.fetch_add(1, Ordering::Relaxed);
        TOTAL_DROPS.fetch_add(1, Ordering::Relaxed);
    }
}

/// The lines [`line`] dropped in this process's life.
pub fn dropped_lines() -> u64 {
    TOTAL_DROPS.load(Ordering::Relaxed)
}

/// A pipe for a child process's stderr: the writing end (for the child, through
/// `Stdio::from`) is non-blocking, so that a child writing through [`line`] never waits for the
/// reader; the reading end blocks (for the thread that reads it). Both close on exec; the child
/// gets its copy as fd 2.
pub fn stderr_pipe() -> std::io::Result<(OwnedFd, OwnedFd)> {
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: pipe2 writes two new descriptors into `fds` when it returns 0.
    if unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: both descriptors are new and owned by nobody else.
    let (read, write) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
    // SAFETY: fcntl on a descriptor we own.
    let ok = unsafe {
        let flags = libc::fcntl(write.as_raw_fd(), libc::F_GETFL);
        flags >= 0 && libc::fcntl(write.as_raw_fd(), libc::F_SETFL, flags | libc::O_NONBLOCK) == 0
    };
    if !ok {
        return Err(std::io::Error::last_os_error());
    }
    Ok((read, write))
}

/// One write(2) of `bytes` (at most [`ATOMIC_WRITE_BYTES`]) to stderr, retried on EINTR.
fn write_whole(bytes: &[u8]) -> bool {
    use std::io::Write;
    let mut err = std::io::stderr().lock();
    loop {
        match err.write(bytes) {
            Ok(n) => return n == bytes.len(),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(_) => return false,
        }
    }
}

/// `eprintln!` that never blocks on, or panics over, a full stderr: see [`line`].
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::diag::line(format_args!($($arg)*))
    };
}

#[cfg(test)]
mod tests {
    const FLOOD_LINES: u64 = 50_000;

    /// A child writes 50 000 lines into a non-blocking pipe that nobody reads (a stopped
    /// launcher): it finishes, having dropped and counted what did not fit. With a blocking
    /// pipe the child would wait forever once the pipe's 64 KiB are full.
    #[test]
    fn a_full_pipe_costs_lines_never_a_stall() {
        if std::env::var_os("DECKWATCH_DIAG_FLOOD").is_some() {
            for i in 0..FLOOD_LINES {
                crate::say!("line {i} of a flood into a pipe nobody reads");
            }
            println!("dropped {}", super::dropped_lines());
            return;
        }
        let (read, write) = super::stderr_pipe().unwrap();
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .args([
                "--exact",
                "diag::tests::a_full_pipe_costs_lines_never_a_stall",
                "--nocapture",
            ])
            .env("DECKWATCH_DIAG_FLOOD", "1")
            .stderr(std::process::Stdio::from(write))
            .output()
            .unwrap();
        // Read only now: the child ran against a full pipe.
        let mut kept = String::new();
        std::io::Read::read_to_string(&mut std::fs::File::from(read), &mut kept).unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{stdout}");
        let dropped: u64 = stdout
            .lines()
            .find_map(|l| l.strip_prefix("dropped "))
            .and_then(|n| n.trim().parse().ok())
            .unwrap_or_else(|| panic!("no count in {stdout}"));
        let written = kept.lines().filter(|l| l.contains("of a flood")).count() as u64;
        assert!(dropped > 0, "a 64 KiB pipe cannot hold {FLOOD_LINES} lines");
        assert_eq!(written + dropped, FLOOD_LINES, "every line written or counted");
        // Whole lines only (each write is atomic).
        assert!(kept
            .lines()
            .all(|l| l.ends_with("nobody reads") || l.starts_with('(')));
    }

    #[test]
    fn a_long_line_is_cut_to_one_write() {
        let before = super::dropped_lines();
        super::line(format_args!("{}", "x".repeat(10_000)));
        assert_eq!(super::dropped_lines(), before);
    }
}
