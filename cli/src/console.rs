//! The command line's own output: lines to stdout and stderr that never panic.
//!
//! `println!` panics when its stream is gone (`deckwatch run | head -1`, a terminal closed, a
//! supervisor's log pipe shut). A launcher that panics there ends the pipeline mid-run (its
//! stages follow it), and a stage's stderr reader that panics stops draining the stage's pipe
//! until the stage blocks on it. What a command says is for people; a reader that
//! went away is no fault of the run, so a failed write is dropped. Report commands end instead
//! (`main::end_with_a_closed_pipe`): their output is the whole point.

/// Like `println!`, but a closed or failing stdout drops the line.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// Like `print!`, but a closed or failing stdout drops the text.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// Like `eprintln!`, but a closed or failing stderr drops the line.
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}
