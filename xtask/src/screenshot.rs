//! `cargo xtask screenshot`: the ground station's real window under Xvfb,
//! connected to a demo edge on loopback, saved as `docs/ground-station.png`.
//!
//! Xvfb comes from Debian's `xvfb` package, installed when missing.

use std::path::Path;
use std::process::{Command, Stdio};

use anyhow::{Context, bail};

use crate::{build_release, run, target_dir};

/// A loopback port of its own, so a running demo (7447) is not disturbed.
const EDGE_ENDPOINT: &str = "tcp/127.0.0.1:17480";

pub fn screenshot(root: &Path, seconds: f64) -> anyhow::Result<()> {
    let bin = build_release(
        root,
        &["towernav-edge", "towernav-sim", "towernav-ground-station"],
    )?;
    let work = target_dir(root).join("screenshot");
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let towers = work.join("towers.csv");
    run(Command::new(bin.join("towernav-sim"))
        .arg("world")
        .arg("--out")
        .arg(&towers))?;
    let db = work.join("towers.sqlite");
    for stale in [
        db.clone(),
        db.with_extension("sqlite-wal"),
        db.with_extension("sqlite-shm"),
    ] {
        let _ = std::fs::remove_file(stale);
    }
    let mut edge = Command::new(bin.join("towernav-edge"))
        .args([
            "demo",
            "--detector",
            "oracle",
            "--speed",
            "1",
            "--flight",
            "paper-path-1",
            "--listen",
            EDGE_ENDPOINT,
        ])
        .arg("--landmarks")
        .arg(&towers)
        .stdout(Stdio::null())
        .spawn()
        .context("starting the demo edge")?;
    let out = root.join("docs").join("ground-station.png");
    std::fs::create_dir_all(root.join("docs"))?;
    let shot = run(Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x900x24"])
        .arg(bin.join("towernav-gs"))
        .arg("--db")
        .arg(&db)
        .arg("--import")
        .arg(&towers)
        .args(["--connect", EDGE_ENDPOINT])
        .arg("--screenshot")
        .arg(&out)
        .args(["--quit-after-s", &seconds.to_string()]));
    let _ = edge.kill();
    let _ = edge.wait();
    shot?;
    if !out.exists() {
        bail!("the ground station quit without writing {}", out.display());
    }
    eprintln!("xtask: wrote {}", out.display());
    Ok(())
}
