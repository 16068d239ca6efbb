//! Process control: starting a stage binary, signalling it, stopping every stage.

use deckwatch_common::messages::{monotonic_ns, StageLog};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// One stage's process, across restarts.
pub struct StageProcess {
    pub name: &'static str,
    binary: PathBuf,
    child: Option<Child>,
    /// When the current (or last) process started.
    pub started: Instant,
    /// Restarts so far.
    pub restarts: u32,
    /// Where its stderr lines go besides the launcher's stderr (to be published for the
    /// recorder); None: the stage writes to the launcher's stderr directly.
    pub log: Option<std::sync::mpsc::Sender<StageLog>>,
    /// The threads that follow its processes' stderr (each ends when its process has exited).
    stderr_readers: Vec<std::thread::JoinHandle<()>>,
}

/// What a status poll found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Poll {
    Running,
    /// The process exited (just now; it is no longer running).
    Exited(ExitStatus),
    /// No process (not started, or its exit was already reported).
    Absent,
}

impl StageProcess {
    pub fn new(name: &'static str, binary: PathBuf) -> Self {
        Self {
            name,
            binary,
            child: None,
            started: Instant::now(),
            restarts: 0,
            log: None,
            stderr_readers: Vec::new(),
        }
    }

    /// Starts the binary on the configuration file and domain; `restarted` tells it that it
    /// joins a running pipeline.
    pub fn spawn(&mut self, config: &Path, domain: &str) -> Result<u32, String> {
        let mut cmd = Command::new(&self.binary);
        cmd.arg("--config")
            .arg(config)
            .arg("--domain")
            .arg(domain)
            .stdin(Stdio::null());
        if self.restarts > 0 {
            cmd.arg("--restarted");
        }
        // Own process group: Ctrl-C reaches the launcher only, which stops the stages in order.
        cmd.process_group(0);
        // SAFETY: prctl and getppid are async-signal-safe; prctl makes the kernel send SIGTERM
        // to the stage if the launcher dies, so no stage outlives it. A launcher that died
        // before the prctl took effect is caught by the parent check (the stage is not started).
        let launcher = std::process::id() as libc::pid_t;
        unsafe {
            cmd.pre_exec(move || {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                if libc::getppid() != launcher {
                    return Err(std::io::Error::other("the launcher is gone"));
                }
                Ok(())
            });
        }
        // The stage writes into a non-blocking pipe (`deckwatch_common::diag`): a stopped
        // launcher costs it lines, never time.
        let mut stderr = None;
        if self.log.is_some() {
            let (read, write) = deckwatch_common::diag::stderr_pipe()
                .map_err(|e| format!("a pipe for {}'s stderr: {e}", self.name))?;
            cmd.stderr(Stdio::from(write));
            stderr = Some(std::fs::File::from(read));
        }
        let child = cmd
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", self.binary.display()))?;
        // The child's copy is all that keeps the pipe open for writing: end of file when it exits.
        drop(cmd);
        let pid = child.id();
        if let (Some(tx), Some(stderr)) = (self.log.clone(), stderr) {
            let name = format!("deckwatch-{}", self.name);
            // Passes every line on to the launcher's stderr, and to the recorder. Ends when the
            // process closes its stderr (it exited).
            let reader = std::thread::Builder::new()
                .name(format!("{}-stderr", self.name))
                .spawn(move || {
                    use std::io::BufRead;
                    for line in std::io::BufReader::new(stderr).lines() {
                        let Ok(line) = line else { break };
                        errln!("{line}");
                        let _ = tx.send(StageLog::new(monotonic_ns(), pid, &name, &line));
                    }
                });
            // Finished readers of earlier (restarted) processes are done with.
            self.stderr_readers.retain(|r| !r.is_finished());
            self.stderr_readers.extend(reader.ok());
        }
        self.child = Some(child);
        self.started = Instant::now();
        Ok(pid)
    }

    /// Waits, up to `timeout`, until every line its processes wrote to stderr has been passed on
    /// (their readers end at the end of the pipe, once the process has exited). False if a
    /// reader is still going (a process that has not exited, or a child of it that keeps the
    /// pipe open).
    pub fn stderr_read(&mut self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        while self.stderr_readers.iter().any(|r| !r.is_finished()) {
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        self.stderr_readers.clear();
        true
    }

    /// Whether the process is still running; an exit is reported once.
    pub fn poll(&mut self) -> Poll {
        let Some(child) = self.child.as_mut() else {
            return Poll::Absent;
        };
        match child.try_wait() {
            Ok(Some(status)) => {
                self.child = None;
                Poll::Exited(status)
            }
            _ => Poll::Running,
        }
    }

    /// The running process's id.
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(|c| c.id())
    }

