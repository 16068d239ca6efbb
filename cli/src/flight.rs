//! Flight recordings on the command line: `deckwatch replay`, `diff`, `convert`, `recover`.

use crate::launch::{launch, print_report, LaunchOptions};
use crate::pipeline::load;
use deckwatch_capture::source::is_flight_recording;
use deckwatch_common::messages::FrameSource;
use deckwatch_flight::diff::{diff, DiffOptions, StageDiff};
use deckwatch_flight::reader::FlightMessages;
use deckwatch_flight::{FlightWriter, FrameEncoding, RecordCompression, TimeBase, WriterOptions};
use deckwatch_runtime::config::PipelineConfig;
use deckwatch_runtime::resim::{recorded_config, resimulate};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct ReplayArgs {
    /// The flight recording (FILE.mcap), or a recording folder.
    recording: PathBuf,
    /// Frames per second (default: the recorded rate; 0: as fast as possible).
    #[arg(long)]
    rate: Option<f64>,
    /// Instead of running the processes: re-simulate the flight in this process on its
    /// recorded timing (each stage sees what it saw in the flight), write the stages' outputs
    /// to this MCAP file and compare them with the recorded ones.
    #[arg(long, value_name = "OUT.mcap")]
    resim: Option<PathBuf>,
    /// Pipeline configuration (default: the one the flight was recorded with, for --resim; the
    /// defaults otherwise).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Record the replay (another flight recording).
    #[arg(long, value_name = "FILE.mcap")]
    record: Option<PathBuf>,
    /// iceoryx2 domain.
    #[arg(long)]
    domain: Option<String>,
    /// No live status line.
    #[arg(long)]
    quiet: bool,
    /// Folder of the stage binaries (default: beside this executable).
    #[arg(long)]
    stage_dir: Option<PathBuf>,
}

pub fn replay(a: ReplayArgs) -> Result<(), String> {
    if let Some(out) = &a.resim {
        return resim(&a.recording, out, a.config.as_deref());
    }
    let (mut c, file) = load(a.config.as_deref())?;
    c.source.kind = FrameSource::Replay;
    c.replay.recording = Some(a.recording.clone());
    c.replay.rate_hz = a.rate;
    if let Some(d) = a.domain {
        c.bus.domain = d;
    }
    if let Some(p) = a.record {
        c.record.path = Some(p);
    }
    let options = LaunchOptions {
        status: !a.quiet,
        decisions_csv: None,
        stage_dir: a.stage_dir,
        ..Default::default()
    };
    print_report(&launch(&c, &file, &options)?);
    Ok(())
}

