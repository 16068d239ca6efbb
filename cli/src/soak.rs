//! `deckwatch soak`: the whole pipeline for a long time at camera rate on full-size frames (a
//! looped replay), with each process's CPU (user + system), resident memory and context switches
//! and the domain's shared memory sampled as it runs. What a flight of half an hour must not
//! show: memory that grows, frames dropped; and what each process costs per frame (the budget a
//! Raspberry Pi must have).

use deckwatch_common::messages::STAGES;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How many processes a soak follows: the source and the frame's stages (a soak's run has no
/// link or recorder), then the launcher.
const FOLLOWED: usize = STAGES + 2;

/// The processes a soak follows, in the order of its table: the names the pipeline's topology
/// declares (`runtime::stages::PROCESSES`), then the launcher.
fn followed_processes() -> [&'static str; FOLLOWED] {
    std::array::from_fn(|k| match k {
        k if k <= STAGES => deckwatch_runtime::stages::PROCESSES[k].name,
        _ => "launcher",
    })
}

#[derive(clap::Args)]
pub struct SoakArgs {
    /// How long to run.
    #[arg(long, default_value_t = 30.0)]
    minutes: f64,
    /// Frames per second (the replay's pace).
    #[arg(long, default_value_t = 30.0)]
    rate: f64,
    /// A recording to replay in a loop. Default: 60 frames of the simulator at the Pi camera's
    /// 3280x2464, rendered first into a temporary folder.
    #[arg(long)]
    recording: Option<PathBuf>,
    /// Seconds between memory samples.
    #[arg(long, default_value_t = 60.0)]
    every_s: f64,
    /// iceoryx2 domain of the run.
    #[arg(long, default_value = "soak")]
    domain: String,
    /// Private resident memory any process may gain from the first sample (taken after the
    /// first minute, once every buffer is allocated) to the last (MiB).
    #[arg(long, default_value_t = 8.0)]
    max_growth_mib: f64,
}

/// CPU time of a process so far (user + system, s): `/proc/<pid>/stat` fields 14 and 15.
pub(crate) fn cpu_s(pid: u32) -> Option<f64> {
    cpu_split_s(pid).map(|(user, system)| user + system)
}

/// CPU time of a process so far, (user, system) in seconds: `/proc/<pid>/stat` fields 14, 15.
pub(crate) fn cpu_split_s(pid: u32) -> Option<(f64, f64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) may hold spaces and parentheses: count from the last `)`.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let user = fields.get(11)?.parse::<u64>().ok()?;
    let system = fields.get(12)?.parse::<u64>().ok()?;
    // SAFETY: sysconf only reads a system constant.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    Some((user as f64 / hz, system as f64 / hz))
}

/// Context switches of a process so far: (voluntary, involuntary).
pub(crate) fn context_switches(pid: u32) -> Option<(u64, u64)> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let get = |key: &str| {
        status
            .lines()
            .find(|l| l.starts_with(key))?
            .split_whitespace()
            .nth(1)?
            .parse::<u64>()
            .ok()
    };
    Some((
        get("voluntary_ctxt_switches:")?,
        get("nonvoluntary_ctxt_switches:")?,
    ))
}

/// Private resident memory (MiB) of a process: `RssAnon` of `/proc/<pid>/status`, the heap and
/// stacks, where a leak shows. (`VmRSS` also counts the shared-memory pages a process has
/// touched, which grow whenever the transport first uses another of its fixed pool of frame
/// samples; those are in the domain's shared-memory column.)
pub(crate) fn private_mib(pid: u32) -> Option<f64> {
    status_kib(pid, "RssAnon:").map(|kib| kib / 1024.0)
}

/// Shared memory a process has touched (MiB): `RssShmem` of `/proc/<pid>/status`.
pub(crate) fn shared_mib(pid: u32) -> Option<f64> {
    status_kib(pid, "RssShmem:").map(|kib| kib / 1024.0)
}

fn status_kib(pid: u32, key: &str) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find(|l| l.starts_with(key))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

/// Shared memory the domain holds (MiB allocated in /dev/shm, and files).
pub(crate) fn shm_mib(domain: &str) -> (f64, usize) {
    use std::os::unix::fs::MetadataExt;
    let prefix = deckwatch_runtime::bus::domain_prefix(domain);
    let Ok(entries) = std::fs::read_dir("/dev/shm") else {
        return (0.0, 0);
    };
    let (mut bytes, mut files) = (0u64, 0usize);
    for e in entries.flatten() {
        if e.file_name().to_string_lossy().starts_with(&prefix) {
            if let Ok(m) = e.metadata() {
                bytes += m.blocks() * 512;
                files += 1;
            }
        }
    }
    (bytes as f64 / (1 << 20) as f64, files)
}

/// A folder removed when dropped.
pub(crate) struct TempDir(pub(crate) PathBuf);

