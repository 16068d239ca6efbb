//! `deckwatch doctor`: what a deployment needs, checked on this machine with its configuration:
//! the configuration itself, the stage binaries, shared memory, the camera, the MAVLink
//! endpoint, the rerun viewer, the flight recorder's disk. Each check says `ok`, or `FIX` with
//! what to do; the exit status is 1 when anything needs fixing.

use crate::launch::process::stage_binary;
use crate::pipeline::load;
use deckwatch_common::messages::FrameSource;
use deckwatch_runtime::bus::Bus;
use deckwatch_runtime::config::PipelineConfig;
use deckwatch_runtime::stage::active_stages;
use deckwatch_viz::RerunSink;
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(clap::Args)]
pub struct DoctorArgs {
    /// The pipeline configuration to check (default: the built-in defaults).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Folder of the stage binaries (default: beside this executable).
    #[arg(long)]
    stage_dir: Option<PathBuf>,
}

/// One finding.
enum Finding {
    Ok(String),
    Note(String),
    Fix(String, String),
}

/// Runs every check and prints them; true when nothing needs fixing.
pub fn run(a: DoctorArgs) -> Result<bool, String> {
    let (c, file) = load(a.config.as_deref())?;
    let mut found = vec![match c.validate(&file) {
        Ok(()) => Finding::Ok(format!("configuration {file}")),
        Err(e) => Finding::Fix(format!("configuration {file}"), e.to_string()),
    }];
    found.extend(binaries(&c, a.stage_dir.as_deref()));
    found.extend(shared_memory(&c));
    found.extend(camera(&c));
    found.extend(link(&c));
    found.extend(viewer(&c));
    found.extend(recorder(&c));
    let mut fixes = 0;
    for f in &found {
        match f {
            Finding::Ok(what) => outln!("ok    {what}"),
            Finding::Note(what) => outln!("note  {what}"),
            Finding::Fix(what, how) => {
                fixes += 1;
                outln!("FIX   {what}: {how}");
            }
        }
    }
    outln!(
        "{} checks, {fixes} to fix",
        found.iter().filter(|f| !matches!(f, Finding::Note(_))).count()
    );
    Ok(fixes == 0)
}

fn binaries(c: &PipelineConfig, dir: Option<&Path>) -> Vec<Finding> {
    use std::os::unix::fs::PermissionsExt;
    let version = format!("deckwatch {}", env!("CARGO_PKG_VERSION"));
    active_stages(c)
        .iter()
        .map(|s| {
            let what = format!("stage binary deckwatch-{}", s.name);
            let path = match stage_binary(dir, s.name) {
                Ok(p) => p,
                Err(e) => return Finding::Fix(what, e),
            };
            let executable = std::fs::metadata(&path).is_ok_and(|m| m.permissions().mode() & 0o111 != 0);
            if !executable {
                return Finding::Fix(what, format!("{} is not executable (chmod +x)", path.display()));
            }
            match std::process::Command::new(&path).arg("--version").output() {
                Ok(out) if String::from_utf8_lossy(&out.stdout).contains(env!("CARGO_PKG_VERSION")) => {
                    Finding::Ok(format!("{what} ({})", path.display()))
                }
                Ok(out) => Finding::Fix(
                    what,
                    format!(
                        "{} says `{}`, this is {version}: install the binaries of one build together",
                        path.display(),
                        String::from_utf8_lossy(&out.stdout).trim()
                    ),
                ),
                Err(e) => Finding::Fix(what, format!("{} does not run: {e}", path.display())),
            }
        })
        .collect()
}

/// Bytes free on the file system of `path` (statvfs), and whether it is a tmpfs.
fn free_bytes(path: &Path) -> Option<(u64, bool)> {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).ok()?;
    // SAFETY: statvfs and statfs fill the structs we pass for a NUL-terminated path.
    let mut v: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut v) } != 0 {
        return None;
    }
    let mut f: libc::statfs = unsafe { std::mem::zeroed() };
    let tmpfs = unsafe { libc::statfs(c.as_ptr(), &mut f) } == 0 && f.f_type == libc::TMPFS_MAGIC;
    Some((v.f_bavail as u64 * v.f_frsize as u64, tmpfs))
}

