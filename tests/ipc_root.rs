//! Another local user against the pipeline's shared memory (issue 72, item 6). The test makes a
//! second user (`useradd`; it needs root, and says so and does nothing else without it), who:
//!
//! - squats, before the pipeline starts, iceoryx2's default root `/tmp/iceoryx2` and the folder
//!   deckwatch would use without a runtime directory, open to everyone;
//! - while the pipeline runs (its runtime directory private, as systemd's `RuntimeDirectory=` or
//!   a login's `XDG_RUNTIME_DIR` give it), tries to write into it: a file in its iceoryx2 root
//!   and its services folder, every shared-memory segment of its domain, every event socket.
//!
//! Every attempt is denied, nothing of the pipeline goes to the squatted folders, and the pipeline
//! runs to its end. Without a runtime directory, a root the other user made first is refused
//! with an error that says so (a denial of service, never a substitution).

use deckwatch_tests::{guard::walk, workspace_binary, PipelineGuard};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// A local user made for the test, removed with it.
struct LocalUser(String);

impl LocalUser {
    /// None (said) when this test cannot make users: not root.
    fn make() -> Option<Self> {
        // SAFETY: geteuid has no preconditions and cannot fail.
        if unsafe { libc::geteuid() } != 0 {
            eprintln!("ipc_root: not root, cannot make a second local user: nothing tested");
            return None;
        }
        let name = format!("dwsq{}", std::process::id());
        let made = Command::new("useradd")
            .args([
                "--system",
                "--no-create-home",
                "--shell",
                "/usr/sbin/nologin",
                &name,
            ])
            .status()
            .expect("useradd");
        assert!(made.success(), "useradd {name}");
        Some(Self(name))
    }

    /// The squatter (tests/peers/squatter.py, copied to `dir`) run as this user.
    fn squatter(&self, dir: &Path, args: &[&str]) -> serde_json::Value {
        let out = Command::new("runuser")
            .args(["-u", &self.0, "--", "/usr/bin/python3"])
            .arg(dir.join("squatter.py"))
            .args(args)
            .current_dir(dir)
            .output()
            .expect("runuser");
        assert!(
            out.status.success(),
            "the squatter failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).expect("the squatter's JSON")
    }
}

impl Drop for LocalUser {
    fn drop(&mut self) {
        let _ = Command::new("userdel").arg(&self.0).status();
    }
}

/// `mode` on `path`.
fn chmod(path: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
}

#[test]
fn another_user_can_neither_take_the_iceoryx2_root_nor_write_into_a_running_pipeline() {
    let Some(user) = LocalUser::make() else {
        return;
    };
    // A temporary folder like /tmp (everyone may make folders in it) and a private runtime
    // directory like /run/user/UID.
    let tmp = tempfile::tempdir().unwrap();
    chmod(tmp.path(), 0o1777);
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/squatter.py"),
        tmp.path().join("squatter.py"),
    )
    .unwrap();
    chmod(&tmp.path().join("squatter.py"), 0o644);
    let runtime = tempfile::tempdir().unwrap();
    chmod(runtime.path(), 0o700);
    // SAFETY: geteuid has no preconditions and cannot fail.
    let fallback = tmp.path().join(format!("dw-ipc-{}", unsafe { libc::geteuid() }));
    let iceoryx2_default = PathBuf::from("/tmp/iceoryx2");
    let fallback_text = fallback.display().to_string();
    let squatted_default = !iceoryx2_default.exists();
    let mut squat = vec![fallback_text.as_str()];
    if squatted_default {
        squat.push("/tmp/iceoryx2");
    }
    let mut args = vec!["--squat"];
    args.extend(squat.iter().copied());
    let s = user.squatter(tmp.path(), &args);
    assert!(s["squatted"].as_array().unwrap().len() == squat.len(), "{s}");

    // The pipeline with its private runtime directory, the squatter writing at it meanwhile.
    let domain = format!("t{}-squat", std::process::id());
    let decisions = runtime.path().join("decisions.csv");
    let deckwatch = || {
        let mut c = Command::new(workspace_binary("deckwatch"));
        c.env_remove("RUNTIME_DIRECTORY")
            .env("TMPDIR", tmp.path())
            .args([
                "run", "--quiet", "--frames", "120", "--rate", "10", "--rerun", "off",
            ])
            .args(["--domain", &domain])
            .arg("--decisions")
            .arg(&decisions);
        c
    };
    let mut pipeline = PipelineGuard::spawn(
        deckwatch()
            .env("XDG_RUNTIME_DIR", runtime.path())
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
        &domain,
    );
    let start = std::time::Instant::now();
    while std::fs::read_to_string(&decisions).map_or(0, |t| t.lines().count()) < 5 {
        assert!(start.elapsed().as_secs() < 120, "no decisions");
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let root = runtime.path().join("dw-ipc");
    let prefix = deckwatch_runtime::bus::domain_prefix(&domain);
    let attack = user.squatter(
        tmp.path(),
        &[
            "--attack-root",
            &root.display().to_string(),
            "--shm-prefix",
            &prefix,
        ],
    );
    let out = pipeline.wait_with_output();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "the pipeline under attack failed:\n{stderr}"
    );
    assert_eq!(attack["written"], serde_json::json!([]), "{attack}");
    let denied = attack["denied"].as_array().unwrap();
    // The root's file and service file and its listing, and each of the domain's segments.
    assert!(denied.len() > 3, "{attack}");
    assert!(
        denied.iter().any(|d| d.as_str().unwrap().contains("/dev/shm/")),
        "no segment tried: {attack}"
    );
    let rows = std::fs::read_to_string(&decisions).unwrap().lines().count() - 1;
    assert!(rows >= 100, "{rows} decisions");
    // Nothing of the pipeline in the squatted folders.
    for folder in [fallback.clone(), iceoryx2_default.clone()] {
        let ours: Vec<String> = walk(&folder)
            .into_iter()
            .filter(|n| n.contains(&prefix))
            .collect();
        assert!(ours.is_empty(), "{}: {ours:?}", folder.display());
    }
    println!(
        "the other user squatted {squat:?} and was denied {} writes into the running pipeline",
        denied.len()
    );

    // Without a runtime directory: the root the other user made first is refused, said.
    let refused = deckwatch().env_remove("XDG_RUNTIME_DIR").output().unwrap();
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "started in another user's folder");
    assert!(
        stderr.contains(&fallback_text) && stderr.contains("another user made it first"),
        "{stderr}"
    );
    if squatted_default {
        let _ = std::fs::remove_dir_all(&iceoryx2_default);
    }
}