fn resim(input: &Path, out: &Path, config: Option<&Path>) -> Result<(), String> {
    let config: PipelineConfig = match config {
        Some(p) => {
            let c = PipelineConfig::load(p).map_err(|e| e.to_string())?;
            c.validate(&p.display().to_string()).map_err(|e| e.to_string())?;
            c
        }
        None => match recorded_config(input).map_err(|e| e.to_string())? {
            Some(c) => c,
            None => {
                errln!(
                    "{}: no pipeline.toml attached; re-simulating with the defaults",
                    input.display()
                );
                PipelineConfig::default()
            }
        },
    };
    let recorded = FlightMessages::read(input).map_err(|e| e.to_string())?;
    if let Some(why) = &recorded.ended_early {
        errln!("{}: the recording ends early ({why})", input.display());
    }
    let r = resimulate(input, &recorded, &config).map_err(|e| e.to_string())?;
    if !r.gaps.is_empty() {
        errln!(
            "{} frames detect processed have no pixels in the recording (first: {}); detect's tracking may differ after them",
            r.gaps.len(),
            r.gaps[0]
        );
    }
    let mut w = FlightWriter::create(
        out,
        WriterOptions {
            compression: RecordCompression::Zstd,
            time_base: recorded_time_base(&recorded),
            ..Default::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let note = [
        ("resimulated_from".to_string(), input.display().to_string()),
        ("version".to_string(), deckwatch_flight::VERSION.to_string()),
    ];
    w.write_metadata("deckwatch.resim", note.into())
        .map_err(|e| e.to_string())?;
    w.attach(
        "pipeline.toml",
        "application/toml",
        config.to_toml().as_bytes(),
        0,
    )
    .map_err(|e| e.to_string())?;
    for h in &recorded.frames {
        w.write(h).map_err(|e| e.to_string())?;
    }
    for m in &r.markers {
        w.write(m).map_err(|e| e.to_string())?;
    }
    for m in &r.attitudes {
        w.write(m).map_err(|e| e.to_string())?;
    }
    for m in &r.decisions {
        w.write(m).map_err(|e| e.to_string())?;
    }
    w.finish().map_err(|e| e.to_string())?;
    outln!(
        "re-simulated {} frames: {} marker sets, {} attitudes, {} decisions -> {}",
        recorded.frames.len(),
        r.markers.len(),
        r.attitudes.len(),
        r.decisions.len(),
        out.display()
    );
    let resimulated = FlightMessages {
        markers: r.markers,
        attitudes: r.attitudes,
        decisions: r.decisions,
        ..Default::default()
    };
    let stages = diff(&recorded, &resimulated, DiffOptions::default());
    print_diff(&stages, "recorded", "re-simulated");
    Ok(())
}

/// The recording's monotonic-to-UNIX offset (its `deckwatch.clock` metadata), so a derived file
/// shows the same times.
fn recorded_time_base(m: &FlightMessages) -> TimeBase {
    let offset = m
        .metadata
        .get("deckwatch.clock")
        .and_then(|c| c.get("unix_minus_monotonic_ns"))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    TimeBase {
        unix_minus_monotonic_ns: offset,
    }
}

#[derive(clap::Args)]
pub struct DiffArgs {
    a: PathBuf,
    b: PathBuf,
    /// Compare the stage times too (left out by default: no two runs take the same
    /// microseconds).
    #[arg(long)]
    with_times: bool,
    /// Differing frames listed per stage (0: all).
    #[arg(long, default_value_t = 10)]
    list: usize,
}

/// `deckwatch diff`: exit status 0 when the outputs agree, 1 when they part.
pub fn diff_command(a: DiffArgs) -> Result<bool, String> {
    let ma = FlightMessages::read(&a.a).map_err(|e| e.to_string())?;
    let mb = FlightMessages::read(&a.b).map_err(|e| e.to_string())?;
    let stages = diff(
        &ma,
        &mb,
        DiffOptions {
            with_times: a.with_times,
        },
    );
    let name = |p: &Path| p.display().to_string();
    print_diff_listing(&stages, &name(&a.a), &name(&a.b), a.list);
    Ok(stages.iter().all(StageDiff::same))
}

fn print_diff(stages: &[StageDiff], a: &str, b: &str) {
    print_diff_listing(stages, a, b, 10);
}

fn print_diff_listing(stages: &[StageDiff], a: &str, b: &str, list: usize) {
    outln!("A = {a}\nB = {b}");
    for d in stages {
        if d.same() {
            outln!(
                "{:<8} identical: {} outputs, every field bit for bit",
                d.stage,
                d.compared
            );
            continue;
        }
        outln!(
            "{:<8} {} compared, {} identical, {} differ; {} only in A, {} only in B",
            d.stage,
            d.compared,
            d.identical,
            d.differing.len(),
            d.only_a.len(),
            d.only_b.len()
        );
        let shown = if list == 0 {
            d.differing.len()
        } else {
            list.min(d.differing.len())
        };
        if shown > 0 {
            let frames: Vec<String> = d.differing[..shown].iter().map(u64::to_string).collect();
            let more = if shown < d.differing.len() { " ..." } else { "" };
            outln!("         differing frames: {}{more}", frames.join(" "));
        }
        if let Some((seq, fields)) = &d.first {
            outln!("         first at frame {seq}:");
            for f in fields.iter().take(12) {
                outln!("           {}: A {} B {}", f.path, f.a, f.b);
            }
            if fields.len() > 12 {
                outln!("           ... {} more fields", fields.len() - 12);
            }
        }
        let mut largest: Vec<(&String, &f64)> = d.largest.iter().collect();
        largest.sort_by(|x, y| y.1.total_cmp(x.1));
        for (path, v) in largest.iter().take(8) {
            outln!("         largest |A - B| of {path}: {v:.3e}");
        }
        for (path, n) in d.changed.iter().take(8) {
            outln!("         {path}: differs in {n} frames");
        }
    }
}

#[derive(clap::Args)]
pub struct ConvertArgs {
    /// A recording folder (-> MCAP) or a flight recording FILE.mcap (-> folder).
    input: PathBuf,
    /// The new MCAP file, or the new recording folder.
    output: PathBuf,
    /// Images in the MCAP (folder -> MCAP): `raw`, `png` (lossless) or `jpeg`.
    #[arg(long, default_value = "png")]
    frames: String,
    /// Largest total of frame bytes held (MCAP -> folder), MiB.
    #[arg(long, default_value_t = 4096)]
    max_mib: u64,
}

pub fn convert(a: ConvertArgs) -> Result<(), String> {
    if is_flight_recording(&a.input) {
        let c = deckwatch_flight::convert::mcap_to_folder(&a.input, &a.output, a.max_mib << 20)
            .map_err(|e| e.to_string())?;
        if let Some(why) = c.ended_early {
            errln!("{}: ends early ({why})", a.input.display());
        }
        outln!("{} frames -> {}", c.frames, a.output.display());
        return Ok(());
    }
    let encoding = match a.frames.as_str() {
        "raw" => FrameEncoding::Raw,
        "png" => FrameEncoding::Png,
        "jpeg" => FrameEncoding::Jpeg,
        other => return Err(format!("--frames: unknown `{other}` (raw, png, jpeg)")),
    };
    let n = folder_to_mcap(&a.input, &a.output, encoding)?;
    outln!("{n} frames -> {}", a.output.display());
    Ok(())
}

/// A recording folder as a flight recording: every frame through capture's own replay source
/// (so the headers are what a replay would publish), on the recording's timestamps.
pub fn folder_to_mcap(dir: &Path, out: &Path, encoding: FrameEncoding) -> Result<u64, String> {
    let mut c = PipelineConfig::default();
    c.source.kind = FrameSource::Replay;
    c.replay.recording = Some(dir.to_path_buf());
    c.replay.rate_hz = Some(0.0);
    c.replay.preload = false;
    let mut source = c.capture().open().map_err(|e| e.to_string())?;
    let mut w = FlightWriter::create(
        out,
        WriterOptions {
            compression: RecordCompression::Zstd,
            ..Default::default()
        },
    )
    .map_err(|e| e.to_string())?;
    w.write_metadata(
        "deckwatch",
        [
            ("version".to_string(), deckwatch_flight::VERSION.to_string()),
            ("source".to_string(), "replay".to_string()),
            ("converted_from".to_string(), dir.display().to_string()),
        ]
        .into(),
    )
    .map_err(|e| e.to_string())?;
    let mut pixels = vec![0u8; source.frame_bytes()];
    let mut written = 0u64;
    let mut drops = deckwatch_common::messages::DropCounts::default();
    let n = source.len().unwrap_or(0);
    for k in 0..n {
        let mut header = deckwatch_runtime::stages::capture::new_header(&source, written, drops);
        let width = header.width as usize;
        let f = match source.capture(k, &mut pixels, width) {
            Ok(f) => f,
            Err(e) => {
                errln!("frame {k}: {e}; skipped");
                drops.bad_frames += 1;
                continue;
            }
        };
        deckwatch_runtime::stages::capture::complete_header(&mut header, &f);
        // The recording's own clock: the file shows the recording's times.
        header.stamp.times.captured_ns = f.source_timestamp_ns;
        header.stamp.times.published_ns = f.source_timestamp_ns;
        if written == 0 {
            w.write_calibration(&header.context.camera, f.source_timestamp_ns)
                .map_err(|e| e.to_string())?;
        }
        w.write(&header).map_err(|e| e.to_string())?;
        w.write_frame(&header, &pixels, encoding, 90)
            .map_err(|e| e.to_string())?;
        written += 1;
    }
    w.finish().map_err(|e| e.to_string())?;
    Ok(written)
}

#[derive(clap::Args)]
pub struct RecoverArgs {
    /// The flight recording of a recorder that was killed.
    input: PathBuf,
    /// The complete file to write.
    output: PathBuf,
}

pub fn recover(a: RecoverArgs) -> Result<(), String> {
    let r = deckwatch_flight::convert::recover(
        &a.input,
        &a.output,
        WriterOptions {
            compression: RecordCompression::Zstd,
            ..Default::default()
        },
    )
    .map_err(|e| e.to_string())?;
    match r.ended_early {
        Some(why) => outln!(
            "{} messages recovered into {} ({} ended early: {why})",
            r.messages,
            a.output.display(),
            a.input.display()
        ),
        None => outln!(
            "{} messages copied into {} ({} was complete)",
            r.messages,
            a.output.display(),
            a.input.display()
        ),
    }
    Ok(())
}
