//! Fleet scale: `cargo bench -p towernav-tests --bench fleet -- [--edges 20]
//! [--seconds 10] [--speed 1] [--preview-hz 0] [--record fleet.mcap]
//! [--zenohd .zenohd/bin/zenohd] [--secure]`.
//!
//! Runs that many simulated edges (oracle detector) through one router to one
//! subscriber and reports poses lost and their latency (sender timestamp to
//! arrival). With `--record`, the subscriber's traffic is written to MCAP: the
//! ground station replays it (`towernav-gs --replay`) for its own frame-rate bench.

use clap::Parser;
use towernav_tests::fleet::{FleetOptions, run_fleet};

#[derive(Parser)]
struct Args {
    #[arg(long, default_value_t = 20)]
    edges: usize,
    /// Flight length per edge, seconds of simulated time at 30 Hz.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// 1 = real time; 0 = as fast as possible.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    #[arg(long, default_value_t = 0.0)]
    preview_hz: f64,
    #[arg(long)]
    record: Option<std::path::PathBuf>,
    /// Route through this zenohd (`cargo xtask zenohd` builds it) instead of
    /// an in-process router; the subscriber is then its client.
    #[arg(long)]
    zenohd: Option<std::path::PathBuf>,
    /// Mutual TLS with a fresh fleet CA's certificates, under its access rules.
    #[arg(long)]
    secure: bool,
    /// Passed by `cargo bench`; ignored.
    #[arg(long, hide = true)]
    bench: bool,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let options = FleetOptions {
        edges: args.edges,
        frames: (args.seconds * 30.0).round() as u64,
        speed: args.speed,
        preview_hz: args.preview_hz,
        record: args.record,
        zenohd: args.zenohd,
        secure: args.secure,
    };
    let report = run_fleet(&options).await?;
    let published: u64 = report.published.values().sum();
    let received: u64 = report.received.values().sum();
    let (p50, p99, max) = report.latency();
    println!(
        "fleet: {} edges x {} frames at speed {} in {:.1} s, through {}{}",
        options.edges,
        options.frames,
        options.speed,
        report.wall_s,
        options
            .zenohd
            .as_ref()
            .map_or("an in-process router".to_owned(), |p| p
                .display()
                .to_string()),
        if options.secure {
            ", mutual TLS and access rules"
        } else {
            ", plain TCP"
        }
    );
    println!(
        "poses: {published} published, {received} received, {} UAVs short",
        report.lost().len()
    );
    println!(
        "latency (sender timestamp to subscriber): p50 {p50:.2} ms, p99 {p99:.2} ms, max {max:.2} ms"
    );
    for (uav, p, r) in report.lost() {
        println!("  {uav}: {p} published, {r} received");
    }
    if !report.lost().is_empty() {
        anyhow::bail!("poses were lost");
    }
    Ok(())
}
