//! `towernav-edge`: the onboard daemon, its demo, and the evaluations.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use towernav_edge::detector::PostprocessParams;
use towernav_edge::shell::daemon::config::{DetectorSection, EdgeConfig, ZenohMode};
use towernav_edge::shell::detector_eval_cmd::DetectorEvalOptions;
use towernav_edge::shell::edge_cmd::{run_edge, spawn_signal_watch};
use towernav_edge::shell::yolo::DetectorOptions;

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
        /// Types each box may be scored under, best first: 1 is what the
        /// pipeline gets; 4 scores mAP as Ultralytics validates (`multi_label`).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=4))]
        types_per_box: u8,
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
    /// YOLO model (Ultralytics ONNX export, classes A-D); default: the
    /// daemon's (`towernav-edge print-config`).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Tower-type classifier run on each box's full-resolution crop; default:
    /// the daemon's.
    #[arg(long, conflicts_with = "no_type_model")]
    type_model: Option<PathBuf>,
    /// No classifier: the detector's own types.
    #[arg(long)]
    no_type_model: bool,
    /// ONNX Runtime threads for inference.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Run inference on CUDA (build with `--features cuda`).
    #[arg(long)]
    cuda: bool,
    /// Detections below this confidence are dropped.
    #[arg(long, default_value_t = 0.25)]
    min_score: f32,
    /// Weight of the detector's own type scores against the classifier's
    /// reading of the crop, 0 to 1 (0: the classifier alone).
    #[arg(long, default_value_t = towernav_edge::detector::postprocess::DETECTOR_TYPE_WEIGHT,
          value_parser = unit_interval)]
    detector_type_weight: f32,
}

fn unit_interval(text: &str) -> Result<f32, String> {
    match text.parse::<f32>() {
        Ok(w) if (0.0..=1.0).contains(&w) => Ok(w),
        Ok(w) => Err(format!("{w} is not between 0 and 1")),
        Err(e) => Err(e.to_string()),
    }
}

impl DetectorArgs {
    /// The daemon's detector section with these flags applied: the evaluator
    /// scores what the daemon runs unless told otherwise.
    fn section(&self) -> DetectorSection {
        let mut section = DetectorSection::default();
        if let Some(model) = &self.model {
            section.model = model.clone();
        }
        if let Some(type_model) = &self.type_model {
            section.type_model = type_model.clone();
            section.classify_types = true;
        }
        if self.no_type_model {
            section.classify_types = false;
        }
        section
    }

    fn options(&self) -> DetectorOptions {
        DetectorOptions {
            threads: self.threads,
            cuda: self.cuda,
            post: PostprocessParams {
                min_score: self.min_score,
                detector_type_weight: self.detector_type_weight,
                ..PostprocessParams::default()
            },
        }
    }
}

