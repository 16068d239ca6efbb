//! Tests that start a pipeline own it through a [`PipelineGuard`]. Whatever happens to the test
//! (an assertion fails mid-fault, the launcher or a stage is stopped, the test thread dies), the
//! guard's drop resumes (SIGCONT) and kills (SIGKILL) the launcher and every stage process of its
//! domain, waits until they are gone, and removes the domain's shared memory and run folders.
//! A failing test must not leave a drone pipeline rendering on a developer's or CI's machine.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

/// What [`PipelineGuard::output`] gives: `std::process::Output`'s fields, and what of the domain
/// was still on the machine when the command had ended by itself, before the guard cleaned up
/// (a clean stop leaves nothing: [`leftovers`]).
pub struct PipelineOutput {
    pub status: ExitStatus,
    pub stdout: Vec<u8>,
    pub stderr: Vec<u8>,
    pub left_at_exit: Vec<String>,
}

impl From<PipelineOutput> for Output {
    fn from(o: PipelineOutput) -> Self {
        Output {
            status: o.status,
            stdout: o.stdout,
            stderr: o.stderr,
        }
    }
}

/// A launcher (or any process that starts stages on `domain`) and what it may leave behind, or
/// a peer process and what it started.
pub struct PipelineGuard {
    child: Option<Child>,
    /// The iceoryx2 domains its stages run on.
    domains: Vec<String>,
}

impl PipelineGuard {
    /// Starts `cmd`, whose stages run on `domain`. The launcher gets PR_SET_PDEATHSIG (SIGKILL),
    /// so a test process killed outright takes it along; its stages follow the launcher by
    /// their own PR_SET_PDEATHSIG.
    pub fn spawn(cmd: &mut Command, domain: &str) -> Self {
        let mut guard = Self::spawn_peer(cmd);
        guard.domains.push(domain.to_string());
        guard
    }

    /// Starts a process that runs no stages of its own (a pymavlink peer, the Ray driver and
    /// the local cluster it starts): on drop it and every process under it are killed, so a
    /// failed test leaves no peer streaming to a port or Ray cluster running.
    pub fn spawn_peer(cmd: &mut Command) -> Self {
        use std::os::unix::process::CommandExt;
        let test = std::process::id() as libc::pid_t;
        // SAFETY: prctl and getppid are async-signal-safe.
        unsafe {
            cmd.pre_exec(move || {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                if libc::getppid() != test {
                    return Err(std::io::Error::other("the test process is gone"));
                }
                Ok(())
            });
        }
        let child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {:?}: {e}", cmd.get_program()));
        Self {
            child: Some(child),
            domains: Vec::new(),
        }
    }

    /// Runs `cmd` to its end with its output captured, as `Command::output` does, but killed
    /// (and the test failed) if it has not ended within `timeout`.
    pub fn output(cmd: &mut Command, domain: &str, timeout: Duration) -> PipelineOutput {
        cmd.stdout(Stdio::piped()).stderr(Stdio::piped());
        let mut guard = Self::spawn(cmd, domain);
        let child = guard.child();
        let mut stdout = child.stdout.take().expect("piped stdout");
        let mut stderr = child.stderr.take().expect("piped stderr");
        let out = std::thread::spawn(move || read_all(&mut stdout));
        let err = std::thread::spawn(move || read_all(&mut stderr));
        let status = guard.wait_within(timeout);
        let stdout = out.join().unwrap_or_default();
        let stderr = err.join().unwrap_or_default();
        let Some(status) = status else {
            drop(guard);
            panic!(
                "{:?} did not end within {timeout:?}; killed it. stderr:\n{}",
                cmd.get_program(),
                String::from_utf8_lossy(&stderr)
            );
        };
        PipelineOutput {
            status,
            stdout,
            stderr,
            left_at_exit: leftovers(domain),
        }
    }

    pub fn child(&mut self) -> &mut Child {
        self.child.as_mut().expect("the launcher was already reaped")
    }

    pub fn id(&self) -> u32 {
        self.child.as_ref().expect("the launcher was already reaped").id()
    }

    /// One more domain the command's stages run on (one it names after its own pid, say).
    pub fn also_domain(&mut self, domain: String) {
        self.domains.push(domain);
    }

    /// Waits for the launcher to end by itself. The guard still makes sure, on drop, that
    /// nothing of the domain is left.
    pub fn wait(&mut self) -> ExitStatus {
        self.child().wait().expect("wait for the launcher")
    }

    /// Waits for the launcher to end by itself and collects its piped stdout and stderr, as
    /// `Child::wait_with_output` does.
    pub fn wait_with_output(&mut self) -> Output {
        let child = self.child();
        let mut stdout = child.stdout.take();
        let mut stderr = child.stderr.take();
        let err = std::thread::spawn(move || stderr.as_mut().map(read_all).unwrap_or_default());
        let stdout = stdout.as_mut().map(read_all).unwrap_or_default();
        let status = self.wait();
        Output {
            status,
            stdout,
            stderr: err.join().unwrap_or_default(),
        }
    }

