//! `run` and `demo` flags, over the config file, over the defaults.

use std::path::PathBuf;

use clap::Args;
use towernav_edge::daemon::config::{EdgeConfig, ZenohMode};

/// Flags override the config file (`--config`), which overrides the defaults
/// (`towernav-edge print-config` shows them all).
#[derive(Args, Default)]
pub struct RunArgs {
    /// TOML config file.
    #[arg(long)]
    pub config: Option<PathBuf>,
    #[arg(long)]
    pub fleet: Option<String>,
    #[arg(long)]
    pub uav: Option<String>,
    /// Zenoh endpoint to listen on (repeatable; ground stations connect here).
    #[arg(long)]
    pub listen: Vec<String>,
    /// Zenoh mode: peer (default), or client behind a router given with --connect.
    #[arg(long, value_enum)]
    pub zenoh_mode: Option<ZenohMode>,
    /// Zenoh endpoint to connect to: a peer, or a router (repeatable).
    #[arg(long)]
    pub connect: Vec<String>,
    /// Frame source: sim, images, video, rtsp, v4l2.
    #[arg(long, value_parser = ["sim", "images", "video", "rtsp", "v4l2"])]
    pub source: Option<String>,
    /// Image folder, video file, rtsp:// URL or /dev/videoN.
    #[arg(long)]
    pub path: Option<String>,
    /// Frame rate of an image folder or video file.
    #[arg(long)]
    pub fps: Option<f64>,
    /// Simulation seed: detector noise, misses, false positives, IMU noise.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Playback speed relative to real time, for recorded sources; when the
    /// pipeline falls behind, the oldest frame is dropped. 0: every frame, as
    /// fast as the pipeline goes. Default: 4 for the simulator; 0 for an image
    /// folder or a video file (1 replays them in real time). Live cameras
    /// (rtsp, v4l2) pace themselves and take no speed.
    #[arg(long)]
    pub speed: Option<f64>,
    /// Simulated flight: a preset (paper-path-1, paper-path-2, straight,
    /// out-and-back, lawnmower) or a waypoint plan file (TOML, as in
    /// sim/flights/). Default: the skeleton's level flight over the paper's
    /// field; a pass along the longest line over any other world.
    #[arg(long)]
    pub flight: Option<String>,
    /// Simulated world from a landmark CSV or database (positions, heights,
    /// types); the edge localizes against the same towers unless --landmarks.
    #[arg(long, conflicts_with = "random_world")]
    pub world: Option<PathBuf>,
    /// Simulated world drawn at random from this seed.
    #[arg(long)]
    pub random_world: Option<u64>,
    /// Stop after this many frames.
    #[arg(long)]
    pub max_frames: Option<u64>,
    /// Rehearse a camera failure: the simulator's camera stops at AT_S of
    /// the flight for FOR_S seconds (`--stall 20,5`).
    #[arg(long, value_delimiter = ',', num_args = 2, value_names = ["AT_S", "FOR_S"])]
    pub stall: Option<Vec<f64>>,
    /// How recorded frames are timed: pts (a video's), rate (index over
    /// --fps), names, names_ms, names_us, names_ns, or a timestamps file.
    #[arg(long)]
    pub timestamps: Option<String>,
    /// The camera's calibration file (OpenCV, ROS camera_info or Kalibr).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Attitude input: source, log (csv is another name for it), mavlink.
    #[arg(long, value_parser = ["source", "log", "csv", "mavlink"])]
    pub attitude: Option<String>,
    /// The flight log for `--attitude log`: ArduPilot .bin, MAVLink .tlog,
    /// PX4 .ulg, or a CSV of time_s,roll_deg,pitch_deg,heading_deg.
    #[arg(long)]
    pub attitude_log: Option<PathBuf>,
    /// Seconds from the camera's clock to the log's.
    #[arg(long, allow_hyphen_values = true)]
    pub time_offset: Option<f64>,
    /// Landmarks to localize against (.csv or a landmark database); default: the simulated world's.
    #[arg(long, conflicts_with = "replica")]
    pub landmarks: Option<PathBuf>,
    /// Keep a replica of the ground station's landmarks in this file and follow its changes.
    #[arg(long)]
    pub replica: Option<PathBuf>,
    /// Per-frame estimator: ours (`rays`) or the paper's, the baseline
    /// (`paper`; `seed` is its older name).
    #[arg(long, value_parser = towernav_core::localizer::METHOD_NAMES)]
    pub method: Option<String>,
    /// Publish raw per-frame fixes instead of the EKF's estimates.
    #[arg(long)]
    pub no_filter: bool,
    /// `yolo` (the model on rendered or camera frames) or `oracle` (simulator truth with noise).
    #[arg(long, value_parser = ["yolo", "oracle"])]
    pub detector: Option<String>,
    /// YOLO model (Ultralytics ONNX export, classes A-D).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Tower-type classifier run on each box's full-resolution crop.
    #[arg(long)]
    pub type_model: Option<PathBuf>,
    /// Keep the detector's own types (no type classifier).
    #[arg(long)]
    pub no_type_model: bool,
    /// ONNX Runtime threads.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Inference on CUDA (build with `--features cuda`).
    #[arg(long)]
    pub cuda: bool,
    /// Talk to the autopilot at this MAVLink address (udpout:host:port, or serial:device:baud).
    #[arg(long)]
    pub mavlink: Option<String>,
    /// Write every published estimate as a JSON line here.
    #[arg(long)]
    pub jsonl: Option<PathBuf>,
    /// Write annotated frames (JPEG) into this folder.
    #[arg(long)]
    pub annotate: Option<PathBuf>,
    /// Write the autopilot's own GNSS positions (GLOBAL_POSITION_INT) as JSON
    /// lines here, each with the frame it came during: a survey flight's record.
    #[arg(long)]
    pub autopilot_log: Option<PathBuf>,
}

/// A config enum from its flag spelling (the same as in the TOML file).
fn kind<T: serde::de::DeserializeOwned>(v: &str) -> anyhow::Result<T> {
    Ok(toml::Value::String(v.to_string()).try_into()?)
}

impl RunArgs {
    pub fn config(&self) -> anyhow::Result<EdgeConfig> {
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
        if let Some(v) = &self.stall {
            c.source.stall = match v[..] {
                [at_s, for_s] => Some([at_s, for_s]),
                _ => anyhow::bail!("--stall takes AT_S,FOR_S"),
            };
        }
        if let Some(v) = &self.attitude {
            c.attitude.kind = kind(v)?;
        }
        if let Some(v) = &self.attitude_log {
            c.attitude.path = Some(v.clone());
        }
        if let Some(v) = self.time_offset {
            c.attitude.time_offset_s = v;
        }
        if let Some(v) = &self.timestamps {
            c.source.timestamps = Some(v.clone());
        }
        if let Some(v) = &self.calibration {
            c.camera.calibration = Some(v.clone());
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
        if let Some(v) = &self.autopilot_log {
            c.output.autopilot_log = Some(v.clone());
        }
        c.validate()?;
        Ok(c)
    }
}
