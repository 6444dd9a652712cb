//! The onboard build for a 64-bit ARM companion computer, run here under
//! Debian's qemu-user: `cargo xtask cross aarch64` builds it and `cargo xtask
//! test` hands this test its folder (`TOWERNAV_AARCH64_BIN`), ONNX
//! Runtime's aarch64 library (`TOWERNAV_AARCH64_ORT`) and qemu's prefix
//! (`TOWERNAV_AARCH64_SYSROOT`). The aarch64 daemon
//! replays a short rendered flight from its images, and its poses are
//! compared with the x86-64 daemon's on the same frames.
//!
//! Run alone (`cargo test`) without those variables it says so and passes:
//! the cross toolchain is the xtask's to install, not a test's.

use std::path::{Path, PathBuf};
use std::process::Command;

use towernav_geometry::{Datum, Geodetic};
use towernav_tests::programs::{run_ok, short_flight, sibling_binary};

/// Frames replayed: enough for the filter to settle, few enough for qemu.
const FRAMES: &str = "45";

/// (seq, position) of each estimate the daemon wrote to `jsonl`.
fn poses(jsonl: &Path) -> Vec<(u64, Geodetic)> {
    let text = std::fs::read_to_string(jsonl).expect("the daemon's JSON lines");
    text.lines()
        .map(|line| {
            let p: serde_json::Value = serde_json::from_str(line).expect("a JSON line");
            let at = Geodetic::new(
                p["lat_deg"].as_f64().expect("lat"),
                p["lon_deg"].as_f64().expect("lon"),
                p["alt_m"].as_f64().expect("alt"),
            )
            .expect("a place");
            (p["seq"].as_u64().expect("seq"), at)
        })
        .collect()
}

#[test]
fn the_aarch64_daemon_under_qemu_replays_a_flight_as_the_x86_64_one_does() {
    let (Some(bin), Some(ort), Some(sysroot)) = (
        std::env::var_os("TOWERNAV_AARCH64_BIN"),
        std::env::var_os("TOWERNAV_AARCH64_ORT"),
        std::env::var_os("TOWERNAV_AARCH64_SYSROOT"),
    ) else {
        eprintln!(
            "skipped: no aarch64 build given (`cargo xtask test` builds one with \
             `cargo xtask cross aarch64` and sets TOWERNAV_AARCH64_BIN, _ORT and _SYSROOT)"
        );
        return;
    };
    let edge_arm = PathBuf::from(bin).join("towernav-edge");
    // An ELF for ARM64 (e_machine 0xB7), not the host's binary by mistake.
    let header = std::fs::read(&edge_arm).expect("the aarch64 daemon");
    assert_eq!(
        header.get(18..20),
        Some(&[0xB7, 0x00][..]),
        "not an aarch64 ELF"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let config = short_flight().join("replay.toml");
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models");
    // The onboard `run`, every frame, as the packaged service runs it.
    let replay = |mut cmd: Command, out: &Path| {
        cmd.arg("run")
            .arg("--config")
            .arg(&config)
            .arg("--model")
            .arg(models.join("towers-int8.onnx"))
            .arg("--type-model")
            .arg(models.join("tower-types-int8.onnx"))
            .args(["--speed", "0", "--max-frames", FRAMES])
            .args(["--listen", &towernav_tests::loopback_endpoint()])
            .arg("--jsonl")
            .arg(out);
        cmd
    };
    let x86_out = dir.path().join("x86_64.jsonl");
    run_ok(&mut replay(
        Command::new(sibling_binary("towernav-edge")),
        &x86_out,
    ));
    let arm_out = dir.path().join("aarch64.jsonl");
    let mut qemu = Command::new("qemu-aarch64");
    // The prefix holds the aarch64 C library and an ARM board's /proc/cpuinfo
    // and /sys CPU lists, which ONNX Runtime's CPU probe reads.
    qemu.arg("-L")
        .arg(&sysroot)
        .arg(&edge_arm)
        .env("ORT_DYLIB_PATH", &ort);
    run_ok(&mut replay(qemu, &arm_out));

    let x86 = poses(&x86_out);
    let arm = poses(&arm_out);
    assert!(x86.len() >= 30, "x86-64 gave {} poses", x86.len());
    let seqs = |p: &[(u64, Geodetic)]| p.iter().map(|q| q.0).collect::<Vec<_>>();
    assert_eq!(
        seqs(&arm),
        seqs(&x86),
        "the two builds fixed different frames"
    );
    let datum = Datum::new(x86[0].1);
    let worst = x86
        .iter()
        .zip(&arm)
        .map(|(a, b)| (datum.to_enu(&a.1) - datum.to_enu(&b.1)).xy().norm())
        .fold(0.0, f64::max);
    eprintln!(
        "aarch64 under qemu against x86-64: {} poses, largest horizontal difference {worst:.4} m",
        arm.len()
    );
    // INT8 kernels differ between instruction sets: boxes may move by a
    // rounding step, and the poses by centimetres, not metres.
    assert!(worst < 0.5, "the builds disagree by {worst:.3} m");
}
