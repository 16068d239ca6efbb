//! `deckwatch budget`: what each process of the pipeline costs, per second and per frame, at
//! the frame rates a flight uses (10 and 30 fps by default) on full-size frames: user and system
//! CPU time, context switches, private resident memory and the shared memory it touches; and
//! what that would be on a Raspberry Pi 5, scaled by factors measured against it
//! (BENCHMARKS.md, "Per-process resources: CPU, memory, a Raspberry Pi 5").
//!
//! CPU time is the scheduler's (nanoseconds, `/proc/<pid>/schedstat`), split into user and system
//! time in the proportion of `/proc/<pid>/stat`'s clock ticks.
//!
//! Each rate is a run of the whole pipeline (`deckwatch run`) replaying a recording in a loop;
//! the counters of `/proc` are read after it has settled and again before it ends, so start-up
//! (decoding, mapping shared memory) is left out.

use crate::soak::{
    context_switches, cpu_split_s, private_mib, render_recording, shared_mib, shm_mib, BackgroundRun, TempDir,
};
use deckwatch_runtime::config::MAX_CONFIG_FILE_BYTES;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct BudgetArgs {
    /// Frame rates to measure (fps), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "10,30")]
    rates: Vec<f64>,
    /// Seconds measured at each rate (after `--settle-s`).
    #[arg(long, default_value_t = 30.0)]
    seconds: f64,
    /// Seconds left out at the start of each run.
    #[arg(long, default_value_t = 5.0)]
    settle_s: f64,
    /// A recording to replay in a loop. Default: 60 frames of the simulator at the Pi camera's
    /// 3280x2464, rendered first into a temporary folder.
    #[arg(long)]
    recording: Option<PathBuf>,
    /// A pipeline configuration for the other sections (estimator, decision, link, vehicle);
    /// its source, replay, bus and rerun sections are the budget's.
    #[arg(long)]
    config: Option<PathBuf>,
    /// How many times longer a Raspberry Pi 5 core takes for this machine's compute (this
    /// machine's single-thread 7-Zip rating over the Pi 5's; BENCHMARKS.md says how it was
    /// measured).
    #[arg(long, default_value_t = 1.0)]
    pi5_cpu_factor: f64,
    /// How many times longer a Raspberry Pi 5 takes to move memory (this machine's single-core
    /// memcpy bandwidth over the Pi 5's).
    #[arg(long, default_value_t = 1.0)]
    pi5_memory_factor: f64,
    /// iceoryx2 domain of the runs.
    #[arg(long, default_value = "budget")]
    domain: String,
}

/// One process's counters at one instant.
#[derive(Debug, Clone, Copy)]
struct Counters {
    pid: u32,
    /// Time on a CPU (s, nanosecond resolution: `/proc/<pid>/schedstat`).
    cpu_s: f64,
    /// User and system time (s, in clock ticks of 10 ms: only their ratio is used).
    user_s: f64,
    system_s: f64,
    voluntary: u64,
    involuntary: u64,
    private_mib: f64,
    shared_mib: f64,
}

impl Counters {
    fn read(pid: u32) -> Option<Self> {
        let (user_s, system_s) = cpu_split_s(pid)?;
        let schedstat = std::fs::read_to_string(format!("/proc/{pid}/schedstat")).ok()?;
        let cpu_s = schedstat.split_whitespace().next()?.parse::<u64>().ok()? as f64 / 1e9;
        let (voluntary, involuntary) = context_switches(pid)?;
        Some(Self {
            pid,
            cpu_s,
            user_s,
            system_s,
            voluntary,
            involuntary,
            private_mib: private_mib(pid)?,
            shared_mib: shared_mib(pid).unwrap_or(0.0),
        })
    }
}

/// The processes of a run by name (the stages in the topology's order, then the launcher).
fn processes(domain: &str, launcher: u32) -> Vec<(String, u32)> {
    let mut p = deckwatch_runtime::stage::stage_processes(domain);
    let order = deckwatch_runtime::stages::PROCESSES.map(|p| p.name);
    p.sort_by_key(|(n, _)| order.iter().position(|o| o == n).unwrap_or(order.len()));
    p.push(("launcher".into(), launcher));
    p
}