impl TempDir {
    pub(crate) fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `deckwatch run --quiet --json --config CONFIG` in the background (a soak's, a budget's), its
/// JSON report read as it ends.
pub(crate) struct BackgroundRun {
    launcher: std::process::Child,
    reader: std::thread::JoinHandle<String>,
}

impl BackgroundRun {
    pub(crate) fn start(me: &Path, config: &Path) -> Result<Self, String> {
        let mut launcher = Command::new(me)
            .args(["run", "--quiet", "--json", "--config"])
            .arg(config)
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("deckwatch run: {e}"))?;
        let mut stdout = launcher.stdout.take().ok_or("no stdout")?;
        let reader = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut stdout, &mut s);
            s
        });
        Ok(Self { launcher, reader })
    }

    /// The launcher's process id.
    pub(crate) fn id(&self) -> u32 {
        self.launcher.id()
    }

    /// Whether the run has ended.
    pub(crate) fn finished(&mut self) -> Result<bool, String> {
        Ok(self.launcher.try_wait().map_err(|e| e.to_string())?.is_some())
    }

    /// Waits for the end: the run's report, or why there is none.
    pub(crate) fn report(mut self) -> Result<serde_json::Value, String> {
        let status = self.launcher.wait().map_err(|e| e.to_string())?;
        let out = self.reader.join().map_err(|_| "the report reader failed")?;
        if !status.success() {
            return Err(format!("deckwatch run failed ({status})"));
        }
        out.find('{')
            .and_then(|i| serde_json::from_str(&out[i..]).ok())
            .ok_or_else(|| format!("no report from deckwatch run: {out}"))
    }
}

/// Renders 60 frames of the simulator at 3280x2464 into `dir`/recording (what a soak or a budget
/// replays in a loop when given no recording).
pub(crate) fn render_recording(me: &Path, dir: &Path, rate: f64, who: &str) -> Result<PathBuf, String> {
    let r = dir.join("recording");
    errln!("{who}: rendering 60 frames of 3280x2464 into {}", r.display());
    let status = Command::new(me)
        .args(["sim", "record", "--frames", "60", "--rate"])
        .arg(rate.to_string())
        .arg("--out")
        .arg(&r)
        .stdout(Stdio::null())
        .status()
        .map_err(|e| format!("deckwatch sim record: {e}"))?;
    if !status.success() {
        return Err("deckwatch sim record failed".into());
    }
    Ok(r)
}

