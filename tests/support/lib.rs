//! Helpers shared by the integration tests in `tests/`.

use deckwatch_capture::MotionSample;
use deckwatch_common::rotation::rpy_error_deg;
use deckwatch_common::{Attitude, CameraModel, DeckLayout, Rpy, SceneGeometry};

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
/// cannot name another package's binaries directly).
pub fn workspace_binary(name: &str) -> std::path::PathBuf {
    static BUILD: std::sync::Once = std::sync::Once::new();
    // .../target/<profile>/deps/<test-binary>
    let exe = std::env::current_exe().expect("test binary path");
    let profile_dir = exe.parent().and_then(|d| d.parent()).expect("target/<profile>");
    BUILD.call_once(|| {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
        let mut cmd = std::process::Command::new(cargo);
        cmd.args([
            "build",
            "--quiet",
            "--workspace",
            "--bins",
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