pub fn run(a: BudgetArgs) -> Result<(), String> {
    if a.rates.is_empty() || a.rates.iter().any(|r| !(*r > 0.0 && *r <= 120.0)) {
        return Err("--rates: each must be in (0, 120] fps".into());
    }
    if !(a.seconds > 0.0 && a.settle_s >= 0.0 && a.pi5_cpu_factor > 0.0 && a.pi5_memory_factor > 0.0) {
        return Err("--seconds and the factors must be positive, --settle-s not negative".into());
    }
    let me = std::env::current_exe().map_err(|e| format!("this program's path: {e}"))?;
    let dir = TempDir(std::env::temp_dir().join(format!("deckwatch-budget-{}", std::process::id())));
    std::fs::create_dir_all(dir.path()).map_err(|e| format!("{}: {e}", dir.path().display()))?;
    let recording = match &a.recording {
        Some(r) => r.clone(),
        None => render_recording(&me, dir.path(), 30.0, "budget")?,
    };
    let base = match &a.config {
        Some(p) => deckwatch_common::files::read_bounded_to_string(p, MAX_CONFIG_FILE_BYTES)
            .map_err(|e| e.to_string())?,
        None => "[decide]\nheave = \"off\"\n".to_string(),
    };
    let factor = a.pi5_cpu_factor.max(a.pi5_memory_factor);
    outln!(
        "budget: {} s at each of {:?} fps replaying {} (after {} s settling); per process: CPU \
         (user + system) per frame and % of a core, context switches per frame, private resident \
         memory (RssAnon) and the shared memory it has touched (RssShmem); Pi 5 = this machine's \
         CPU time x {factor:.2} (the larger of the CPU factor {} and the memory factor {})",
        a.seconds,
        a.rates,
        recording.display(),
        a.settle_s,
        a.pi5_cpu_factor,
        a.pi5_memory_factor
    );
    for &rate in &a.rates {
        let frames = ((a.settle_s + a.seconds + 5.0) * rate).ceil() as u64;
        let config = dir.path().join(format!("budget-{rate}.toml"));
        let table = toml_merge(&base, &a.domain, &recording, frames, rate)?;
        std::fs::write(&config, table).map_err(|e| format!("{}: {e}", config.display()))?;
        let run = BackgroundRun::start(&me, &config)?;
        std::thread::sleep(Duration::from_secs_f64(a.settle_s));
        let names = processes(&a.domain, run.id());
        let first: Vec<Option<Counters>> = names.iter().map(|(_, pid)| Counters::read(*pid)).collect();
        let t0 = Instant::now();
        std::thread::sleep(Duration::from_secs_f64(a.seconds));
        let last: Vec<Option<Counters>> = names.iter().map(|(_, pid)| Counters::read(*pid)).collect();
        let elapsed_s = t0.elapsed().as_secs_f64();
        let (shm, files) = shm_mib(&a.domain);
        let report = run.report().map_err(|e| format!("at {rate} fps: {e}"))?;
        let frames_s = elapsed_s * rate;
        outln!(
            "\n{rate} fps: {} decisions, drops {}",
            report["decisions"],
            report["drops"]
        );
        outln!(
            "{:<9} {:>10} {:>10} {:>8} {:>14} {:>9} {:>11} {:>12}",
            "process",
            "user ms/f",
            "sys ms/f",
            "CPU %",
            "ctx/f vol/inv",
            "RssAnon",
            "shm touched",
            "Pi 5 ms/f"
        );
        let mut total = [0.0f64; 5];
        for (k, (name, _)) in names.iter().enumerate() {
            let (Some(f), Some(l)) = (first[k], last[k]) else {
                outln!("{name:<9} (not running for the whole measurement)");
                continue;
            };
            if f.pid != l.pid {
                outln!("{name:<9} (restarted during the measurement)");
                continue;
            }
            // The CPU time in nanoseconds, split into user and system as the ticks are.
            let cpu = l.cpu_s - f.cpu_s;
            let (ticks_user, ticks_system) = (l.user_s - f.user_s, l.system_s - f.system_s);
            let user_share = if ticks_user + ticks_system > 0.0 {
                ticks_user / (ticks_user + ticks_system)
            } else {
                1.0
            };
            let user = 1e3 * cpu * user_share / frames_s;
            let system = 1e3 * cpu * (1.0 - user_share) / frames_s;
            let pct = 100.0 * cpu / elapsed_s;
            let vol = (l.voluntary - f.voluntary) as f64 / frames_s;
            let inv = (l.involuntary - f.involuntary) as f64 / frames_s;
            for (t, v) in total
                .iter_mut()
                .zip([user, system, pct, l.private_mib, vol + inv])
            {
                *t += v;
            }
            outln!(
                "{name:<9} {user:>10.3} {system:>10.3} {pct:>8.2} {:>14} {:>9.1} {:>11.1} {:>12.2}",
                format!("{vol:.1}/{inv:.2}"),
                l.private_mib,
                l.shared_mib,
                (user + system) * factor
            );
        }
        outln!(
            "{:<9} {:>10.3} {:>10.3} {:>8.2} {:>14} {:>9.1} {:>11} {:>12.2}",
            "all",
            total[0],
            total[1],
            total[2],
            format!("{:.1}", total[4]),
            total[3],
            "",
            (total[0] + total[1]) * factor
        );
        outln!(
            "the domain's shared memory: {shm:.1} MiB in {files} files; a Pi 5 core would be \
             {:.1} % busy",
            total[2] * factor
        );
    }
    Ok(())
}

/// The run's configuration: the user's sections, with the budget's source, replay, bus and
/// rerun (these keys of the user's file are replaced).
fn toml_merge(
    base: &str,
    domain: &str,
    recording: &std::path::Path,
    frames: u64,
    rate: f64,
) -> Result<String, String> {
    let mut table: toml::Table = base.parse().map_err(|e| format!("--config: {e}"))?;
    let ours: toml::Table = format!(
        "[bus]\ndomain = \"{domain}\"\n[source]\nkind = \"replay\"\n[replay]\nrecording = \"{}\"\n\
         loops = 0\nframes = {frames}\nrate_hz = {rate}\n[rerun]\nsink = \"off\"\n",
        recording.display()
    )
    .parse()
    .map_err(|e| format!("the budget's configuration: {e}"))?;
    for (section, values) in ours {
        let entry = table
            .entry(section)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let (Some(t), toml::Value::Table(v)) = (entry.as_table_mut(), values) {
            t.extend(v);
        }
    }
    toml::to_string(&table).map_err(|e| e.to_string())
}
