//! `deckwatch soak`: the whole pipeline for a long time at camera rate on full-size frames (a
//! looped replay), with each process's resident memory and the domain's shared memory sampled
//! as it runs. What a flight of half an hour must not show: memory that grows, frames dropped.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The processes a soak follows, in the order of its table.
const PROCESSES: [&str; 5] = ["capture", "detect", "estimate", "decide", "launcher"];

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

/// Private resident memory (MiB) of a process: `RssAnon` of `/proc/<pid>/status`, the heap and
/// stacks, where a leak shows. (`VmRSS` also counts the shared-memory pages a process has
/// touched, which grow whenever the transport first uses another of its fixed pool of frame
/// samples; those are in the domain's shared-memory column.)
fn private_mib(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kib: f64 = status
        .lines()
        .find(|l| l.starts_with("RssAnon:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kib / 1024.0)
}

/// Shared memory the domain holds (MiB allocated in /dev/shm, and files).
fn shm_mib(domain: &str) -> (f64, usize) {
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
struct TempDir(PathBuf);

impl TempDir {
    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
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
        None => {
            let r = dir.path().join("recording");
            eprintln!("soak: rendering 60 frames of 3280x2464 into {}", r.display());
            let status = Command::new(&me)
                .args(["sim", "record", "--frames", "60", "--rate"])
                .arg(a.rate.to_string())
                .arg("--out")
                .arg(&r)
                .stdout(Stdio::null())
                .status()
                .map_err(|e| format!("deckwatch sim record: {e}"))?;
            if !status.success() {
                return Err("deckwatch sim record failed".into());
            }
            r
        }
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
    let mut launcher = Command::new(&me)
        .args(["run", "--quiet", "--json", "--config"])
        .arg(&config)
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("deckwatch run: {e}"))?;
    let mut stdout = launcher.stdout.take().ok_or("no stdout")?;
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stdout, &mut s);
        s
    });
    println!(
        "soak: {} min at {} fps of {} ({frames} frames); private resident memory (RssAnon, MiB) of each process and the domain's shared memory every {} s",
        a.minutes,
        a.rate,
        recording.display(),
        a.every_s
    );
    println!(
        "{:>7} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "t_s", "capture", "detect", "estimate", "decide", "launcher", "shm_MiB", "shm_files"
    );
    let start = Instant::now();
    let mut samples: Vec<[Option<f64>; 5]> = Vec::new();
    let mut next = Duration::from_secs_f64(a.every_s.min(10.0));
    loop {
        if launcher.try_wait().map_err(|e| e.to_string())?.is_some() {
            break;
        }
        if start.elapsed() >= next {
            next += Duration::from_secs_f64(a.every_s);
            let pids = deckwatch_runtime::stage::stage_processes(&a.domain);
            let rss: [Option<f64>; 5] = PROCESSES.map(|p| match p {
                "launcher" => private_mib(launcher.id()),
                stage => pids
                    .iter()
                    .find(|(n, _)| n == stage)
                    .and_then(|(_, pid)| private_mib(*pid)),
            });
            let (shm, files) = shm_mib(&a.domain);
            let cell = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
            println!(
                "{:>7.0} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9.1} {:>9}",
                start.elapsed().as_secs_f64(),
                cell(rss[0]),
                cell(rss[1]),
                cell(rss[2]),
                cell(rss[3]),
                cell(rss[4]),
                shm,
                files
            );
            samples.push(rss);
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let status = launcher.wait().map_err(|e| e.to_string())?;
    let out = reader.join().map_err(|_| "the report reader failed")?;
    if !status.success() {
        return Err(format!("deckwatch run failed ({status})"));
    }
    let report: serde_json::Value = out
        .find('{')
        .and_then(|i| serde_json::from_str(&out[i..]).ok())
        .ok_or_else(|| format!("no report from deckwatch run: {out}"))?;
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
    for (k, name) in PROCESSES.iter().enumerate() {
        let first = samples.get(settled).and_then(|s| s[k]);
        let last = samples.iter().rev().find_map(|s| s[k]);
        if let (Some(f), Some(l)) = (first, last) {
            println!("{name:<9} {f:>8.1} -> {l:>8.1} MiB ({:+.1})", l - f);
            worst = worst.max(l - f);
        }
    }
    println!(
        "{} decisions in {:.0} s; drops {total_drops} ({drops}); restarts {}",
        report["decisions"],
        report["duration_s"].as_f64().unwrap_or(0.0),
        report["restarts"]
    );
    let flat = worst <= a.max_growth_mib;
    println!(
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