/// Flags override the config file (`--config`), which overrides the defaults
/// (`towernav-edge print-config` shows them all).
#[derive(Args, Default)]
struct RunArgs {
    /// TOML config file.
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long)]
    fleet: Option<String>,
    #[arg(long)]
    uav: Option<String>,
    /// Zenoh endpoint to listen on (repeatable; ground stations connect here).
    #[arg(long)]
    listen: Vec<String>,
    /// Zenoh mode: peer (default), or client behind a router given with --connect.
    #[arg(long, value_enum)]
    zenoh_mode: Option<ZenohMode>,
    /// Zenoh endpoint to connect to: a peer, or a router (repeatable).
    #[arg(long)]
    connect: Vec<String>,
    /// Frame source: sim, images, video, rtsp, v4l2.
    #[arg(long, value_parser = ["sim", "images", "video", "rtsp", "v4l2"])]
    source: Option<String>,
    /// Image folder, video file, rtsp:// URL or /dev/videoN.
    #[arg(long)]
    path: Option<String>,
    /// Frame rate of an image folder or video file.
    #[arg(long)]
    fps: Option<f64>,
    /// Simulation seed: detector noise, misses, false positives, IMU noise.
    #[arg(long)]
    seed: Option<u64>,
    /// Playback speed relative to real time, for recorded sources; when the
    /// pipeline falls behind, the oldest frame is dropped. 0: every frame, as
    /// fast as the pipeline goes. Default: 4 for the simulator; 0 for an image
    /// folder or a video file (1 replays them in real time). Live cameras
    /// (rtsp, v4l2) pace themselves and take no speed.
    #[arg(long)]
    speed: Option<f64>,
    /// Simulated flight: a preset (seed-path-1, seed-path-2, straight,
    /// out-and-back, lawnmower) or a waypoint plan file (TOML, as in
    /// sim/flights/). Default: the skeleton's level flight over the seed's
    /// field; a pass along the longest line over any other world.
    #[arg(long)]
    flight: Option<String>,
    /// Simulated world from a landmark CSV or database (positions, heights,
    /// types); the edge localizes against the same towers unless --landmarks.
    #[arg(long, conflicts_with = "random_world")]
    world: Option<PathBuf>,
    /// Simulated world drawn at random from this seed.
    #[arg(long)]
    random_world: Option<u64>,
    /// Stop after this many frames.
    #[arg(long)]
    max_frames: Option<u64>,
    /// Attitude input: source, csv, mavlink.
    #[arg(long, value_parser = ["source", "csv", "mavlink"])]
    attitude: Option<String>,
    /// The attitude CSV log (time_s,roll_deg,pitch_deg,heading_deg).
    #[arg(long)]
    attitude_log: Option<PathBuf>,
    /// Landmarks to localize against (.csv or a landmark database); default: the simulated world's.
    #[arg(long, conflicts_with = "replica")]
    landmarks: Option<PathBuf>,
    /// Keep a replica of the ground station's landmarks in this file and follow its changes.
    #[arg(long)]
    replica: Option<PathBuf>,
    /// Per-frame estimator: ours (`rays`) or the seed's baseline (`seed`).
    #[arg(long, value_parser = ["rays", "seed"])]
    method: Option<String>,
    /// Publish raw per-frame fixes instead of the EKF's estimates.
    #[arg(long)]
    no_filter: bool,
    /// `yolo` (the model on rendered or camera frames) or `oracle` (simulator truth with noise).
    #[arg(long, value_parser = ["yolo", "oracle"])]
    detector: Option<String>,
    /// YOLO model (Ultralytics ONNX export, classes A-D).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Tower-type classifier run on each box's full-resolution crop.
    #[arg(long)]
    type_model: Option<PathBuf>,
    /// Keep the detector's own types (no type classifier).
    #[arg(long)]
    no_type_model: bool,
    /// ONNX Runtime threads.
    #[arg(long)]
    threads: Option<usize>,
    /// Inference on CUDA (build with `--features cuda`).
    #[arg(long)]
    cuda: bool,
    /// Send GPS_INPUT/ODOMETRY to the autopilot at this MAVLink address (udpout:host:port).
    #[arg(long)]
    mavlink: Option<String>,
    /// Write every published estimate as a JSON line here.
    #[arg(long)]
    jsonl: Option<PathBuf>,
    /// Write annotated frames (JPEG) into this folder.
    #[arg(long)]
    annotate: Option<PathBuf>,
}

/// A config enum from its flag spelling (the same as in the TOML file).
fn kind<T: serde::de::DeserializeOwned>(v: &str) -> anyhow::Result<T> {
    Ok(toml::Value::String(v.to_string()).try_into()?)
}

