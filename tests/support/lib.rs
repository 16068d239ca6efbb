//! Helpers shared by the integration tests in `tests/`.

pub mod guard;

pub use guard::{pipeline_output, PipelineGuard};

use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::{Attitude, CameraModel, DeckLayout, Rpy, SceneGeometry};
use deckwatch_sim::MotionSample;

pub use deckwatch_common::stats::ErrorStats;

/// Exact (float64) pixels of the marker centres for a motion sample.
pub fn exact_markers(camera: &CameraModel, deck: &DeckLayout, s: &MotionSample) -> Vec<Option<[f64; 2]>> {
    SceneGeometry {
        attitude: s.attitude.to_matrix(),
        viewpoint: s.viewpoint,
    }
    .project_markers(camera, deck)
}

/// |estimated - true| roll, pitch, yaw in degrees (wrapped).
pub fn rpy_errors_deg(estimate: &Attitude, truth: &Rpy) -> [f64; 3] {
    rpy_error_deg(&estimate.rpy, truth)
}

/// Path of a workspace binary. The first call builds all of the workspace's binaries with the
/// same cargo, profile and target directory as the running test (integration tests of one package
/// cannot name another package's binaries directly). `--tests` makes that build resolve the
/// dependencies' features as `cargo test --workspace` did (dev-dependencies included), so it
/// reuses every library the test build made and only compiles and links the binaries: without
/// it, cargo resolved other features and rebuilt a large part of the workspace inside the
/// first test (docs/history.md, "The newcomer's path").
///
/// `DECKWATCH_TEST_BIN_DIR` names a folder of binaries built beforehand instead (a build with
/// other features, as ci/libcamera.sh makes: a plain `cargo build` here would rebuild them).
pub fn workspace_binary(name: &str) -> std::path::PathBuf {
    if let Some(dir) = std::env::var_os("DECKWATCH_TEST_BIN_DIR") {
        let path = std::path::Path::new(&dir).join(name);
        assert!(
            path.exists(),
            "{} (DECKWATCH_TEST_BIN_DIR) is missing",
            path.display()
        );
        return path;
    }
    static BUILD: std::sync::Once = std::sync::Once::new();
    // .../target/<profile>/deps/<test-binary>
    let exe = std::env::current_exe().expect("test binary path");
    let profile_dir = exe.parent().and_then(|d| d.parent()).expect("target/<profile>");
    BUILD.call_once(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
        let mut cmd = std::process::Command::new(cargo);
        // The variables cargo sets for a running test (CARGO_PKG_NAME, CARGO_MANIFEST_DIR, ...)
        // are not this build's: build scripts that watch them (ring's) would see them change
        // and rebuild everything above them, here and again in the next `cargo test`.
        for (key, _) in std::env::vars_os() {
            let key = key.to_string_lossy();
            let set_for_tests = ["CARGO_PKG_", "CARGO_CRATE_", "CARGO_MANIFEST_", "CARGO_BIN_"]
                .iter()
                .any(|p| key.starts_with(p))
                || [
                    "CARGO_PRIMARY_PACKAGE",
                    "CARGO_TARGET_TMPDIR",
                    "CARGO_RUSTC_CURRENT_DIR",
                    "OUT_DIR",
                ]
                .contains(&key.as_ref());
            if set_for_tests {
                cmd.env_remove(key.as_ref());
            }
        }
        cmd.args([
            "build",
            "--quiet",
            "--workspace",
            "--bins",
            "--tests",
            "--manifest-path",
            manifest,
        ]);
        if profile_dir.file_name().is_some_and(|p| p == "release") {
            cmd.arg("--release");
        }
        let status = cmd.status().expect("run cargo build");
        assert!(status.success(), "cargo build --workspace --bins failed");
    });
    let path = profile_dir.join(name);
    assert!(path.exists(), "{} was not built", path.display());
    path
}

