//! The command line's own output: lines to stdout and stderr that never panic.
//!
//! `println!` panics when its stream is gone (`deckwatch run | head -1`, a terminal closed, a
//! supervisor's log pipe shut). A launcher that panics there ends the pipeline mid-run (its
//! stages follow it), and a stage's stderr reader that panics loses the stage's later lines (and
//! the recorder's copy of them). A reader that went away is no fault of the run: a line to a
//! closed pipe is dropped. Any other failure (a full disk under `--json > file`) is remembered
//! and fails the command at its end ([`lost_output`]): its output is incomplete. Report commands
//! end at once on a closed pipe instead (`main::end_with_a_closed_pipe`).

use std::sync::OnceLock;

/// The first write that failed for another reason than a closed pipe.
static LOST_OUTPUT: OnceLock<String> = OnceLock::new();

/// Takes a write's outcome: a closed pipe is no failure; any other error is remembered.
pub fn settle(written: std::io::Result<()>) {
    if let Err(e) = written {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            let _ = LOST_OUTPUT.set(e.to_string());
        }
    }
}

/// Flushes stdout; then why some output was lost, if any was (not to a closed pipe).
pub fn lost_output() -> Option<&'static str> {
    use std::io::Write as _;
    settle(std::io::stdout().flush());
    LOST_OUTPUT.get().map(String::as_str)
}

/// Like `println!`, but a closed stdout drops the line ([`settle`]).
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        $crate::console::settle(writeln!(std::io::stdout().lock(), $($arg)*));
    }};
}

/// Like `print!`, but a closed stdout drops the text ([`settle`]).
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        $crate::console::settle(write!(std::io::stdout().lock(), $($arg)*));
    }};
}

/// Like `eprintln!`, but a closed stderr drops the line ([`settle`]).
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        $crate::console::settle(writeln!(std::io::stderr().lock(), $($arg)*));
    }};
}
