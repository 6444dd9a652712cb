//! `cargo xtask screenshot`: the ground station's real window under Xvfb,
//! connected to a demo edge on loopback: `docs/ground-station.png` live,
//! `docs/link-lost.png` after the edge was stopped, `docs/landmark-editor.png`
//! on the Landmarks tab, and `docs/fix-lost-link-lost.png`: two UAVs, one
//! flying away from the towers (its link up, its fix lost) and one whose edge
//! was stopped (its link lost).
//!
//! Xvfb comes from Debian's `xvfb` package, installed when missing.

use std::path::Path;
use std::process::{Child, Command, Stdio};

use anyhow::{Context, bail};

use crate::{build_release, run, target_dir};

/// Loopback ports of their own, so a running demo (7447) is not disturbed.
const EDGE_ENDPOINT: &str = "tcp/127.0.0.1:17480";
const SECOND_EDGE_ENDPOINT: &str = "tcp/127.0.0.1:17481";

/// One demo edge of a screenshot.
struct Edge<'a> {
    uav: &'a str,
    /// A flight preset or plan file.
    flight: &'a str,
    speed: f64,
    endpoint: &'a str,
    /// Stopped after this many seconds (never: `INFINITY`).
    stop_after_s: f64,
}

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
    let leave = root
        .join("tests")
        .join("fixtures")
        .join("leave-and-return.toml");
    let leave = leave.display().to_string();
    let one = |stop_after_s| {
        vec![Edge {
            uav: "uav1",
            flight: "paper-path-1",
            speed: 1.0,
            endpoint: EDGE_ENDPOINT,
            stop_after_s,
        }]
    };
    // Live, then with the edge stopped half-way (the link-lost state), then
    // the editor, then a lost fix (link up) beside a lost link.
    let shots: [(&str, &str, Vec<Edge>, f64); 4] = [
        ("ground-station.png", "map", one(f64::INFINITY), seconds),
        ("link-lost.png", "map", one(seconds), seconds + 8.0),
        (
            "landmark-editor.png",
            "landmarks",
            one(f64::INFINITY),
            seconds,
        ),
        (
            "fix-lost-link-lost.png",
            "map",
            vec![
                // At 4x it is far north of the towers, fix lost, by about 16 s.
                Edge {
                    uav: "uav1",
                    flight: &leave,
                    speed: 4.0,
                    endpoint: EDGE_ENDPOINT,
                    stop_after_s: f64::INFINITY,
                },
                Edge {
                    uav: "uav2",
                    flight: "paper-path-1",
                    speed: 1.0,
                    endpoint: SECOND_EDGE_ENDPOINT,
                    stop_after_s: 10.0,
                },
            ],
            22.0,
        ),
    ];
    for (name, tab, edges, total_s) in shots {
        let out = docs.join(name);
        let mut running = Vec::new();
        for edge in &edges {
            running.push((start_edge(&bin, &towers, edge)?, edge.stop_after_s));
        }
        let connect = edges.iter().flat_map(|e| ["--connect", e.endpoint]);
        let gs = Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1600x900x24"])
            .arg(bin.join("towernav-gs"))
            .arg("--db")
            .arg(&db)
            .arg("--import")
            .arg(&towers)
            .args(connect)
            .args(["--tab", tab])
            .arg("--screenshot")
            .arg(&out)
            .args(["--quit-after-s", &total_s.to_string()])
            .spawn()
            .context("starting xvfb-run (the xvfb package)")?;
        shoot(running, gs, &out)?;
    }
    Ok(())
}

/// A demo edge with the oracle detector.
fn start_edge(bin: &Path, towers: &Path, edge: &Edge) -> anyhow::Result<Child> {
    Command::new(bin.join("towernav-edge"))
        .args(["demo", "--detector", "oracle", "--uav", edge.uav])
        .args(["--speed", &edge.speed.to_string()])
        .args(["--flight", edge.flight, "--listen", edge.endpoint])
        .arg("--landmarks")
        .arg(towers)
        .stdout(Stdio::null())
        .spawn()
        .with_context(|| format!("starting the demo edge of {}", edge.uav))
}

/// Stops each edge after its time (never, for a live picture: the window
/// starts later than this clock), waits for the window's screenshot.
fn shoot(mut edges: Vec<(Child, f64)>, mut gs: Child, out: &Path) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let stop = |edge: &mut Child| {
        let _ = edge.kill();
        let _ = edge.wait();
    };
    loop {
        for (edge, stop_after_s) in &mut edges {
            if started.elapsed().as_secs_f64() >= *stop_after_s {
                stop(edge);
            }
        }
        if let Some(status) = gs.try_wait()? {
            for (edge, _) in &mut edges {
                stop(edge);
            }
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
