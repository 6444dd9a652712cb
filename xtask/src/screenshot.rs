//! `cargo xtask screenshot`: the ground station's real window under Xvfb,
//! connected to a demo edge on loopback: `docs/ground-station.png` live,
//! `docs/link-lost.png` after the edge was stopped, `docs/landmark-editor.png`
//! on the Landmarks tab.
//!
//! Xvfb comes from Debian's `xvfb` package, installed when missing.

use std::path::Path;
use std::process::{Child, Command, Stdio};

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
    std::fs::create_dir_all(root.join("docs"))?;
    let docs = root.join("docs");
    // Live, then with the edge stopped half-way (the link-lost state), then the editor.
    for (name, tab, edge_for_s, total_s) in [
        ("ground-station.png", "map", f64::INFINITY, seconds),
        ("link-lost.png", "map", seconds, seconds + 8.0),
        ("landmark-editor.png", "landmarks", f64::INFINITY, seconds),
    ] {
        let out = docs.join(name);
        let edge = start_edge(&bin, &towers)?;
        let gs = Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1600x900x24"])
            .arg(bin.join("towernav-gs"))
            .arg("--db")
            .arg(&db)
            .arg("--import")
            .arg(&towers)
            .args(["--connect", EDGE_ENDPOINT, "--tab", tab])
            .arg("--screenshot")
            .arg(&out)
            .args(["--quit-after-s", &total_s.to_string()])
            .spawn()
            .context("starting xvfb-run (the xvfb package)")?;
        shoot(edge, gs, edge_for_s, &out)?;
    }
    Ok(())
}

/// The demo edge, flying paper path 1 in real time with the oracle detector.
fn start_edge(bin: &Path, towers: &Path) -> anyhow::Result<Child> {
    Command::new(bin.join("towernav-edge"))
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
        .arg(towers)
        .stdout(Stdio::null())
        .spawn()
        .context("starting the demo edge")
}

/// Stops the edge after `edge_for_s` (never, for a live picture: the window
/// starts later than this clock), waits for the window's screenshot.
fn shoot(mut edge: Child, mut gs: Child, edge_for_s: f64, out: &Path) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    loop {
        if started.elapsed().as_secs_f64() >= edge_for_s {
            let _ = edge.kill();
            let _ = edge.wait();
        }
        if let Some(status) = gs.try_wait()? {
            let _ = edge.kill();
            let _ = edge.wait();
            if !status.success() {
                bail!("the ground station exited with {status}");
            }
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    if !out.exists() {
        bail!("the ground station quit without writing {}", out.display());
    }
    eprintln!("xtask: wrote {}", out.display());
    Ok(())
}
