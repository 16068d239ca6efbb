//! Detector speed on 3280x2464 simulator frames (rpi-v2, realistic noise and blur, ship motion),
//! one thread: `cargo bench -p deckwatch-detect --bench detect`. Tracked detection also at
//! 640x480 (a Pi's 30 fps stream), where the discs are small (radius about 5 px from 5 m), and
//! there through a lens blurred to a deviation of 2.5 px (the discs measured by their blurred
//! pass, `measure/blurred.rs`), and at 1640x1232 (the Pi's other 30 fps stream) through a lens
//! blurred to 3 px (large discs, the same pass where the pattern leaves it room).
//!
//! Criterion measures full-frame and tracked detection; then, in the same run, a plain timing
//! loop measures the detector and the OpenCV baseline (`opencv_baseline.py`: threshold +
//! connectedComponentsWithStats + moments, one thread) on the same frames and prints the ratio.
//! The baseline needs `pip install opencv-python-headless numpy`; without it that part is skipped
//! with a message.

use criterion::Criterion;
use deckwatch_common::stats::Percentiles;
use deckwatch_common::{CameraModel, DeckLayout, GrayImage};
use deckwatch_detect::{Detector, DetectorConfig};
use deckwatch_sim::{FrameSimulator, RenderOptions, Renderer, Scenario};
use std::time::Instant;

fn render_frames(cam: CameraModel, n: u64) -> Vec<GrayImage> {
    render_frames_with(cam, n, RenderOptions::realistic())
}

fn render_frames_with(cam: CameraModel, n: u64, options: RenderOptions) -> Vec<GrayImage> {
    let r = Renderer::new(cam, DeckLayout::paper(), options, 3).unwrap();
    let mut sim = FrameSimulator::new(Scenario::Ship.profile(3, 1.0), r, 1.0, 0.0, 1, 3).unwrap();
    (0..n)
        .map(|k| {
            let mut img = GrayImage::new(cam.width as usize, cam.height as usize);
            sim.render_frame(k, &mut img.view_mut()).unwrap();
            img
        })
        .collect()
}

/// `iters` tracked detections, each after a full-frame one on the same frame (not timed) that
/// sets the tracking state.
fn tracked(det: &mut Detector, frames: &[GrayImage], k: &mut usize, iters: u64) -> std::time::Duration {
    let mut total = std::time::Duration::ZERO;
    for _ in 0..iters {
        *k = (*k + 1) % frames.len();
        det.detect_full(frames[*k].view());
        let t0 = Instant::now();
        let set = det.detect(frames[*k].view());
        total += t0.elapsed();
        assert!(set.tracked.get());
    }
    total
}

fn main() {
    let cam = CameraModel::rpi_v2();
    let deck = DeckLayout::paper();
    let frames = render_frames(cam, 8);
    let mut det = Detector::new(cam, deck, DetectorConfig::for_camera(&cam, &deck));

    let mut c = Criterion::default().sample_size(50).configure_from_args();
    let small_cam = cam.scaled_to(640, 480);
    let small_frames = render_frames(small_cam, 8);
    let mut small_det = Detector::new(small_cam, deck, DetectorConfig::for_camera(&small_cam, &deck));
    c.bench_function("detect_640x480/tracked", |b| {
        let mut k = 0;
        b.iter_custom(|iters| tracked(&mut small_det, &small_frames, &mut k, iters))
    });
    let blurred_frames = render_frames_with(
        small_cam,
        8,
        RenderOptions {
            optical_blur_px: 2.5,
            ..RenderOptions::realistic()
        },
    );
    c.bench_function("detect_640x480_blurred/tracked", |b| {
        let mut k = 0;
        b.iter_custom(|iters| tracked(&mut small_det, &blurred_frames, &mut k, iters))
    });
    let mid_cam = cam.scaled_to(1640, 1232);
    let mid_blurred = render_frames_with(
        mid_cam,
        8,
        RenderOptions {
            optical_blur_px: 3.0,
            ..RenderOptions::realistic()
        },
    );
    let mut mid_det = Detector::new(mid_cam, deck, DetectorConfig::for_camera(&mid_cam, &deck));
    c.bench_function("detect_1640x1232_blurred/tracked", |b| {
        let mut k = 0;
        b.iter_custom(|iters| tracked(&mut mid_det, &mid_blurred, &mut k, iters))
    });
    let mut group = c.benchmark_group("detect_3280x2464");
    let mut k = 0;
    group.bench_function("full_frame", |b| {
        b.iter(|| {
            k = (k + 1) % frames.len();
            det.detect_full(frames[k].view())
        })
    });
    // Tracked: the previous frame's markers are known (here: the same frame's), so only the
    // regions around them are searched.
    let mut k = 0;
    group.bench_function("tracked", |b| {
        b.iter_custom(|iters| tracked(&mut det, &frames, &mut k, iters))
    });
    group.finish();
    c.final_summary();

    // Side by side with OpenCV, same frames, same run.
    let mut ours = Vec::new();
    for _ in 0..10 {
        for f in &frames {
            let t0 = Instant::now();
            let set = det.detect_full(f.view());
            ours.push(t0.elapsed().as_secs_f64() * 1e3);
            assert_eq!(set.count, 9);
        }
    }
    let p = Percentiles::of(&mut ours).unwrap();
    println!(
        "deckwatch full frame: p50 {:.3} ms p90 {:.3} ms p99 {:.3} ms (n {})",
        p.p50, p.p90, p.p99, p.n
    );
    let dir = std::env::temp_dir().join(format!("deckwatch-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (i, f) in frames.iter().enumerate() {
        std::fs::write(dir.join(format!("frame_{i:02}.raw")), &f.data).unwrap();
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/opencv_baseline.py");
    let out = std::process::Command::new("python3")
        .args([script, dir.to_str().unwrap(), "3280", "2464", "150", "10"])
        .output();
    let _ = std::fs::remove_dir_all(&dir);
    match out {
        Ok(o) if o.status.success() => {
            let text = String::from_utf8_lossy(&o.stdout);
            println!("opencv baseline: {}", text.trim());
            let p50: f64 = text
                .split("\"p50_ms\": ")
                .nth(1)
                .and_then(|s| s.split([',', '}']).next())
                .and_then(|s| s.trim().parse().ok())
                .unwrap_or(f64::NAN);
            println!("ratio (opencv p50 / deckwatch p50): {:.1}x", p50 / p.p50);
        }
        Ok(o) => println!(
            "opencv baseline skipped: {}",
            String::from_utf8_lossy(&o.stderr).trim()
        ),
        Err(e) => println!("opencv baseline skipped: cannot run python3: {e}"),
    }
}