/// Whether this user can create a file in `dir`.
fn writable(dir: &Path) -> Result<(), String> {
    let probe = dir.join(format!(".deckwatch-doctor-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| e.to_string())?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// The frame size the configuration asks for, where it says (else the Pi camera's 3280x2464).
fn frame_bytes(c: &PipelineConfig) -> (u64, &'static str) {
    let size = match c.source.kind {
        FrameSource::Simulator => c.image.width.zip(c.image.height),
        FrameSource::Libcamera => {
            Some((c.libcamera.width, c.libcamera.height)).filter(|(w, h)| *w > 0 && *h > 0)
        }
        FrameSource::Replay => c
            .replay
            .recording
            .as_deref()
            .filter(|p| p.is_dir())
            .and_then(|p| deckwatch_formats::Recording::open(p).ok())
            .map(|r| (r.camera.width, r.camera.height)),
    };
    match size {
        Some((w, h)) => (u64::from(w) * u64::from(h), "the configured frames"),
        None => (3280 * 2464, "3280x2464 frames"),
    }
}

fn shared_memory(c: &PipelineConfig) -> Vec<Finding> {
    let mut out = Vec::new();
    let (bytes, what) = frame_bytes(c);
    let mut bus = c.bus.clone();
    if c.record.records_frames() {
        bus.frame_subscribers += 1;
    }
    let needed = bus.settings(bytes as usize).frame_memory_bytes() as u64 + (16 << 20);
    let shm = Path::new("/dev/shm");
    match free_bytes(shm) {
        None => out.push(Finding::Fix(
            "shared memory /dev/shm".into(),
            "missing: iceoryx2 needs a tmpfs at /dev/shm (mount -t tmpfs tmpfs /dev/shm)".into(),
        )),
        Some((free, tmpfs)) => {
            let mib = |b: u64| b >> 20;
            if free < needed {
                out.push(Finding::Fix(
                    "shared memory /dev/shm".into(),
                    format!(
                        "{} MiB free, the pipeline needs {} MiB for {what}: enlarge it (mount -o remount,size=1G /dev/shm; in Docker --shm-size=1g)",
                        mib(free),
                        mib(needed)
                    ),
                ));
            } else {
                out.push(Finding::Ok(format!(
                    "shared memory /dev/shm: {} MiB free, {} MiB needed for {what}{}",
                    mib(free),
                    mib(needed),
                    if tmpfs {
                        ""
                    } else {
                        " (not a tmpfs: frames go through a disk)"
                    }
                )));
            }
            match writable(shm) {
                Ok(()) => {}
                Err(e) => out.push(Finding::Fix(
                    "shared memory /dev/shm".into(),
                    format!("this user cannot create files there ({e})"),
                )),
            }
        }
    }
    match deckwatch_runtime::bus::ipc_root(&c.bus.domain) {
        Ok(root) => match writable(&root) {
            Ok(()) => out.push(Finding::Ok(format!(
                "iceoryx2 root {}: this user's alone, writable",
                root.display()
            ))),
            Err(e) => out.push(Finding::Fix(
                format!("iceoryx2 root {}", root.display()),
                format!("not writable by this user ({e})"),
            )),
        },
        Err(e) => out.push(Finding::Fix("iceoryx2 root".into(), e.to_string())),
    }
    match Bus::live_nodes(&c.bus.domain) {
        Ok(n) if n.is_empty() => out.push(Finding::Ok(format!("domain `{}` is free", c.bus.domain))),
        Ok(n) => out.push(Finding::Fix(
            format!("domain `{}`", c.bus.domain),
            format!(
                "in use by running nodes ({}): stop that pipeline or choose another bus.domain",
                n.join(", ")
            ),
        )),
        Err(e) => out.push(Finding::Fix(format!("domain `{}`", c.bus.domain), e.to_string())),
    }
    out
}

fn camera(c: &PipelineConfig) -> Vec<Finding> {
    if c.source.kind != FrameSource::Libcamera {
        return vec![Finding::Note(format!(
            "source is `{}`: no camera needed",
            c.source.kind.name()
        ))];
    }
    if !deckwatch_capture::camera::LIBCAMERA_BUILT_IN {
        return vec![Finding::Fix(
            "camera".into(),
            "this build has no libcamera: rebuild with --features deckwatch-capture/libcamera,deckwatch/libcamera (README, \"Real camera\")".into(),
        )];
    }
    match deckwatch_capture::camera::list_cameras() {
        Ok((_, cams)) if cams.is_empty() => vec![Finding::Fix(
            "camera".into(),
            "libcamera sees no camera: is it connected, enabled (camera_auto_detect=1) and this user in the `video` group?".into(),
        )],
        Ok((version, cams)) => cams
            .iter()
            .map(|d| Finding::Ok(format!("camera {}: {} ({}; libcamera {version})", d.index, d.model, d.id)))
            .collect(),
        Err(e) => vec![Finding::Fix("camera".into(), e.to_string())],
    }
}

fn link(c: &PipelineConfig) -> Vec<Finding> {
    use deckwatch_link::signing::Signing;
    use deckwatch_link::{Endpoint, SigningMode};
    if !c.link.enabled {
        return vec![Finding::Note("link off: no autopilot endpoint needed".into())];
    }
    let address = c.link.address.as_str();
    let what = format!("MAVLink endpoint {address}");
    let endpoint = match Endpoint::parse(address) {
        Ok(e) => e,
        Err(e) => return vec![Finding::Fix(what, e)],
    };
    let reach = match &endpoint {
        Endpoint::Serial { port, .. } => match std::fs::OpenOptions::new().read(true).write(true).open(port) {
            Ok(_) => Finding::Ok(format!("{what}: {port} opens for reading and writing")),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Finding::Fix(
                what,
                format!("{port} does not exist: is the flight controller wired and the UART enabled (dtoverlay=uart0 on a Pi)?"),
            ),
            Err(e) => Finding::Fix(what, format!("{port}: {e} (is this user in the `dialout` group?)")),
        },
        Endpoint::UdpIn(listen) => match std::net::UdpSocket::bind(listen) {
            Ok(_) => Finding::Ok(format!("{what}: the port is free to listen on")),
            Err(e) => Finding::Fix(
                what,
                format!("cannot listen on {listen}: {e} (another program holds the port?)"),
            ),
        },
        Endpoint::UdpOut(to) | Endpoint::TcpOut(to) => {
            match std::net::ToSocketAddrs::to_socket_addrs(to.as_str()).map(|mut a| a.next()) {
                Ok(Some(addr)) if matches!(endpoint, Endpoint::TcpOut(_)) => {
                    match std::net::TcpStream::connect_timeout(&addr, Duration::from_secs(1)) {
                        Ok(_) => Finding::Ok(format!("{what}: reachable")),
                        Err(e) => Finding::Fix(what, format!("cannot connect: {e}")),
                    }
                }
                Ok(Some(_)) => Finding::Ok(format!("{what}: the address resolves")),
                Ok(None) => Finding::Fix(what, "resolves to no address".into()),
                Err(e) => Finding::Fix(what, format!("does not resolve: {e}")),
            }
        }
    };
    let configured = Signing::configured(&c.link);
    let signing = match (c.link.signing, &configured) {
        (SigningMode::Off, _) => Finding::Note(format!(
            "MAVLink signing off: whoever reaches {address} can send the link an attitude (keep it on the loopback behind mavlink-router, or set [link] signing)"
        )),
        (SigningMode::Required, Ok(s)) => Finding::Ok(format!(
            "MAVLink signing required: the key in {} is this user's alone; timestamps kept in {}",
            c.link.signing_key_file,
            s.as_ref()
                .and_then(|s| s.kept_file())
                .map_or("-".into(), |f| f.display().to_string())
        )),
        (SigningMode::Required, Err(e)) => Finding::Fix("MAVLink signing".into(), e.to_string()),
    };
    let mut found = vec![reach, signing];
    if let (SigningMode::Required, Ok(Some(s))) = (c.link.signing, &configured) {
        found.push(signing_clock(s.newest_10us()));
    }
    found
}

/// Whether this machine's clock can be trusted for MAVLink signing: set (not behind the newest
/// time the link kept) and synchronised (the kernel's NTP status). Without it the kept state
/// alone orders the frames, which holds, but the autopilot's frames are then judged against it.
fn signing_clock(kept_newest_10us: u64) -> Finding {
    let what = "clock for MAVLink signing".to_string();
    let now = deckwatch_link::signing::clock_10us();
    if now < kept_newest_10us {
        return Finding::Fix(
            what,
            format!(
                "the clock is {:.0} s behind the newest signing time kept: not set (a board without a real-time clock before NTP or GPS)? Frames older than the kept state are refused all the same; set the clock (timedatectl, chrony) before flight",
                (kept_newest_10us - now) as f64 / 1e5
            ),
        );
    }
    // SAFETY: adjtimex with `modes` 0 only reads the kernel's time status into the zeroed
    // struct it is given.
    let status = unsafe {
        let mut t: libc::timex = std::mem::zeroed();
        libc::adjtimex(&mut t)
    };
    if status == libc::TIME_ERROR {
        Finding::Note(format!(
            "{what}: set, but not synchronised (the kernel's NTP status): the kept signing state still orders the frames; run chrony or systemd-timesyncd"
        ))
    } else {
        Finding::Ok(format!("{what}: set and synchronised"))
    }
}

fn viewer(c: &PipelineConfig) -> Vec<Finding> {
    let r = &c.rerun;
    let what = "rerun viewer".to_string();
    match r.sink {
        RerunSink::Off => vec![Finding::Note("rerun off".into())],
        RerunSink::Spawn => {
            let found = std::env::var_os("PATH")
                .map(|p| std::env::split_paths(&p).any(|d| d.join("rerun").is_file()))
                .unwrap_or(false);
            vec![if found {
                Finding::Ok(format!("{what}: `rerun` on PATH"))
            } else {
                Finding::Fix(
                    what,
                    "`rerun` is not on PATH: pip install rerun-sdk==0.36.3".into(),
                )
            }]
        }
        RerunSink::Connect => {
            let address = r
                .address
                .clone()
                .unwrap_or_else(|| deckwatch_viz::DEFAULT_ADDRESS.into());
            // rerun+http://HOST:PORT/proxy
            let hostport = address
                .split("://")
                .nth(1)
                .and_then(|rest| rest.split('/').next())
                .unwrap_or_default()
                .to_string();
            let addr = std::net::ToSocketAddrs::to_socket_addrs(&hostport)
                .ok()
                .and_then(|mut a| a.next());
            vec![
                match addr.map(|a| std::net::TcpStream::connect_timeout(&a, Duration::from_secs(1))) {
                    Some(Ok(_)) => Finding::Ok(format!("{what} at {address}: reachable")),
                    Some(Err(e)) => Finding::Fix(
                        format!("{what} at {address}"),
                        format!(
                            "{e}: start `rerun` there (it listens on 9876), or use --rerun save FILE.rrd"
                        ),
                    ),
                    None => Finding::Fix(format!("{what} at {address}"), "not a host:port".into()),
                },
            ]
        }
        RerunSink::Save => {
            let dir = r
                .path
                .as_deref()
                .and_then(Path::parent)
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            vec![match writable(dir) {
                Ok(()) => Finding::Ok(format!("rerun file folder {} writable", dir.display())),
                Err(e) => Finding::Fix(format!("rerun file folder {}", dir.display()), e),
            }]
        }
    }
}

fn recorder(c: &PipelineConfig) -> Vec<Finding> {
    let Some(path) = &c.record.path else {
        return vec![Finding::Note("no flight recorder".into())];
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let what = format!("flight recorder {}", path.display());
    if let Err(e) = writable(dir) {
        return vec![Finding::Fix(
            what,
            format!("{} is not writable: {e}", dir.display()),
        )];
    }
    let Some((free, _)) = free_bytes(dir) else {
        return vec![Finding::Ok(what)];
    };
    let (bytes, _) = frame_bytes(c);
    let rate = match c.source.kind {
        FrameSource::Simulator => c.sim.rate,
        FrameSource::Libcamera if c.libcamera.frame_rate > 0.0 => c.libcamera.frame_rate,
        _ => c.replay.rate_hz.filter(|r| *r > 0.0).unwrap_or(10.0),
    };
    // Raw: the pixels; PNG about half; JPEG about a fifth (BENCHMARKS.md); none: messages only.
    let share = match c.record.frames {
        deckwatch_flight::FrameEncoding::Raw => 1.0,
        deckwatch_flight::FrameEncoding::Png => 0.5,
        deckwatch_flight::FrameEncoding::Jpeg => 0.2,
        deckwatch_flight::FrameEncoding::None => 0.0,
    };
    let per_s = bytes as f64 * share * rate / f64::from(c.record.frame_every) + 100e3;
    let minutes = free as f64 / per_s / 60.0;
    vec![if minutes < 10.0 {
        Finding::Fix(
            what,
            format!(
                "{} MiB free in {}: {minutes:.1} min of recording at about {:.0} MB/s; free space, or record JPEG or every Nth frame ([record] frames, frame_every)",
                free >> 20,
                dir.display(),
                per_s / 1e6
            ),
        )
    } else {
        Finding::Ok(format!(
            "{what}: {} MiB free, about {minutes:.0} min at {:.1} MB/s",
            free >> 20,
            per_s / 1e6
        ))
    }]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kept signing time ahead of the clock is a clock not set: said as something to fix; a
    /// clock ahead of it is fine (and its NTP status a note at most).
    #[test]
    fn a_clock_behind_the_kept_signing_state_is_named() {
        let ahead = deckwatch_link::signing::clock_10us() + 3600 * 100_000;
        match signing_clock(ahead) {
            Finding::Fix(what, how) => {
                assert!(
                    what.contains("clock") && how.contains("behind") && how.contains("3600"),
                    "{how}"
                )
            }
            _ => panic!("a clock an hour behind the kept state passed"),
        }
        assert!(!matches!(signing_clock(0), Finding::Fix(..)));
    }
}
