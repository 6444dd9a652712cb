//! A long flight through the edge daemon: `cargo xtask soak --minutes N`
//! (which builds the daemon and runs this with `--edge`).
//!
//! The simulator flies laps of the paper's field for N minutes of flight,
//! as fast as the daemon goes (oracle boxes by default, so hours of flight
//! take minutes). The daemon runs as its own process; this one samples its
//! resident memory every second, hears its poses and status over Zenoh, and
//! reports per minute of flight: peak RSS, latency p99, poses; then the RSS
//! growth after the first minute, the p99's spread and the poses lost
//! (the daemon's own pose log against what arrived).

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::Parser;
use towernav_protocol::session::Endpoints;
use towernav_protocol::{Keys, NodeId, PoseEstimate, StatusHeartbeat, Topic, decode};

#[derive(Parser)]
struct Args {
    /// The daemon (`target/release/towernav-edge`, built with `--features demo`).
    #[arg(long)]
    edge: PathBuf,
    /// Minutes of flight.
    #[arg(long, default_value_t = 60.0)]
    minutes: f64,
    /// 0: as fast as the daemon goes; 1: real time.
    #[arg(long, default_value_t = 0.0)]
    speed: f64,
    /// `oracle` (the simulator's boxes) or `yolo` (rendered frames through the detector).
    #[arg(long, default_value = "oracle")]
    detector: String,
    /// Where the report (`soak.csv`) and the daemon's logs go.
    #[arg(long, default_value = "target/soak")]
    out: PathBuf,
    /// Passed by `cargo bench`; ignored.
    #[arg(long, hide = true)]
    bench: bool,
}

/// Laps out and back along the paper's field (about 190 s each) covering
/// `minutes`, as a waypoint plan.
fn laps(minutes: f64) -> String {
    let n = (minutes * 60.0 / 180.0).ceil() as usize + 1;
    let mut plan = String::from(
        "name = \"soak\"\ndescription = \"Laps out and back along the paper's field.\"\n",
    );
    for _ in 0..n {
        for (east, north, height, speed) in [
            (0, 250, 35, 12),
            (900, 250, 35, 12),
            (900, 262, 28, 8),
            (0, 262, 28, 8),
        ] {
            plan.push_str(&format!(
                "\n[[waypoint]]\neast_m = {east}\nnorth_m = {north}\nheight_m = {height}\nspeed_mps = {speed}\n"
            ));
        }
    }
    plan
}