    /// Waits up to `timeout` for the launcher to end by itself; None if it is still running.
    pub fn wait_within(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child().try_wait().expect("wait for the launcher") {
                return Some(status);
            }
            if Instant::now() > end {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Resumes and kills the launcher and every stage of the domain, then removes what they
    /// left. Idempotent; what could not be removed is in the returned list (empty: clean).
    pub fn stop_and_clean(&mut self) -> Vec<String> {
        // A launcher already reaped has no pid any more (it may be another process's by now).
        let launcher = self
            .child
            .as_mut()
            .and_then(|c| matches!(c.try_wait(), Ok(None)).then(|| c.id()));
        let mut pids: Vec<u32> = self
            .domains
            .iter()
            .flat_map(|d| deckwatch_runtime::stage::stage_processes(d))
            .map(|(_, pid)| pid)
            .collect();
        if let Some(l) = launcher {
            pids.extend(descendants(l));
            pids.push(l);
        }
        pids.sort_unstable();
        pids.dedup();
        // A stopped process acts on no signal but SIGKILL; resume it first all the same, so
        // that nothing stays stopped if the kill is refused.
        for &pid in &pids {
            signal(pid, libc::SIGCONT);
            signal(pid, libc::SIGKILL);
        }
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
        // The stages are reaped by init (they are not this process's children).
        let end = Instant::now() + Duration::from_secs(10);
        while pids.iter().any(|&p| running(p)) && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(10));
        }
        // Shared memory of the killed nodes, the domain, the run folders.
        let mut left = Vec::new();
        for domain in &self.domains {
            let _ = deckwatch_runtime::bus::Bus::cleanup_dead_nodes(domain);
            let _ = deckwatch_runtime::bus::Bus::remove_idle_domain(domain);
            for dir in run_dirs(domain) {
                let _ = std::fs::remove_dir_all(dir);
            }
            // A node killed while it was being created leaves files iceoryx2 does not take for
            // a node (seen once: a stage SIGKILLed within its first second). The domain is this
            // test's own, so whatever still carries its name goes.
            for path in leftovers(domain).iter().filter(|p| p.starts_with('/')) {
                let path = Path::new(path);
                let _ = std::fs::remove_file(path).or_else(|_| std::fs::remove_dir_all(path));
                // The node's own folder (`.../nodes/<node id>/`), once empty.
                if let Some(parent) = path.parent() {
                    if parent
                        .parent()
                        .and_then(|p| p.file_name())
                        .is_some_and(|n| n == "nodes")
                    {
                        let _ = std::fs::remove_dir(parent);
                    }
                }
            }
            left.extend(leftovers(domain));
        }
        left
    }
}

impl Drop for PipelineGuard {
    fn drop(&mut self) {
        let left = self.stop_and_clean();
        if !left.is_empty() {
            // Never a second panic while unwinding: say it.
            eprintln!("PipelineGuard({:?}): left behind: {left:?}", self.domains);
        }
    }
}

fn read_all(r: &mut impl std::io::Read) -> Vec<u8> {
    let mut v = Vec::new();
    let _ = r.read_to_end(&mut v);
    v
}

fn signal(pid: u32, sig: i32) {
    // SAFETY: kill(2) on a process of this test's pipeline; a gone pid is an ESRCH, ignored.
    unsafe { libc::kill(pid as libc::pid_t, sig) };
}

/// Whether `pid` still runs (a zombie has exited).
pub fn running(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, r)| r.split_whitespace().next() != Some("Z"))
        })
        .unwrap_or(false)
}

/// The parent process id of `pid`.
fn parent_of(pid: u32) -> Option<u32> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    stat.rsplit_once(')')?.1.split_whitespace().nth(1)?.parse().ok()
}

/// The live children of `pid`.
pub fn children(pid: u32) -> Vec<u32> {
    std::fs::read_dir("/proc")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .filter(|&p| parent_of(p) == Some(pid) && running(p))
        .collect()
}

/// Every live process below `pid` (children, their children, ...).
pub fn descendants(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let mut todo = vec![pid];
    while let Some(p) = todo.pop() {
        for c in children(p) {
            if !out.contains(&c) {
                out.push(c);
                todo.push(c);
            }
        }
    }
    out
}

/// The launcher's run folders of `domain` (`deckwatch-<domain>-<pid>` in the temporary folder).
pub fn run_dirs(domain: &str) -> Vec<PathBuf> {
    let prefix = format!("deckwatch-{domain}-");
    std::fs::read_dir(std::env::temp_dir())
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_str()
                .and_then(|n| n.strip_prefix(&prefix))
                .is_some_and(|pid| pid.parse::<u32>().is_ok())
        })
        .map(|e| e.path())
        .collect()
}

/// What of `domain` is still on this machine: its stage processes, its shared memory and
/// iceoryx2 files, its run folders (empty: nothing).
pub fn leftovers(domain: &str) -> Vec<String> {
    let mut left: Vec<String> = deckwatch_runtime::stage::stage_processes(domain)
        .into_iter()
        .map(|(stage, pid)| format!("process deckwatch-{stage} ({pid})"))
        .collect();
    let prefix = deckwatch_runtime::bus::domain_prefix(domain);
    left.extend(
        [PathBuf::from("/dev/shm"), deckwatch_runtime::bus::ipc_root_path()]
            .iter()
            .flat_map(|d| walk(d))
            .filter(|name| name.contains(&prefix)),
    );
    left.extend(run_dirs(domain).into_iter().map(|d| d.display().to_string()));
    left
}

/// Every path under `dir`.
pub fn walk(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            if e.path().is_dir() {
                todo.push(e.path());
            }
            out.push(e.path().display().to_string());
        }
    }
    out
}

/// `Command::output` for a command that starts a pipeline on `domain` (`deckwatch run`,
/// `latency`, `trials --processes`, ...): killed, and the test failed, if it has not ended
/// within 10 minutes; whatever happens, nothing of the domain is left.
pub fn pipeline_output(cmd: &mut Command, domain: &str) -> PipelineOutput {
    PipelineGuard::output(cmd, domain, Duration::from_secs(600))
}
