//! The `towernav-edge` binary's refusals: each names what is wrong and how to fix it.

use std::path::PathBuf;
use std::process::Command;

fn edge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_towernav-edge"))
}

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures")
        .join(name)
}

#[test]
fn without_onnx_runtime_the_detector_says_both_ways_to_get_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = edge()
        .args([
            "eval-detector",
            "--worlds",
            "1",
            "--frames-per-world",
            "1",
            "--model",
        ])
        .arg(fixture("fake-v8-towers.onnx"))
        .env("ORT_DYLIB_PATH", dir.path().join("libonnxruntime.so"))
        .current_dir(dir.path())
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cargo xtask setup-ort") && err.contains("ORT_DYLIB_PATH"),
        "{err}"
    );
}

#[test]
fn a_missing_model_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = edge()
        .args(["eval-detector", "--worlds", "1", "--model"])
        .arg(dir.path().join("nope.onnx"))
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("nope.onnx") && err.contains("cannot read"),
        "{err}"
    );
}
