//! `towernav-edge`: the onboard daemon. Today its frame source is the simulator.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use towernav_edge::LandmarkMap;
use towernav_edge::detector::PostprocessParams;
use towernav_edge::localizer::Method;
use towernav_edge::report::FlightReport;
use towernav_edge::shell::collector::{PoseCollector, wait_for_peer};
use towernav_edge::shell::detector_eval_cmd::DetectorEvalOptions;
use towernav_edge::shell::landmark_sync::LandmarkSync;
use towernav_edge::shell::landmarks_source::load_landmarks;
use towernav_edge::shell::node::{EdgeNode, open_session};
use towernav_edge::shell::rendered_detector::RenderedDetector;
use towernav_edge::shell::sim_flight::{FlightRecord, SimFlightOptions, fly};
use towernav_edge::shell::yolo::{DetectorOptions, YoloDetector};
use towernav_protocol::NodeId;
use towernav_protocol::session::Endpoints;
use towernav_sim::{Conditions, Scenario};

#[derive(Parser)]
#[command(about = "towernav edge daemon: landmark localization from a forward camera")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fly the simulated seed flight through the pipeline and publish over Zenoh.
    Run(RunArgs),
    /// Run the flight with a listener on loopback and print the accuracy report.
    Demo(RunArgs),
    /// The seed's Table 2: SORT, ByteTrack-style and ours on the seed's paths and
    /// random fields (oracle detector), with MOT-challenge result files.
    EvalTracking {
        /// Folder for the MOT-challenge files.
        #[arg(long, default_value = "target/tracking-eval")]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// An ONNX re-identification model ([N, 3, H, W] crops in, [N, D] out) for
        /// DeepSORT's appearance; default: the Rust crop descriptor.
        #[arg(long)]
        reid: Option<PathBuf>,
    },
    /// The seed's Table 1 for a YOLO model: precision, recall, mAP50, mAP50-95 per
    /// class, recall by box height, and latency, on held-out simulated worlds.
    EvalDetector {
        #[command(flatten)]
        detector: DetectorArgs,
        /// Held-out worlds to render (drawn from --seed; training used seed 0).
        #[arg(long, default_value_t = 10)]
        worlds: u64,
        #[arg(long, default_value_t = 30)]
        frames_per_world: u64,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Folder for detector-eval.json.
        #[arg(long, default_value = "target/detector-eval")]
        out: PathBuf,
    },
    /// Reproduce the seed's localization analysis (seed vs ours, tables and PNG plots).
    EvalLocalization {
        /// Folder for the plots.
        #[arg(long, default_value = "target/loc-eval")]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

#[derive(Args, Clone)]
struct DetectorArgs {
    /// YOLO model (Ultralytics ONNX export, classes A-D).
    #[arg(long, default_value = "models/towers.onnx")]
    model: PathBuf,
    /// ONNX Runtime threads for inference.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Run inference on CUDA (build with `--features cuda`).
    #[arg(long)]
    cuda: bool,
    /// Detections below this confidence are dropped.
    #[arg(long, default_value_t = 0.25)]
    min_score: f32,
}

impl DetectorArgs {
    fn options(&self) -> DetectorOptions {
        DetectorOptions {
            threads: self.threads,
            cuda: self.cuda,
            post: PostprocessParams {
                min_score: self.min_score,
                ..PostprocessParams::default()
            },
        }
    }
}

#[derive(Args)]
struct RunArgs {
    #[arg(long, default_value = "demo")]
    fleet: NodeId,
    #[arg(long, default_value = "uav1")]
    uav: NodeId,
    /// Zenoh endpoint to listen on (ground stations connect here).
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    listen: Vec<String>,
    /// Zenoh endpoint to connect to, e.g. a router (repeatable).
    #[arg(long)]
    connect: Vec<String>,
    /// Simulation seed: detector noise, misses, false positives, IMU noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Playback speed relative to real time; 0 runs as fast as possible.
    #[arg(long, default_value_t = 4.0)]
    speed: f64,
    /// Landmarks to localize against (.csv or a landmark database); default: the simulated world's.
    #[arg(long, conflicts_with = "replica")]
    landmarks: Option<PathBuf>,
    /// Keep a replica of the ground station's landmarks in this file and follow its changes.
    #[arg(long)]
    replica: Option<PathBuf>,
    /// Fly a quadrotor plan over the seed field (seed-path-1, seed-path-2, straight,
    /// out-and-back, lawnmower) with the realistic oracle; default: the skeleton's level flight.
    #[arg(long)]
    flight: Option<String>,
    /// Per-frame estimator: ours (`rays`) or the seed's baseline (`seed`).
    #[arg(long, default_value = "rays", value_parser = ["rays", "seed"])]
    method: String,
    /// Publish raw per-frame fixes instead of the EKF's estimates.
    #[arg(long)]
    no_filter: bool,
    /// Boxes from the YOLO model on rendered frames (`yolo`), or from the
    /// simulator's truth with noise (`oracle`, no rendering).
    #[arg(long, default_value = "yolo", value_parser = ["yolo", "oracle"])]
    detector: String,
    #[command(flatten)]
    yolo: DetectorArgs,
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,towernav=info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    if let Command::EvalLocalization { out, seed } = &cli.command {
        return towernav_edge::shell::loc_eval_cmd::write_all(out, *seed);
    }
    if let Command::EvalDetector {
        detector,
        worlds,
        frames_per_world,
        seed,
        out,
    } = &cli.command
    {
        let options = DetectorEvalOptions {
            worlds: *worlds,
            frames_per_world: *frames_per_world,
            seed: *seed,
            recall_score: detector.min_score,
        };
        return towernav_edge::shell::detector_eval_cmd::write_all(
            &detector.model,
            &detector.options(),
            &options,
            out,
        );
    }
    if let Command::EvalTracking { out, seed, reid } = &cli.command {
        return towernav_edge::shell::tracking_eval_cmd::write_all(out, *seed, reid.as_deref());
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(async {
        match cli.command {
            Command::Run(args) => run(args, false).await,
            Command::Demo(args) => run(args, true).await,
            Command::EvalLocalization { .. }
            | Command::EvalTracking { .. }
            | Command::EvalDetector { .. } => Ok(()),
        }
    })
}

async fn run(args: RunArgs, demo: bool) -> anyhow::Result<()> {
    let scenario = match &args.flight {
        Some(plan) => Scenario::preset(towernav_sim::World::seed_field(), plan, args.seed)?,
        None => Scenario::seed(args.seed),
    };
    let endpoints = Endpoints {
        listen: args.listen.clone(),
        connect: args.connect.clone(),
    };
    let session = open_session(&endpoints).await?;
    let mut sync = match &args.replica {
        Some(path) => {
            // Zenoh retries links every few seconds: give the ground station a moment to reach us.
            if wait_for_peer(&session, Duration::from_secs(6))
                .await
                .is_err()
            {
                tracing::warn!("no peer yet; asking for landmarks anyway");
            }
            let (sync, source) = LandmarkSync::start(
                &session,
                args.fleet.clone(),
                path.clone(),
                Duration::from_secs(3),
            )
            .await?;
            println!(
                "landmarks: {} towers at revision {} ({source:?})",
                sync.replica().len(),
                sync.replica().revision
            );
            Some(sync)
        }
        None => None,
    };
    let records = match (&sync, &args.landmarks) {
        (Some(sync), _) => sync.replica().records(),
        (None, Some(path)) => load_landmarks(path)?,
        (None, None) => scenario.world.landmarks(),
    };
    let map = LandmarkMap::from_records(&records, &scenario.world.datum);
    let node = EdgeNode::new(session, args.fleet.clone(), args.uav.clone()).await?;

    let listener = if demo {
        let connect = args
            .listen
            .first()
            .cloned()
            .context("the demo needs a --listen endpoint to listen on")?;
        let session = open_session(&Endpoints {
            listen: vec![],
            connect: vec![connect],
        })
        .await?;
        let collector = PoseCollector::start(&session, args.fleet.clone()).await?;
        wait_for_peer(&session, Duration::from_secs(10)).await?;
        Some((session, collector))
    } else {
        None
    };

    println!(
        "towernav edge: fleet {} uav {} on {:?}",
        args.fleet, args.uav, args.listen
    );
    let endpoint = args
        .listen
        .first()
        .map_or("tcp/127.0.0.1:7447", String::as_str);
    println!(
        "watch live: `cargo xtask gs` in another terminal, or `towernav-gs --db <towers.sqlite> --connect {endpoint}`"
    );
    println!(
        "            (start it before or after the edge; `--speed 1` plays the flight in real time)"
    );

    let bar = towernav_edge::shell::progress::bar(scenario.frame_count(), "flying");
    let options = SimFlightOptions {
        speed: (args.speed > 0.0).then_some(args.speed),
        method: if args.method == "seed" {
            Method::Seed
        } else {
            Method::Rays
        },
        filter: !args.no_filter,
        ..SimFlightOptions::default()
    };
    let mut detector = match args.detector.as_str() {
        "yolo" => {
            let yolo = YoloDetector::load(&args.yolo.model, &args.yolo.options()).with_context(|| {
                "loading the detector (run `cargo xtask setup-ort` for ONNX Runtime, or fly with `--detector oracle`)"
            })?;
            Some(RenderedDetector::new(
                &scenario,
                yolo,
                Conditions::default(),
            ))
        }
        _ => None,
    };
    let record: FlightRecord = fly(
        &node,
        &scenario,
        map,
        options,
        sync.as_mut(),
        detector.as_mut(),
        |n| bar.set_position(n),
    )
    .await?;
    bar.finish_and_clear();

    if let Some((_session, collector)) = listener {
        let received = collector
            .drain(record.poses_published as usize, Duration::from_secs(3))
            .await;
        if collector.rejected() > 0 {
            println!("warning: {} poses did not decode", collector.rejected());
        }
        let report = FlightReport::new(&record, &received, scenario.fps);
        println!(
            "\ntowernav demo report (seed field, 18 towers, seed {})\n{report}",
            args.seed
        );
    } else {
        println!(
            "flew {} frames, published {} poses",
            record.frames, record.poses_published
        );
    }
    Ok(())
}
