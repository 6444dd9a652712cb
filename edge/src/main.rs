//! `towernav-edge`: the onboard daemon; in the demo build also its demo and
//! the evaluations.

mod cli;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context;
use clap::{Parser, Subcommand};
use towernav_edge::daemon::config::EdgeConfig;
use towernav_edge::edge_cmd::{run_edge, spawn_signal_watch};

use cli::run_args::RunArgs;

#[derive(Parser)]
#[command(about = "towernav edge daemon: landmark localization from a forward camera")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The onboard daemon: frames from the simulator, an image folder, a video,
    /// RTSP or V4L2; poses over Zenoh and MAVLink.
    Run(RunArgs),
    /// Run the daemon with a listener on loopback; print the accuracy report and
    /// write trajectory and error plots to target/demo.
    Demo(RunArgs),
    /// Print the default configuration as TOML (a starting point for --config).
    PrintConfig,
    /// Replay a recorded flight (video or images, flight log, calibration,
    /// landmarks) through the pipeline, every frame, and score it against
    /// the log's GNSS: poses.jsonl, replay.json and plots in --out.
    #[cfg(feature = "demo")]
    Replay(cli::replay_command::ReplayArgs),
    /// Labels from a survey flight: every tower projected into the frames by
    /// the log's GNSS and attitude, snapped to the detector's boxes, written
    /// as a YOLO dataset with a report of every label.
    #[cfg(feature = "demo")]
    Label(cli::label_command::LabelArgs),
    /// Towers measured from a survey flight: feet and heights from many views,
    /// held against the landmark file (confirmed, missed, new), written as
    /// an importable CSV and a GeoJSON for review.
    #[cfg(feature = "demo")]
    #[command(name = "map-towers")]
    MapTowers(cli::map_towers_command::MapTowersArgs),
    /// Reviewed labels back from COCO JSON (CVAT, Label Studio) into a
    /// labelled dataset's YOLO files.
    #[cfg(feature = "demo")]
    #[command(name = "label-import")]
    LabelImport(cli::label_command::LabelImportArgs),
    #[cfg(feature = "demo")]
    #[command(flatten)]
    Eval(cli::eval_command::EvalCommand),
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,towernav=info".into()),
        )
        .with_writer(std::io::stderr)
        // Colour codes only on a terminal: under systemd the journal gets plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    let args = match cli.command {
        Command::PrintConfig => {
            print!("{}", EdgeConfig::default().to_toml());
            return Ok(());
        }
        #[cfg(feature = "demo")]
        Command::Eval(eval) => return eval.run(),
        #[cfg(feature = "demo")]
        Command::Replay(replay) => return replay.run(),
        #[cfg(feature = "demo")]
        Command::Label(label) => return label.run(),
        #[cfg(feature = "demo")]
        Command::LabelImport(import) => return import.run(),
        #[cfg(feature = "demo")]
        Command::MapTowers(map) => return map.run(),
        Command::Run(args) => (args, false),
        Command::Demo(args) => (args, true),
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(run(args.0, args.1))
}

async fn run(args: RunArgs, demo: bool) -> anyhow::Result<()> {
    let config = args.config()?;
    let out = PathBuf::from("target/demo");
    let stop = Arc::new(AtomicBool::new(false));
    spawn_signal_watch(stop.clone());
    run_edge(&config, demo.then_some(out.as_path()), stop).await?;
    Ok(())
}