pub fn run(a: SoakArgs) -> Result<(), String> {
    if !(a.minutes > 0.0 && a.rate > 0.0 && a.every_s > 0.0) {
        return Err("--minutes, --rate and --every-s must be positive".into());
    }
    let me = std::env::current_exe().map_err(|e| format!("this program's path: {e}"))?;
    // The rendered recording and the configuration, removed at the end.
    let dir = TempDir(std::env::temp_dir().join(format!("deckwatch-soak-{}", std::process::id())));
    std::fs::create_dir_all(dir.path()).map_err(|e| format!("{}: {e}", dir.path().display()))?;
    let recording = match a.recording {
        Some(r) => r,
        None => render_recording(&me, dir.path(), a.rate, "soak")?,
    };
    let frames = (a.minutes * 60.0 * a.rate).round() as u64;
    let config = dir.path().join("soak.toml");
    // Heave off: a recording of a level vehicle has no vehicle height.
    std::fs::write(
        &config,
        format!(
            "[bus]\ndomain = \"{}\"\n[source]\nkind = \"replay\"\n[replay]\nrecording = \"{}\"\n\
             loops = 0\nframes = {frames}\nrate_hz = {}\n[decide]\nheave = \"off\"\n[rerun]\nsink = \"off\"\n",
            a.domain,
            recording.display(),
            a.rate
        ),
    )
    .map_err(|e| format!("{}: {e}", config.display()))?;
    let mut run = BackgroundRun::start(&me, &config)?;
    outln!(
        "soak: {} min at {} fps of {} ({frames} frames); every {} s, each process's CPU since the last sample (% of a core, user + system) / private resident memory (RssAnon, MiB), and the domain's shared memory",
        a.minutes,
        a.rate,
        recording.display(),
        a.every_s
    );
    let processes = followed_processes();
    let columns: String = processes.iter().map(|p| format!(" {p:>14}")).collect();
    outln!("{:>7}{columns} {:>9} {:>9}", "t_s", "shm_MiB", "shm_files");
    let start = Instant::now();
    let mut samples: Vec<[Option<f64>; FOLLOWED]> = Vec::new();
    // Per process: (pid, CPU s, when) at the previous sample, at the first after a minute, and
    // the context switches at the last.
    let mut previous: [Option<(u32, f64, Instant)>; FOLLOWED] = [None; FOLLOWED];
    let mut settled_cpu: [Option<(u32, f64, Instant)>; FOLLOWED] = [None; FOLLOWED];
    let mut first_cpu: [Option<(u32, f64, Instant)>; FOLLOWED] = [None; FOLLOWED];
    let mut last_cpu: [Option<(u32, f64, Instant)>; FOLLOWED] = [None; FOLLOWED];
    let mut switches: [Option<(u64, u64)>; FOLLOWED] = [None; FOLLOWED];
    let mut next = Duration::from_secs_f64(a.every_s.min(10.0));
    loop {
        if run.finished()? {
            break;
        }
        if start.elapsed() >= next {
            next += Duration::from_secs_f64(a.every_s);
            let pids = deckwatch_runtime::stage::stage_processes(&a.domain);
            let pid_of: [Option<u32>; FOLLOWED] = std::array::from_fn(|k| match k {
                k if k == FOLLOWED - 1 => Some(run.id()),
                k => pids.iter().find(|(n, _)| n == processes[k]).map(|(_, pid)| *pid),
            });
            let rss: [Option<f64>; FOLLOWED] = pid_of.map(|pid| pid.and_then(private_mib));
            let now = Instant::now();
            let mut cells = String::new();
            for k in 0..FOLLOWED {
                let cpu = pid_of[k].and_then(|pid| Some((pid, cpu_s(pid)?, now)));
                // Since the previous sample of the same process (a restart starts afresh).
                let pct = match (previous[k], cpu) {
                    (Some((p0, c0, t0)), Some((p1, c1, t1))) if p0 == p1 => {
                        Some(100.0 * (c1 - c0) / (t1 - t0).as_secs_f64().max(1e-9))
                    }
                    _ => None,
                };
                previous[k] = cpu;
                if start.elapsed() >= Duration::from_secs(60) && settled_cpu[k].is_none() {
                    settled_cpu[k] = cpu;
                }
                if cpu.is_some() {
                    if first_cpu[k].is_none() {
                        first_cpu[k] = cpu;
                    }
                    last_cpu[k] = cpu;
                    switches[k] = pid_of[k].and_then(context_switches);
                }
                let pct = pct.map_or("-".to_string(), |v| format!("{v:.1}%"));
                let mib = rss[k].map_or("-".to_string(), |v| format!("{v:.1}"));
                cells.push_str(&format!(" {:>14}", format!("{pct}/{mib}")));
            }
            let (shm, files) = shm_mib(&a.domain);
            outln!(
                "{:>7.0}{cells} {:>9.1} {:>9}",
                start.elapsed().as_secs_f64(),
                shm,
                files
            );
            samples.push(rss);
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let report = run.report()?;
    let drops = &report["drops"];
    let total_drops: u64 = [
        "capture",
        "bad_frames",
        "detect",
        "estimate",
        "decide",
        "observer",
    ]
    .iter()
    .map(|k| drops[k].as_u64().unwrap_or(0))
    .sum();
    // Growth from the first sample after a minute (buffers allocated) to the last.
    let settled = ((60.0 / a.every_s).ceil() as usize).min(samples.len().saturating_sub(1));
    let mut worst = 0.0f64;
    outln!(
        "{:<9} {:>11} {:>13} {:>26} {:>22}",
        "process",
        "CPU %",
        "CPU ms/frame",
        "RssAnon MiB (growth)",
        "ctx switches vol/invol"
    );
    for (k, name) in processes.iter().enumerate() {
        let first = samples.get(settled).and_then(|s| s[k]);
        let last = samples.iter().rev().find_map(|s| s[k]);
        // CPU from the first sample after a minute (or the first) to the last, same process.
        let cpu = match (settled_cpu[k].or(first_cpu[k]), last_cpu[k]) {
            (Some((p0, c0, t0)), Some((p1, c1, t1))) if p0 == p1 && t1 > t0 => {
                let s = (t1 - t0).as_secs_f64();
                Some((100.0 * (c1 - c0) / s, 1e3 * (c1 - c0) / (s * a.rate)))
            }
            _ => None,
        };
        let (pct, per_frame) = cpu.map_or(("-".to_string(), "-".to_string()), |(p, f)| {
            (format!("{p:.1}"), format!("{f:.2}"))
        });
        let mem = match (first, last) {
            (Some(f), Some(l)) => {
                worst = worst.max(l - f);
                format!("{f:.1} -> {l:.1} ({:+.1})", l - f)
            }
            _ => "-".to_string(),
        };
        let sw = switches[k].map_or("-".to_string(), |(v, i)| format!("{v}/{i}"));
        outln!("{name:<9} {pct:>11} {per_frame:>13} {mem:>26} {sw:>22}");
    }
    outln!(
        "{} decisions in {:.0} s; drops {total_drops} ({drops}); restarts {}",
        report["decisions"],
        report["duration_s"].as_f64().unwrap_or(0.0),
        report["restarts"]
    );
    let flat = worst <= a.max_growth_mib;
    outln!(
        "memory {} (largest growth {worst:+.1} MiB, limit {} MiB); {}",
        if flat { "flat" } else { "GROWS" },
        a.max_growth_mib,
        if total_drops == 0 { "0 drops" } else { "DROPS" }
    );
    if flat && total_drops == 0 {
        Ok(())
    } else {
        Err("the soak failed: memory grew or frames were dropped".into())
    }
}
