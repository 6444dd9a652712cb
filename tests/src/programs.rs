//! The workspace's own programs, as tests that run them as a user would:
//! the binaries `cargo test --workspace` builds beside the test, commands
//! run to success, and one short rendered flight shared by every test that
//! needs one.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// A sibling binary of the running test's (`target/<profile>/NAME`).
pub fn sibling_binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test's path");
    let path = exe
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>/deps/<test>")
        .join(name);
    assert!(
        path.is_file(),
        "{} is not built: run `cargo test --workspace` (or build it first)",
        path.display()
    );
    path
}

/// Runs `cmd`: whether it succeeded, and its stdout and stderr together.
pub fn output(cmd: &mut Command) -> (bool, String) {
    let out = cmd.output().expect("the command starts");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// Runs `cmd`, which must succeed; its stdout and stderr together.
pub fn run_ok(cmd: &mut Command) -> String {
    let (success, text) = output(cmd);
    assert!(success, "{cmd:?} failed:\n{text}");
    text
}

/// A 5 s pass of the paper's field (`fixtures/arm-pass.toml`, seed 5) as
/// `towernav-sim flight --images` writes it, rendered once per test process;
/// its `replay.toml` is a `towernav-edge run` config.
pub fn short_flight() -> &'static Path {
    static FLIGHT: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, flight) = FLIGHT.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tempdir");
        let flight = dir.path().join("flight");
        let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/arm-pass.toml");
        run_ok(
            Command::new(sibling_binary("towernav-sim"))
                .arg("flight")
                .arg("--plan")
                .arg(&plan)
                .args(["--seed", "5", "--images", "--out"])
                .arg(&flight),
        );
        (dir, flight)
    });
    flight
}