/// `VmRSS` of a process, MiB.
fn rss_mib(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Wall seconds that count as warm-up whatever the flight's speed.
const WARM_UP_WALL_S: f64 = 10.0;

#[derive(Default)]
struct Minute {
    rss_mib: f64,
    p50_ms: f64,
    p99_ms: f64,
    poses: u64,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    std::fs::create_dir_all(&args.out)?;
    let out = std::fs::canonicalize(&args.out)?;
    let plan = out.join("laps.toml");
    std::fs::write(&plan, laps(args.minutes))?;
    let frames = (args.minutes * 60.0 * 30.0).round() as u64;
    let port = towernav_tests::loopback_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let session = towernav_edge::node::open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        ..Default::default()
    })
    .await?;
    let keys = Keys::new(NodeId::new("soak")?);
    let all = session
        .declare_subscriber(keys.all_uavs_any_topic())
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // (flight seconds, p50, p99) per status; pose seqs as they arrive.
    let statuses: Arc<Mutex<Vec<(f64, f64, f64)>>> = Arc::default();
    let poses: Arc<Mutex<Vec<(f64, u64)>>> = Arc::default();
    let reader = tokio::spawn({
        let (statuses, poses) = (statuses.clone(), poses.clone());
        async move {
            while let Ok(s) = all.recv_async().await {
                let Ok(key) = Keys::parse_uav(s.key_expr().as_str()) else {
                    continue;
                };
                let bytes = s.payload().to_bytes();
                match key.topic {
                    Topic::Status => {
                        if let Ok(st) = decode::<StatusHeartbeat>(&bytes) {
                            statuses.lock().unwrap_or_else(|e| e.into_inner()).push((
                                st.time_s,
                                st.latency_p50_ms,
                                st.latency_p99_ms,
                            ));
                        }
                    }
                    Topic::Pose => {
                        if let Ok(p) = decode::<PoseEstimate>(&bytes) {
                            poses
                                .lock()
                                .unwrap_or_else(|e| e.into_inner())
                                .push((p.time_s, p.seq));
                        }
                    }
                    _ => {}
                }
            }
        }
    });

    let pose_log = out.join("poses.jsonl");
    let edge_listen = format!("tcp/127.0.0.1:{}", towernav_tests::loopback_port());
    let mut child = std::process::Command::new(&args.edge)
        .arg("run")
        .args([
            "--fleet",
            "soak",
            "--uav",
            "uav1",
            "--detector",
            &args.detector,
        ])
        .args(["--connect", &endpoint, "--listen", &edge_listen])
        .arg("--flight")
        .arg(&plan)
        .args(["--speed", &args.speed.to_string()])
        .args(["--max-frames", &frames.to_string()])
        .arg("--jsonl")
        .arg(&pose_log)
        .env("RUST_LOG", "warn")
        .stdout(std::fs::File::create(out.join("edge.out"))?)
        .stderr(std::fs::File::create(out.join("edge.log"))?)
        .spawn()
        .map_err(|e| anyhow::anyhow!("starting {}: {e}", args.edge.display()))?;
    let pid = child.id();
    let started = Instant::now();
    let progress = indicatif::ProgressBar::new(frames / 30);
    progress.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} s of flight, {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    // (flight seconds at the sample, wall seconds, RSS MiB)
    let mut rss: Vec<(f64, f64, f64)> = Vec::new();
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        let flight_s = statuses
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .last()
            .map_or(0.0, |s| s.0);
        if let Some(r) = rss_mib(pid) {
            rss.push((flight_s, started.elapsed().as_secs_f64(), r));
            progress.set_position(flight_s as u64);
            progress.set_message(format!("RSS {r:.0} MiB"));
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
    };
    progress.finish_and_clear();
    let wall_s = started.elapsed().as_secs_f64();
    anyhow::ensure!(
        status.success(),
        "the daemon failed: {status}; see {}",
        out.join("edge.log").display()
    );
    tokio::time::sleep(Duration::from_secs(2)).await;
    reader.abort();

    let logged = std::fs::read_to_string(&pose_log)?.lines().count() as u64;
    let poses = std::mem::take(&mut *poses.lock().unwrap_or_else(|e| e.into_inner()));
    let statuses = std::mem::take(&mut *statuses.lock().unwrap_or_else(|e| e.into_inner()));
    let mut seqs: Vec<u64> = poses.iter().map(|p| p.1).collect();
    let in_order = seqs.windows(2).all(|w| w[0] < w[1]);
    seqs.dedup();
    let minutes = (args.minutes.ceil() as usize).max(1);
    let mut table: Vec<Minute> = (0..minutes).map(|_| Minute::default()).collect();
    let minute_of = |s: f64| ((s / 60.0) as usize).min(minutes - 1);
    for (s, _, r) in &rss {
        let m = &mut table[minute_of(*s)];
        m.rss_mib = m.rss_mib.max(*r);
    }
    for (s, p50, p99) in &statuses {
        let m = &mut table[minute_of(*s)];
        m.p50_ms = m.p50_ms.max(*p50);
        m.p99_ms = m.p99_ms.max(*p99);
    }
    for (s, _) in &poses {
        table[minute_of(*s)].poses += 1;
    }
    let mut csv = std::fs::File::create(out.join("soak.csv"))?;
    writeln!(
        csv,
        "minute,peak_rss_mib,latency_p50_ms,latency_p99_ms,poses"
    )?;
    for (i, m) in table.iter().enumerate() {
        writeln!(
            csv,
            "{},{:.1},{:.2},{:.2},{}",
            i + 1,
            m.rss_mib,
            m.p50_ms,
            m.p99_ms,
            m.poses
        )?;
    }
    // Warm-up: the first minute of flight, or the daemon's first 10 s where
    // the flight runs faster than real time (a minute of it is then a second
    // or two, too short for the daemon to reach its working size).
    let warm = |flight_s: f64, wall_s: f64| flight_s < 60.0 || wall_s < WARM_UP_WALL_S;
    let first = rss
        .iter()
        .filter(|(f, w, _)| warm(*f, *w))
        .map(|(_, _, r)| *r)
        .fold(0.0, f64::max);
    let later = rss
        .iter()
        .filter(|(f, w, _)| !warm(*f, *w))
        .map(|(_, _, r)| *r)
        .fold(0.0, f64::max);
    let growth = if later > 0.0 {
        100.0 * (later - first) / first
    } else {
        0.0
    };
    let p99s: Vec<f64> = table
        .iter()
        .map(|m| m.p99_ms)
        .filter(|v| *v > 0.0)
        .collect();
    let (p99_lo, p99_hi) = p99s.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(*v), hi.max(*v))
    });
    println!(
        "soak: {:.0} min of flight ({} frames, {}) in {:.1} min of wall time",
        args.minutes,
        frames,
        args.detector,
        wall_s / 60.0
    );
    println!(
        "  peak RSS: warm-up (first minute of flight, or {WARM_UP_WALL_S} s) {first:.1} MiB, after it at most {later:.1} MiB ({growth:+.1} %); peak of minute 1 {:.1} MiB",
        table[0].rss_mib
    );
    println!("  latency p99 per minute: {p99_lo:.2} to {p99_hi:.2} ms");
    println!(
        "  poses: {} logged by the daemon, {} arrived ({} lost), {}",
        logged,
        seqs.len(),
        logged.saturating_sub(seqs.len() as u64),
        if in_order { "in order" } else { "OUT OF ORDER" }
    );
    println!("  per minute: {}", out.join("soak.csv").display());
    Ok(())
}