/// A simple reference blob finder for tests (the real detector is the detect crate's): threshold
/// halfway between the darkest and brightest pixel, 4-connected components, then an
/// intensity-weighted centroid over each component's box grown by `pad` pixels, with the median
/// of that box's border subtracted as background.
pub fn reference_blobs(
    img: deckwatch_common::GrayView<'_>,
    min_area: usize,
    pad: usize,
) -> Vec<deckwatch_detect::Blob> {
    let (w, h) = (img.width(), img.height());
    let (mut lo, mut hi) = (255u8, 0u8);
    for y in 0..h {
        for &v in img.row(y) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    let threshold = ((lo as u16 + hi as u16) / 2) as u8;
    if hi.saturating_sub(lo) < 40 {
        return Vec::new(); // no contrast, no markers
    }
    let mut seen = vec![false; w * h];
    let mut blobs = Vec::new();
    let mut stack = Vec::new();
    for y0 in 0..h {
        for x0 in 0..w {
            if seen[y0 * w + x0] || img.get(x0, y0) <= threshold {
                continue;
            }
            // Flood fill one component.
            let (mut bx0, mut by0, mut bx1, mut by1, mut area) = (x0, y0, x0, y0, 0usize);
            seen[y0 * w + x0] = true;
            stack.push((x0, y0));
            while let Some((x, y)) = stack.pop() {
                area += 1;
                bx0 = bx0.min(x);
                by0 = by0.min(y);
                bx1 = bx1.max(x);
                by1 = by1.max(y);
                let mut visit = |nx: usize, ny: usize| {
                    if !seen[ny * w + nx] && img.get(nx, ny) > threshold {
                        seen[ny * w + nx] = true;
                        stack.push((nx, ny));
                    }
                };
                if x > 0 {
                    visit(x - 1, y);
                }
                if x + 1 < w {
                    visit(x + 1, y);
                }
                if y > 0 {
                    visit(x, y - 1);
                }
                if y + 1 < h {
                    visit(x, y + 1);
                }
            }
            if area < min_area {
                continue;
            }
            let (gx0, gy0) = (bx0.saturating_sub(pad), by0.saturating_sub(pad));
            let (gx1, gy1) = ((bx1 + pad).min(w - 1), (by1 + pad).min(h - 1));
            let mut border = Vec::new();
            for x in gx0..=gx1 {
                border.push(img.get(x, gy0));
                border.push(img.get(x, gy1));
            }
            for y in gy0..=gy1 {
                border.push(img.get(gx0, y));
                border.push(img.get(gx1, y));
            }
            border.sort_unstable();
            let background = border[border.len() / 2] as f64;
            let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
            for y in gy0..=gy1 {
                for x in gx0..=gx1 {
                    let wgt = (img.get(x, y) as f64 - background).max(0.0);
                    sw += wgt;
                    su += wgt * x as f64;
                    sv += wgt * y as f64;
                }
            }
            if sw > 0.0 {
                blobs.push(deckwatch_detect::Blob {
                    u: su / sw,
                    v: sv / sw,
                    area: area as f64,
                });
            }
        }
    }
    blobs
}

/// The Python interpreter of the test peers that can import `module`: `DECKWATCH_PYTHON`, the
/// virtual environment `ci/peers.sh` makes (~/.cache/deckwatch-venv), or python3.
pub fn peer_python(module: &str) -> std::path::PathBuf {
    use std::path::{Path, PathBuf};
    let candidates = [
        std::env::var_os("DECKWATCH_PYTHON").map(PathBuf::from),
        std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/deckwatch-venv/bin/python3")),
        Some(PathBuf::from("python3")),
    ];
    for p in candidates.into_iter().flatten() {
        let ok = std::process::Command::new(&p)
            .args(["-c", &format!("import {module}")])
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            return p;
        }
    }
    panic!("no python3 with {module}: run ci/peers.sh (or set DECKWATCH_PYTHON)");
}

/// Writes `key` to `path` readable by its owner alone (mode 0600), as the link wants a MAVLink
/// signing key.
pub fn write_private_key(path: &std::path::Path, key: &[u8]) {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .and_then(|mut f| f.write_all(key))
        .expect("the key file");
}

/// Runs `deckwatch ARGS` and returns its standard output; a failure is the test's, with the
/// command's standard error.
pub fn run_deckwatch(args: &[&str]) -> String {
    let out = std::process::Command::new(workspace_binary("deckwatch"))
        .args(args)
        .output()
        .expect("deckwatch runs");
    assert!(
        out.status.success(),
        "deckwatch {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

/// The whitespace-separated fields of `deckwatch eval`'s table row for a recording and
/// estimator (recording, estimator, frames, estimated, missed, no-deck attitudes, RMSE roll
/// pitch yaw, max ...); a missing row fails the test with the table.
pub fn eval_table_row<'a>(table: &'a str, recording: &str, estimator: &str) -> Vec<&'a str> {
    table
        .lines()
        .find(|l| l.starts_with(recording) && l.split_whitespace().nth(1) == Some(estimator))
        .unwrap_or_else(|| panic!("{recording} {estimator} in\n{table}"))
        .split_whitespace()
        .collect()
}

/// rerun-sdk's `rerun` command (the venv of `ci/peers.sh`, else the one on PATH), version 0.36.3.
/// Asserts that rerun's own reader (`rerun rrd verify`) accepts `rrd`.
pub fn assert_rrd_verifies(rrd: &std::path::Path) {
    let verify = std::process::Command::new(peer_rerun())
        .args(["rrd", "verify"])
        .arg(rrd)
        .output()
        .unwrap();
    assert!(
        verify.status.success(),
        "{}: {}",
        rrd.display(),
        String::from_utf8_lossy(&verify.stderr)
    );
}

pub fn peer_rerun() -> std::path::PathBuf {
    let python = peer_python("rerun");
    let beside = python.with_file_name("rerun");
    let rerun = if beside.exists() { beside } else { "rerun".into() };
    let version = std::process::Command::new(&rerun)
        .arg("--version")
        .output()
        .unwrap_or_else(|e| panic!("{}: {e} (run ci/peers.sh)", rerun.display()));
    let text = String::from_utf8_lossy(&version.stdout);
    assert!(
        text.contains("0.36.3"),
        "{}: {text} (need rerun-sdk 0.36.3)",
        rerun.display()
    );
    rerun
}

/// The interpreter with pymavlink (the MAVLink peers of the link's tests).
pub fn pymavlink_python() -> std::path::PathBuf {
    peer_python("pymavlink")
}

/// A UDP port free on the loopback now (the link's `udpin` in a test).
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .expect("a free UDP port")
        .port()
}

/// A CSV file without quoted fields (the decisions CSV) as rows of column -> value.
pub fn read_csv_rows(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap_or_default()
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}