impl RunArgs {
    fn config(&self) -> anyhow::Result<EdgeConfig> {
        let mut c = match &self.config {
            Some(path) => EdgeConfig::read(path)?,
            None => EdgeConfig::default(),
        };
        if let Some(v) = &self.fleet {
            c.fleet = v.clone();
        }
        if let Some(v) = &self.uav {
            c.uav = v.clone();
        }
        if !self.listen.is_empty() {
            c.zenoh.listen = self.listen.clone();
        }
        if let Some(mode) = self.zenoh_mode {
            c.zenoh.mode = mode;
        }
        if !self.connect.is_empty() {
            c.zenoh.connect = self.connect.clone();
        }
        if let Some(v) = &self.source {
            c.source.kind = kind(v)?;
        }
        if let Some(v) = &self.path {
            c.source.path = Some(v.clone());
        }
        if let Some(v) = self.fps {
            c.source.fps = v;
        }
        if let Some(v) = self.seed {
            c.source.seed = v;
        }
        if let Some(v) = self.speed {
            c.source.speed = Some(v);
        }
        if let Some(v) = &self.world {
            c.source.world = Some(v.clone());
        }
        if let Some(v) = self.random_world {
            c.source.random_world = Some(v);
        }
        if let Some(v) = &self.flight {
            c.source.flight = Some(v.clone());
        }
        if let Some(v) = self.max_frames {
            c.source.max_frames = Some(v);
        }
        if let Some(v) = &self.attitude {
            c.attitude.kind = kind(v)?;
        }
        if let Some(v) = &self.attitude_log {
            c.attitude.path = Some(v.clone());
        }
        if let Some(v) = &self.landmarks {
            c.landmarks.file = Some(v.clone());
        }
        if let Some(v) = &self.replica {
            c.landmarks.replica = Some(v.clone());
        }
        if let Some(v) = &self.method {
            c.pipeline.method = v.clone();
        }
        if self.no_filter {
            c.pipeline.filter = false;
        }
        if let Some(v) = &self.detector {
            c.detector.kind = kind(v)?;
        }
        if let Some(v) = &self.model {
            c.detector.model = v.clone();
        }
        if let Some(v) = &self.type_model {
            c.detector.type_model = v.clone();
            c.detector.classify_types = true;
        }
        if self.no_type_model {
            c.detector.classify_types = false;
        }
        if let Some(v) = self.threads {
            c.detector.threads = v;
        }
        if self.cuda {
            c.detector.cuda = true;
        }
        if let Some(v) = &self.mavlink {
            c.mavlink.enabled = true;
            c.mavlink.address = v.clone();
        }
        if let Some(v) = &self.jsonl {
            c.output.jsonl = Some(v.clone());
        }
        if let Some(v) = &self.annotate {
            c.output.annotated = Some(v.clone());
        }
        c.validate()?;
        Ok(c)
    }
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
    if let Command::PrintConfig = &cli.command {
        print!("{}", EdgeConfig::default().to_toml());
        return Ok(());
    }
    if let Command::EvalLocalization { out, seed } = &cli.command {
        return towernav_edge::shell::loc_eval_cmd::write_all(out, *seed);
    }
    if let Command::EvalDetector {
        detector,
        worlds,
        frames_per_world,
        seed,
        types_per_box,
        out,
    } = &cli.command
    {
        let options = DetectorEvalOptions {
            worlds: *worlds,
            frames_per_world: *frames_per_world,
            seed: *seed,
            recall_score: detector.min_score,
        };
        // Average precision needs the whole ranking: keep candidates down to 0.001,
        // as Ultralytics' validation does; P and R are read at --min-score.
        let mut detector_options = detector.options();
        detector_options.post.min_score = 0.001;
        detector_options.post.types_per_box = usize::from(*types_per_box);
        let section = detector.section();
        return towernav_edge::shell::detector_eval_cmd::write_all(
            &section.model,
            section.type_model(),
            &detector_options,
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
            Command::PrintConfig
            | Command::EvalLocalization { .. }
            | Command::EvalTracking { .. }
            | Command::EvalDetector { .. } => Ok(()),
        }
    })
}

async fn run(args: RunArgs, demo: bool) -> anyhow::Result<()> {
    let config = args.config()?;
    let out = PathBuf::from("target/demo");
    let stop = Arc::new(AtomicBool::new(false));
    spawn_signal_watch(stop.clone());
    run_edge(&config, demo.then_some(out.as_path()), stop).await?;
    Ok(())
}
