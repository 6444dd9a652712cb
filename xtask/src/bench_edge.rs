//! `cargo xtask bench-edge`: the edge daemon end to end on 1280x720 camera
//! frames with the shipped detector, on this machine's cores.
//!
//! The simulator renders a flight to JPEG once (`target/bench-edge`, with its
//! attitude log, towers and `replay.toml`); the daemon then reads them as a
//! camera (image folder, attitude from the CSV log), so rendering is not timed.
//! Two runs: as fast as it goes (throughput, peak RSS), then paced at 30 Hz
//! for 40 s (frame-to-publish latency p50/p99, dropped frames).

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use anyhow::Context;

use crate::{build_release, run, target_dir};

pub fn bench_edge(root: &Path, ort: Option<&Path>) -> anyhow::Result<()> {
    let ort = ort.context("the bench needs ONNX Runtime")?;
    let bin = build_release(root, &["towernav-edge", "towernav-sim"])?;
    let work = target_dir(root).join("bench-edge");
    let config = work.join("replay.toml");
    if !config.exists() {
        run(Command::new(bin.join("towernav-sim"))
            .args(["flight", "--preset", "paper-path-1", "--images", "--out"])
            .arg(&work))?;
    }
    let edge = |speed: &str, port: u16| {
        let mut cmd = Command::new(bin.join("towernav-edge"));
        cmd.arg("run")
            .arg("--config")
            .arg(&config)
            .args(["--speed", speed])
            .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
            .env("ORT_DYLIB_PATH", ort)
            .env("RUST_LOG", "warn");
        cmd
    };
    eprintln!("xtask: throughput: every frame, as fast as the daemon goes");
    run(&mut edge("0", 17465))?;
    eprintln!("xtask: latency: frames paced at 30 Hz for 40 s");
    let mut paced = edge("1", 17466).spawn().context("starting the paced run")?;
    std::thread::sleep(Duration::from_secs(40));
    // SIGINT: the daemon finishes its queued frames and prints its summary.
    run(Command::new("kill").args(["-INT", &paced.id().to_string()]))?;
    let status = paced.wait()?;
    anyhow::ensure!(status.success(), "the paced run failed with {status}");
    Ok(())
}