    /// SIGKILL (works on a stopped process too); the exit is reported by [`Self::poll`].
    pub fn kill(&self) {
        self.signal(libc::SIGKILL);
    }

    fn signal(&self, sig: i32) {
        if let Some(c) = &self.child {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(c.id() as i32, sig) };
        }
    }
}

/// An exit status in words.
pub fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => format!("signal {s}"),
        _ => "unknown status".into(),
    }
}

/// Stops every stage: SIGTERM from the source downstream (so no new frames enter while the
/// others stop), then SIGKILL for any that is still there after `timeout`. Returns the names
/// of the stages that had to be killed.
pub fn stop_all(stages: &mut [StageProcess], timeout: Duration) -> Vec<&'static str> {
    for s in stages.iter().rev() {
        s.signal(libc::SIGTERM);
    }
    let deadline = Instant::now() + timeout;
    let mut killed = Vec::new();
    for s in stages.iter_mut().rev() {
        let Some(mut child) = s.child.take() else { continue };
        loop {
            match child.try_wait() {
                Ok(Some(_)) => break,
                Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
                _ => {
                    killed.push(s.name);
                    let _ = child.kill();
                    let _ = child.wait();
                    break;
                }
            }
        }
    }
    killed
}

/// The stage binary `deckwatch-<name>` in `dir`, or beside this executable.
pub fn stage_binary(dir: Option<&Path>, name: &str) -> Result<PathBuf, String> {
    let dir = match dir {
        Some(d) => d.to_path_buf(),
        None => std::env::current_exe()
            .map_err(|e| format!("cannot locate the deckwatch executable: {e}"))?
            .parent()
            .map(Path::to_path_buf)
            .ok_or("the deckwatch executable has no folder")?,
    };
    let p = dir.join(format!("deckwatch-{name}"));
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!(
            "stage binary {} not found; build all binaries with `cargo build --release --workspace --bins`",
            p.display()
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn script(dir: &Path, name: &str, body: &str) -> PathBuf {
        use std::os::unix::fs::PermissionsExt;
        let p = dir.join(format!("deckwatch-{name}"));
        std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        p
    }

    #[test]
    fn spawn_poll_and_stop() {
        let dir = tempfile::tempdir().unwrap();
        let quick = script(dir.path(), "quick", "exit 3");
        // Ignores SIGTERM: must be killed.
        let stubborn = script(
            dir.path(),
            "stubborn",
            "trap '' TERM\nwhile true; do sleep 0.05; done",
        );
        let polite = script(dir.path(), "polite", "exec sleep 30");
        assert_eq!(stage_binary(Some(dir.path()), "quick").unwrap(), quick);
        let e = stage_binary(Some(dir.path()), "missing").unwrap_err();
        assert!(
            e.contains("deckwatch-missing") && e.contains("cargo build"),
            "{e}"
        );

        let mut q = StageProcess::new("quick", quick);
        assert_eq!(q.poll(), Poll::Absent);
        q.spawn(Path::new("c.toml"), "d").unwrap();
        let status = loop {
            match q.poll() {
                Poll::Exited(s) => break s,
                _ => std::thread::sleep(Duration::from_millis(5)),
            }
        };
        assert_eq!(describe(status), "exit code 3");
        assert_eq!(q.poll(), Poll::Absent, "an exit is reported once");

        let mut stages = vec![
            StageProcess::new("polite", polite),
            StageProcess::new("stubborn", stubborn),
        ];
        for s in &mut stages {
            s.spawn(Path::new("c.toml"), "d").unwrap();
            assert_eq!(s.poll(), Poll::Running);
        }
        std::thread::sleep(Duration::from_millis(100)); // let the trap be set
        let killed = stop_all(&mut stages, Duration::from_millis(300));
        assert_eq!(killed, vec!["stubborn"]);
        assert!(stages.iter_mut().all(|s| s.poll() == Poll::Absent));
    }
}
