//! The daemon's configuration: a TOML file (every field optional, defaults
//! below), overridden by command-line flags, validated before anything starts.
//! `towernav-edge print-config` writes the defaults as a starting file.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use towernav_core::autopilot_link::{LinkConfig, PositionMessage};

use super::frame_times::FrameTimes;
use super::ros2_config::{Px4Section, Ros2Section};

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("config {path}: {reason}")]
    File { path: PathBuf, reason: String },
    #[error("config field `{field}`: {reason}")]
    Invalid { field: &'static str, reason: String },
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EdgeConfig {
    pub fleet: String,
    pub uav: String,
    pub zenoh: ZenohSection,
    pub source: SourceSection,
    pub camera: CameraSection,
    pub attitude: AttitudeSection,
    pub detector: DetectorSection,
    pub landmarks: LandmarksSection,
    pub pipeline: PipelineSection,
    pub mavlink: MavlinkSection,
    pub ros2: Ros2Section,
    pub px4: Px4Section,
    pub output: OutputSection,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohSection {
    /// Endpoints to listen on (peers and ground stations connect here).
    pub listen: Vec<String>,
    /// Endpoints to connect to: other peers, or a router (`tcp/<router>:7447`).
    pub connect: Vec<String>,
    /// `peer` (the default: edges and ground station find each other directly) or
    /// `client` (behind a router: everything goes through the `connect` router).
    pub mode: ZenohMode,
    /// This node's credentials folder from `towernav-fleet issue` (its
    /// certificate, the fleet CA and the roster): links become mutual TLS
    /// (`tls/` endpoints) and the fleet's access rules apply. Without it the
    /// link is plain TCP, for loopback and the bench only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub credentials: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum ZenohMode {
    #[default]
    Peer,
    Client,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    /// The embedded simulator (rendered frames, or oracle boxes with `detector.kind = "oracle"`).
    Sim,
    /// A folder of PNG/JPEG images in name order.
    Images,
    /// A video file, through ffmpeg.
    Video,
    /// An `rtsp://` stream, through ffmpeg.
    Rtsp,
    /// A V4L2 camera such as `/dev/video0`, through ffmpeg.
    V4l2,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SourceSection {
    pub kind: SourceKind,
    /// Folder, file, URL or device, for every kind but `sim`.
    pub path: Option<String>,
    /// Frame rate of an image folder or video file: their clock when
    /// `timestamps` is `rate`.
    pub fps: f64,
    /// Each frame's capture time on the camera's clock, which a flight log's
    /// attitude is looked up at (plus `attitude.time_offset_s`): `pts` (a
    /// video's presentation timestamps; its default), `rate` (index over
    /// `fps`; an image folder's default), `names` (the last number in each
    /// image's file name, seconds; `names_ms`, `names_us`, `names_ns` for
    /// other units), or the path of a timestamps file (one time in seconds
    /// per image in name order, or `name,time_s` lines).
    pub timestamps: Option<String>,
    /// Frames are scaled to this size (the camera model's).
    pub width: u32,
    pub height: u32,
    /// The simulator's flight: a preset (paper-path-1, paper-path-2, straight,
    /// out-and-back, lawnmower) or a waypoint plan file (`.toml`, in the
    /// world's ENU metres). None: the skeleton's level flight over the paper's
    /// field, a pass along the longest line over any other world.
    pub flight: Option<String>,
    /// The simulator's world from a landmark CSV or database (positions,
    /// heights, types; lines by `line_name`); none: the paper's field.
    pub world: Option<PathBuf>,
    /// The simulator's world drawn at random from this seed.
    pub random_world: Option<u64>,
    pub seed: u64,
    /// Stop after this many frames.
    pub max_frames: Option<u64>,
    /// Playback speed relative to real time, for recorded sources; when
    /// behind, the oldest frame is dropped. 0: every frame, as fast as the
    /// pipeline goes. Unset: 4 for the simulator, 0 for an image folder or a
    /// video file. Live cameras (`rtsp`, `v4l2`) pace themselves.
    pub speed: Option<f64>,
    /// Frames waiting for the pipeline; when full, the oldest is dropped.
    pub queue: usize,
    /// The simulator's camera stops at `[at_s, for_s]`: at that flight time,
    /// for that many seconds, to rehearse a camera failure (what the ground
    /// station and the autopilot are told, and the recovery).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stall: Option<[f64; 2]>,
}

/// How frames are fed to the pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// Every frame, as fast as the pipeline goes; none is dropped.
    EveryFrame,
    /// At this multiple of the source's clock; the oldest frame is dropped when behind.
    Speed(f64),
    /// A live camera: frames arrive at their own pace; the oldest is dropped when behind.
    Live,
}

/// The simulator's default playback speed: fast enough to watch a whole flight
/// in a quarter of its time.
pub const SIM_DEFAULT_SPEED: f64 = 4.0;

impl SourceSection {
    /// How frames are timed, the kind's default applied.
    pub fn frame_times(&self) -> FrameTimes {
        match (&self.timestamps, self.kind) {
            (Some(spelled), _) => FrameTimes::parse(spelled),
            (None, SourceKind::Video) => FrameTimes::Pts,
            (None, _) => FrameTimes::Rate,
        }
    }

    /// What `speed` means for this kind of source, its default applied.
    pub fn pacing(&self) -> Pacing {
        let speed = match (self.kind, self.speed) {
            (SourceKind::Rtsp | SourceKind::V4l2, _) => return Pacing::Live,
            (_, Some(speed)) => speed,
            (SourceKind::Sim, None) => SIM_DEFAULT_SPEED,
            (SourceKind::Images | SourceKind::Video, None) => 0.0,
        };
        if speed > 0.0 {
            Pacing::Speed(speed)
        } else {
            Pacing::EveryFrame
        }
    }
}

/// The camera model for real sources (the simulator brings its own).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSection {
    /// Horizontal field of view, degrees (square pixels, centred principal
    /// point, no distortion); used when there is no calibration.
    pub hfov_deg: f64,
    /// A calibration file: OpenCV's (YAML or JSON), ROS `camera_info` YAML
    /// or a Kalibr camchain. Its image size must be the frames' (`source.width`, `source.height`).
    pub calibration: Option<PathBuf>,
    /// How the camera sits on the body.
    pub mount: MountSection,
}

impl Default for CameraSection {
    fn default() -> Self {
        Self {
            hfov_deg: 70.0,
            calibration: None,
            mount: MountSection::default(),
        }
    }
}

/// The camera's mount on the body (forward-left-up), as measured on the
/// airframe: angles turn a camera that looks along the nose, `yaw_deg` to
/// the left, `pitch_deg` up, `roll_deg` right side down; the lever arm is
/// the lens's centre from the autopilot's reference point, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MountSection {
    pub roll_deg: f64,
    pub pitch_deg: f64,
    pub yaw_deg: f64,
    pub lever_arm_m: [f64; 3],
}

impl MountSection {
    pub fn mount(&self) -> towernav_geometry::CameraMount {
        towernav_geometry::CameraMount {
            roll: self.roll_deg.to_radians(),
            pitch: self.pitch_deg.to_radians(),
            yaw: self.yaw_deg.to_radians(),
            lever_arm_m: self.lever_arm_m,
        }
    }
}

impl CameraSection {
    /// The camera of a real source whose frames are `width` x `height`: the
    /// calibration file's, or a pinhole from `hfov_deg`; with the mount.
    pub fn camera(
        &self,
        width: u32,
        height: u32,
    ) -> Result<towernav_geometry::PinholeCamera, ConfigError> {
        use towernav_geometry::{Calibration, Intrinsics, PinholeCamera};
        let mount = self.mount.mount();
        let Some(path) = &self.calibration else {
            return Ok(PinholeCamera::pinhole(
                Intrinsics::from_hfov(width, height, self.hfov_deg),
                mount,
            ));
        };
        let bad = |reason: String| ConfigError::File {
            path: path.clone(),
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        let calibration = Calibration::parse(&text).map_err(|e| bad(e.to_string()))?;
        calibration
            .check_size(width, height)
            .map_err(|e| bad(e.to_string()))?;
        let camera = PinholeCamera {
            intrinsics: calibration.intrinsics,
            mount,
            distortion: calibration.distortion,
        };
        if let Some(p) = camera.uninvertible_pixel() {
            return Err(bad(format!(
                "its lens model cannot be inverted at pixel ({:.0}, {:.0}): the coefficients \
                 fold the image there (a calibration fitted on the centre only?)",
                p.x, p.y
            )));
        }
        Ok(camera)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttitudeKind {
    /// From the frame source (the simulator's IMU).
    Source,
    /// A flight log: ArduPilot `.bin`, MAVLink `.tlog`, PX4 `.ulg`, or a
    /// CSV of time_s,roll_deg,pitch_deg,heading_deg; told apart by extension.
    Log,
    /// The same as `log` (the name from when only CSV was read).
    Csv,
    /// The autopilot's MAVLink ATTITUDE messages.
    Mavlink,
    /// PX4's `vehicle_attitude` over Zenoh (`[px4] attitude_topic`, on
    /// `[ros2]`'s onboard Zenoh).
    Px4,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttitudeSection {
    pub kind: AttitudeKind,
    /// The flight log, for `log`.
    pub path: Option<PathBuf>,
    /// Camera-to-log clock offset, seconds: a frame at camera time `t` takes
    /// the log's attitude at `t + time_offset_s` (the log's clock is the
    /// autopilot's time since boot).
    pub time_offset_s: f64,
    /// Where to listen for ATTITUDE, for `mavlink` (e.g. `udpin:127.0.0.1:14551`).
    pub address: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DetectorKind {
    Yolo,
    /// The simulator's truth with noise; needs `source.kind = "sim"`.
    Oracle,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectorSection {
    pub kind: DetectorKind,
    /// The shipped default is the INT8 export (`training/quantize.py`): a
    /// fifth faster on the CPU for 0.01 less mAP50; `models/towers.onnx` is
    /// the float one.
    pub model: PathBuf,
    /// Name each box's type with the classifier at `type_model`, which reads
    /// the full-resolution crop (off: the detector's own types, which it
    /// confuses far more often at 0.4x).
    pub classify_types: bool,
    pub type_model: PathBuf,
    pub threads: usize,
    pub cuda: bool,
    pub min_score: f32,
    /// With the classifier: how much the detector's own type scores count
    /// against the crop's reading, 0 to 1 (0: the classifier alone).
    pub detector_type_weight: f32,
    /// How far the model's box tops and bottoms are taken to stray from the
    /// tower's, in pixels of the camera's frame, for any box: the localizer's
    /// measurement noise with this detector, with `edge_sigma_share`.
    pub edge_sigma_px: f64,
    /// The share of each box's height (for its top and bottom) and width
    /// (for its sides) that adds to `edge_sigma_px`: a learned detector's
    /// edges stray in proportion to the box (the shipped INT8 model's robust
    /// spread on `bench-localization`'s flights is 2.4 to 4.4 % of the box
    /// height; the default keeps to the low end, as `edge_sigma_px` and the
    /// small-box term add to it. With less, the benchmark's 2-sigma coverage
    /// comes into its band (92 and 98 % at 1 % on worlds 1003 and 1004), but
    /// its fixes err more).
    pub edge_sigma_share: f64,
    /// A side of a box within this share of its height of the image's border
    /// is taken as cut, not as the tower's top, foot or axis: the model stops
    /// tens of pixels short of the border on a near tower that the frame cuts.
    pub cut_margin_share: f64,
    /// The edge spread of a box the frame cuts, times that of a whole one:
    /// the model guesses the part it cannot see, and errs far more.
    pub cut_sigma_scale: f64,
    /// The published position covariance is the filter's times this: the
    /// noise model above is kept wide for weighing and gating, and with the
    /// shipped INT8 model it overstates the errors `bench-localization`
    /// measures (the fixes' median NEES 0.27-0.53 where 1.39 is honest). At
    /// 0.4, 95.9 % of that benchmark's errors fall inside the published
    /// 2-sigma ellipse, against 100 % unscaled (92.4-98.6 % on four worlds
    /// it was not fitted on). `pipeline.max_report_sigma_m` bounds the
    /// filter's own 1-sigma, before the scale.
    pub covariance_scale: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct LandmarksSection {
    /// Towers from a .csv or a landmark database; none: the simulator's world.
    pub file: Option<PathBuf>,
    /// Keep a replica of the ground station's landmarks here and follow its changes.
    pub replica: Option<PathBuf>,
}

impl DetectorSection {
    /// The type classifier's model, when it is on.
    pub fn type_model(&self) -> Option<&std::path::Path> {
        self.classify_types.then_some(self.type_model.as_path())
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineSection {
    /// `rays` (ours) or `paper` (the paper's method, the baseline; `seed` is its older name).
    pub method: String,
    /// Fuse fixes with the EKF.
    pub filter: bool,
    /// Take-off point [lat_deg, lon_deg, alt_m]: the mission datum and the
    /// filter's first guess. Needed for real sources; the simulator knows its own.
    pub takeoff: Option<[f64; 3]>,
    /// The filter reports an estimate only while its horizontal 1-sigma is
    /// within this, metres (5: about a consumer GNSS receiver's spread;
    /// beyond it the autopilot's own dead reckoning is as good): it ends a
    /// coast with no tower in view, and holds back an uncertain fix.
    /// (`max_coast_sigma_m` is its older name.)
    #[serde(alias = "max_coast_sigma_m")]
    pub max_report_sigma_m: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MavlinkMessages {
    /// GPS_INPUT: a GNSS stand-in (ArduPilot, PX4).
    GpsInput,
    /// ODOMETRY: external vision (PX4's EKF2 EV fusion, ArduPilot's VISO).
    Odometry,
    /// GPS_INPUT and ODOMETRY.
    Both,
    /// GLOBAL_POSITION_SENSOR: PX4's auxiliary global position (AGP).
    AuxGlobalPosition,
}

impl MavlinkMessages {
    pub fn position(self) -> Option<PositionMessage> {
        match self {
            Self::GpsInput | Self::Both => Some(PositionMessage::GpsInput),
            Self::AuxGlobalPosition => Some(PositionMessage::AuxGlobalPosition),
            Self::Odometry => None,
        }
    }

    pub fn odometry(self) -> bool {
        matches!(self, Self::Odometry | Self::Both)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MavlinkSection {
    pub enabled: bool,
    /// `udpout:<host>:<port>`, or `serial:<device>:<baud>`.
    pub address: String,
    pub messages: MavlinkMessages,
    /// The position message's rate (GPS_INPUT or GLOBAL_POSITION_SENSOR), Hz.
    pub rate_hz: f64,
    /// ODOMETRY's rate, Hz: the filter's prediction between frames (PX4 wants 30-50).
    pub odometry_rate_hz: f64,
    /// The vehicle's system id: the autopilot's own.
    pub system_id: u8,
    /// This component's id: 197, MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY, by default.
    pub component_id: u8,
    /// The fix is 3-D only this long after a tower fix, seconds.
    pub fresh_fix_s: f64,
    /// Coasting, the fix is 2-D at most this long after the last tower fix,
    /// then none; the filter's `pipeline.max_report_sigma_m` usually ends
    /// the coast sooner.
    pub coast_fix_s: f64,
}

impl MavlinkSection {
    /// What the core's link sends, and when.
    pub fn link_config(&self, accel_sigma: f64, coast_max_sigma_m: f64) -> LinkConfig {
        let every = |hz: f64| Duration::from_secs_f64(1.0 / hz);
        LinkConfig {
            system_id: self.system_id,
            position: self.messages.position().map(|m| (m, every(self.rate_hz))),
            odometry_every: self
                .messages
                .odometry()
                .then(|| every(self.odometry_rate_hz)),
            fresh_fix: Duration::from_secs_f64(self.fresh_fix_s),
            coast_fix: Duration::from_secs_f64(self.coast_fix_s),
            coast_max_sigma_m,
            accel_sigma,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSection {
    /// One JSON line per published estimate.
    pub jsonl: Option<PathBuf>,
    /// Annotated frames (boxes, track and tower ids, pose) as JPEGs in this
    /// folder; the demo build only, as the drawing links the plotting library.
    pub annotated: Option<PathBuf>,
    /// JPEG previews per second on Zenoh; 0: none.
    pub preview_hz: f64,
    /// The autopilot's GNSS positions (MAVLink GLOBAL_POSITION_INT), one JSON
    /// line each with the frame seen last: what a survey flight records.
    pub autopilot_log: Option<PathBuf>,
}

impl Default for EdgeConfig {
    fn default() -> Self {
        Self {
            fleet: "demo".into(),
            uav: "uav1".into(),
            zenoh: ZenohSection::default(),
            source: SourceSection::default(),
            camera: CameraSection::default(),
            attitude: AttitudeSection::default(),
            detector: DetectorSection::default(),
            landmarks: LandmarksSection::default(),
            pipeline: PipelineSection::default(),
            mavlink: MavlinkSection::default(),
            ros2: Ros2Section::default(),
            px4: Px4Section::default(),
            output: OutputSection::default(),
        }
    }
}

impl Default for ZenohSection {
    fn default() -> Self {
        Self {
            listen: vec!["tcp/127.0.0.1:7447".into()],
            connect: vec![],
            mode: ZenohMode::Peer,
            credentials: None,
        }
    }
}

impl Default for SourceSection {
    fn default() -> Self {
        Self {
            kind: SourceKind::Sim,
            path: None,
            fps: 30.0,
            timestamps: None,
            width: 1280,
            height: 720,
            flight: None,
            world: None,
            random_world: None,
            seed: 1,
            max_frames: None,
            speed: None,
            queue: 2,
            stall: None,
        }
    }
}

impl Default for AttitudeSection {
    fn default() -> Self {
        Self {
            kind: AttitudeKind::Source,
            path: None,
            time_offset_s: 0.0,
            address: "udpin:127.0.0.1:14551".into(),
        }
    }
}

impl Default for DetectorSection {
    fn default() -> Self {
        Self {
            kind: DetectorKind::Yolo,
            model: "models/towers-int8.onnx".into(),
            classify_types: true,
            type_model: "models/tower-types-int8.onnx".into(),
            threads: 2,
            cuda: false,
            min_score: 0.25,
            detector_type_weight: towernav_core::detector::postprocess::DETECTOR_TYPE_WEIGHT,
            edge_sigma_px: YOLO_EDGE_SIGMA_PX,
            edge_sigma_share: YOLO_EDGE_SIGMA_SHARE,
            cut_margin_share: YOLO_CUT_MARGIN_SHARE,
            cut_sigma_scale: YOLO_CUT_SIGMA_SCALE,
            covariance_scale: YOLO_COVARIANCE_SCALE,
        }
    }
}

/// The box-edge spread the localizer assumes for a model, pixels (see `edge_sigma_px`).
pub const YOLO_EDGE_SIGMA_PX: f64 = 1.0;

/// The share of the box size that adds to it (see `edge_sigma_share`).
pub const YOLO_EDGE_SIGMA_SHARE: f64 = 0.025;

/// What the published covariance is scaled by (see `covariance_scale`).
pub const YOLO_COVARIANCE_SCALE: f64 = 0.4;

/// How near the border, as a share of the box height, a box's side is taken
/// as cut (see `cut_margin_share`). At 0.15 a near tower's box that stopped
/// 99 px (a fifth of its height) short of the bottom border was read as the
/// whole tower, and one-tower fixes erred by 35-47 m while claiming 6 m.
pub const YOLO_CUT_MARGIN_SHARE: f64 = 0.25;

/// How much more a cut box's edges stray (see `cut_sigma_scale`).
pub const YOLO_CUT_SIGMA_SCALE: f64 = 3.0;

impl Default for PipelineSection {
    fn default() -> Self {
        Self {
            method: "rays".into(),
            filter: true,
            max_report_sigma_m: 5.0,
            takeoff: None,
        }
    }
}

impl Default for MavlinkSection {
    fn default() -> Self {
        Self {
            enabled: false,
            address: "udpout:127.0.0.1:14550".into(),
            messages: MavlinkMessages::GpsInput,
            rate_hz: 5.0,
            odometry_rate_hz: 30.0,
            system_id: 1,
            // The edge is a vision position source: the VIO component id names
            // it so to the autopilot's and ground station's component lists,
            // and leaves 191 to a companion computer's general software
            // (MAVROS, mavlink-router) on the same vehicle.
            component_id: 197,
            fresh_fix_s: 1.0,
            coast_fix_s: 20.0,
        }
    }
}

impl Default for OutputSection {
    fn default() -> Self {
        Self {
            jsonl: None,
            annotated: None,
            preview_hz: 2.0,
            autopilot_log: None,
        }
    }
}

impl EdgeConfig {
    /// What the published covariance is scaled by: the model's calibration
    /// (`detector.covariance_scale`), none for the simulator's oracle boxes.
    pub fn covariance_scale(&self) -> f64 {
        if self.detector.kind == DetectorKind::Yolo {
            self.detector.covariance_scale
        } else {
            1.0
        }
    }

    /// Read a TOML file; unknown keys and wrong types are errors with their place.
    pub fn read(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Self::parse(&text).map_err(|reason| ConfigError::File {
            path: path.to_path_buf(),
            reason,
        })
    }

    pub fn parse(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Everything that would fail later, refused now with the field's name.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_link()?;
        self.validate_source()?;
        self.validate_detector()?;
        self.validate_pose_inputs()?;
        self.ros2.validate(&self.px4)?;
        self.validate_outputs()
    }

    /// Whether the onboard Zenoh (`[ros2]`'s endpoints) is opened: for ROS 2
    /// topics, PX4's auxiliary global position, or PX4's attitude.
    pub fn onboard_zenoh(&self) -> bool {
        self.ros2.enabled || self.px4.enabled || self.attitude.kind == AttitudeKind::Px4
    }

    /// Ids and Zenoh endpoints.
    fn validate_link(&self) -> Result<(), ConfigError> {
        let invalid =
            |field: &'static str, reason: String| Err(ConfigError::Invalid { field, reason });
        for (field, id) in [("fleet", &self.fleet), ("uav", &self.uav)] {
            if let Err(e) = towernav_protocol::NodeId::new(id.clone()) {
                return invalid(field, e.to_string());
            }
        }
        let scheme = if self.zenoh.credentials.is_some() {
            "tls/"
        } else {
            "tcp/"
        };
        for endpoint in self.zenoh.listen.iter().chain(&self.zenoh.connect) {
            if !endpoint.starts_with(scheme) {
                return invalid(
                    "zenoh.listen/connect",
                    format!(
                        "{endpoint:?}: towernav speaks {scheme}<host>:<port> {}",
                        if scheme == "tls/" {
                            "when zenoh.credentials is set (plain tcp would go around them)"
                        } else {
                            "without zenoh.credentials (tls/ needs them)"
                        }
                    ),
                );
            }
        }
        Ok(())
    }

    /// The frame source.
    fn validate_source(&self) -> Result<(), ConfigError> {
        let invalid =
            |field: &'static str, reason: String| Err(ConfigError::Invalid { field, reason });
        let s = &self.source;
        if s.kind != SourceKind::Sim && s.path.is_none() {
            return invalid("source.path", format!("a {:?} source needs a path", s.kind));
        }
        if !(s.fps > 0.0 && s.fps <= 1000.0) {
            return invalid("source.fps", format!("{} is not in (0, 1000]", s.fps));
        }
        if s.width < 32 || s.height < 32 || s.width > 8192 || s.height > 8192 {
            return invalid(
                "source.width/height",
                format!("{}x{} is not a camera size", s.width, s.height),
            );
        }
        if let Some([at_s, for_s]) = s.stall {
            if s.kind != SourceKind::Sim {
                return invalid(
                    "source.stall",
                    "a stall is rehearsed with the simulator only".into(),
                );
            }
            if !(at_s >= 0.0 && (0.0..=600.0).contains(&for_s)) {
                return invalid(
                    "source.stall",
                    format!("[{at_s}, {for_s}]: a start of 0 s or more, 0 to 600 s long"),
                );
            }
        }
        if let Some(speed) = s.speed {
            if speed.is_nan() || speed < 0.0 {
                return invalid("source.speed", format!("{speed} must be 0 or more"));
            }
            if matches!(s.kind, SourceKind::Rtsp | SourceKind::V4l2) {
                return invalid(
                    "source.speed",
                    format!("a live {:?} camera paces itself; remove the speed", s.kind),
                );
            }
        }
        if s.kind != SourceKind::Sim && (s.world.is_some() || s.random_world.is_some()) {
            return invalid(
                "source.world",
                "a world is for the simulator (source.kind = \"sim\")".into(),
            );
        }
        if s.world.is_some() && s.random_world.is_some() {
            return invalid(
                "source.world",
                "give a world file or a random world's seed, not both".into(),
            );
        }
        match (s.kind, s.frame_times()) {
            (SourceKind::Images, FrameTimes::Pts) => {
                return invalid(
                    "source.timestamps",
                    "pts are a video's; an image folder takes rate, names, names_ms, names_us, \
                     names_ns or a timestamps file"
                        .into(),
                );
            }
            (SourceKind::Video, FrameTimes::Names { .. } | FrameTimes::File(_)) => {
                return invalid(
                    "source.timestamps",
                    "a video's frames are timed by pts or rate".into(),
                );
            }
            (SourceKind::Sim | SourceKind::Rtsp | SourceKind::V4l2, times)
                if s.timestamps.is_some() && times != FrameTimes::Rate =>
            {
                return invalid(
                    "source.timestamps",
                    format!("a {:?} source times its own frames; leave it unset", s.kind),
                );
            }
            (_, FrameTimes::File(path)) if !path.is_file() => {
                return invalid(
                    "source.timestamps",
                    format!("no timestamps file at {}", path.display()),
                );
            }
            _ => {}
        }
        if s.queue == 0 || s.queue > 64 {
            return invalid(
                "source.queue",
                format!("{} is not between 1 and 64", s.queue),
            );
        }
        Ok(())
    }

    /// The detector, and the outputs only some builds have.
    fn validate_detector(&self) -> Result<(), ConfigError> {
        let invalid =
            |field: &'static str, reason: String| Err(ConfigError::Invalid { field, reason });
        let s = &self.source;
        if self.detector.kind == DetectorKind::Oracle && s.kind != SourceKind::Sim {
            return invalid(
                "detector.kind",
                "the oracle needs the simulator's truth (source.kind = \"sim\")".into(),
            );
        }
        if cfg!(not(feature = "demo")) && self.output.annotated.is_some() {
            return invalid(
                "output.annotated",
                "this onboard build draws no annotated frames (build towernav-edge with `--features demo`)"
                    .into(),
            );
        }
        // The localizer's noise model, each within what a detector could mean.
        let d = &self.detector;
        for (key, value, (lo, hi), unit) in [
            (
                "detector.edge_sigma_px",
                d.edge_sigma_px,
                (0.1, 50.0),
                " px",
            ),
            (
                "detector.edge_sigma_share",
                d.edge_sigma_share,
                (0.0, 0.5),
                "",
            ),
            (
                "detector.covariance_scale",
                d.covariance_scale,
                (0.01, 10.0),
                "",
            ),
            (
                "detector.cut_margin_share",
                d.cut_margin_share,
                (0.0, 0.5),
                "",
            ),
            (
                "detector.cut_sigma_scale",
                d.cut_sigma_scale,
                (1.0, 20.0),
                "",
            ),
        ] {
            if !(value.is_finite() && (lo..=hi).contains(&value)) {
                return invalid(key, format!("{value} is not between {lo} and {hi}{unit}"));
            }
        }
        if self.detector.threads == 0 || self.detector.threads > 64 {
            return invalid(
                "detector.threads",
                format!("{} is not between 1 and 64", self.detector.threads),
            );
        }
        if !(0.0..1.0).contains(&self.detector.min_score) {
            return invalid(
                "detector.min_score",
                format!("{} is not in [0, 1)", self.detector.min_score),
            );
        }
        if !(0.0..=1.0).contains(&self.detector.detector_type_weight) {
            return invalid(
                "detector.detector_type_weight",
                format!("{} is not in [0, 1]", self.detector.detector_type_weight),
            );
        }
        Ok(())
    }

    /// Attitude, camera and the pipeline's start.
    fn validate_pose_inputs(&self) -> Result<(), ConfigError> {
        let invalid =
            |field: &'static str, reason: String| Err(ConfigError::Invalid { field, reason });
        let s = &self.source;
        match self.attitude.kind {
            AttitudeKind::Source if s.kind != SourceKind::Sim => {
                return invalid(
                    "attitude.kind",
                    "only the simulator stamps frames with attitude; use \"log\" or \"mavlink\""
                        .into(),
                );
            }
            AttitudeKind::Log | AttitudeKind::Csv if self.attitude.path.is_none() => {
                return invalid(
                    "attitude.path",
                    "a flight log attitude input needs a path".into(),
                );
            }
            _ => {}
        }
        if !(self.camera.hfov_deg > 5.0 && self.camera.hfov_deg < 170.0) {
            return invalid(
                "camera.hfov_deg",
                format!("{} is not in (5, 170)", self.camera.hfov_deg),
            );
        }
        let m = &self.camera.mount;
        if ![m.roll_deg, m.pitch_deg, m.yaw_deg]
            .iter()
            .all(|a| a.abs() <= 180.0)
            || !m
                .lever_arm_m
                .iter()
                .all(|x| x.is_finite() && x.abs() < 10.0)
        {
            return invalid(
                "camera.mount",
                "angles are degrees within +-180 and the lever arm metres within +-10".into(),
            );
        }
        if !self.attitude.time_offset_s.is_finite() {
            return invalid("attitude.time_offset_s", "is not a finite number".into());
        }
        if s.kind != SourceKind::Sim {
            self.camera.camera(s.width, s.height)?;
        }
        match self.pipeline.takeoff {
            None if s.kind != SourceKind::Sim => {
                return invalid(
                    "pipeline.takeoff",
                    "a real source needs the take-off point [lat_deg, lon_deg, alt_m]".into(),
                );
            }
            Some([lat, lon, alt]) => {
                if let Err(e) = towernav_geometry::Geodetic::new(lat, lon, alt) {
                    return invalid("pipeline.takeoff", e.to_string());
                }
            }
            None => {}
        }
        if towernav_core::localizer::Method::from_name(&self.pipeline.method).is_none() {
            return invalid(
                "pipeline.method",
                format!(
                    "{:?} is not \"rays\" or \"paper\" (also \"seed\")",
                    self.pipeline.method
                ),
            );
        }
        let sigma = self.pipeline.max_report_sigma_m;
        if !(sigma > 0.0 && sigma <= 1000.0) {
            return invalid(
                "pipeline.max_report_sigma_m",
                format!("{sigma} is not in (0, 1000] metres"),
            );
        }
        Ok(())
    }

    /// MAVLink and the preview.
    fn validate_outputs(&self) -> Result<(), ConfigError> {
        let invalid =
            |field: &'static str, reason: String| Err(ConfigError::Invalid { field, reason });
        if self.mavlink.enabled {
            let m = &self.mavlink;
            for (field, hz) in [
                ("mavlink.rate_hz", m.rate_hz),
                ("mavlink.odometry_rate_hz", m.odometry_rate_hz),
            ] {
                if !(hz > 0.0 && hz <= 50.0) {
                    return invalid(field, format!("{hz} is not in (0, 50]"));
                }
            }
            if !(m.fresh_fix_s > 0.0 && m.fresh_fix_s <= m.coast_fix_s && m.coast_fix_s <= 60.0) {
                return invalid(
                    "mavlink.fresh_fix_s",
                    format!(
                        "{} and coast_fix_s {}: need 0 < fresh_fix_s <= coast_fix_s <= 60",
                        m.fresh_fix_s, m.coast_fix_s
                    ),
                );
            }
            if m.component_id == 0 {
                return invalid(
                    "mavlink.component_id",
                    "0 is the broadcast id, not a component's".into(),
                );
            }
            if !(self.mavlink.address.starts_with("udpout:")
                || self.mavlink.address.starts_with("serial:"))
            {
                return invalid(
                    "mavlink.address",
                    format!(
                        "{:?}: use udpout:<host>:<port> or serial:<device>:<baud>",
                        self.mavlink.address
                    ),
                );
            }
        }
        if self.output.autopilot_log.is_some() && !self.mavlink.enabled {
            return invalid(
                "output.autopilot_log",
                "needs the MAVLink link: set mavlink.enabled (or --mavlink)".into(),
            );
        }
        if !(self.output.preview_hz >= 0.0 && self.output.preview_hz <= 30.0) {
            return invalid(
                "output.preview_hz",
                format!("{} is not in [0, 30]", self.output.preview_hz),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_round_trip_through_toml() {
        let config = EdgeConfig::default();
        config.validate().expect("defaults are valid");
        assert_eq!(
            EdgeConfig::parse(&config.to_toml()).expect("parses"),
            config
        );
    }

    #[test]
    fn the_shipped_fleet_config_is_secured_and_valid() {
        let mut config =
            EdgeConfig::parse(include_str!("../../../deploy/edge.toml")).expect("parses");
        // The calibration file is the user's, read when validating.
        assert!(config.camera.calibration.is_some());
        config.camera.calibration = None;
        config.validate().expect("valid");
        assert!(config.zenoh.credentials.is_some());
        assert!(
            config
                .zenoh
                .listen
                .iter()
                .chain(&config.zenoh.connect)
                .all(|e| e.starts_with("tls/"))
        );
        // Plain tcp beside the credentials is refused, naming the endpoint.
        let mut plain = config.clone();
        plain.zenoh.connect = vec!["tcp/10.0.0.1:7447".into()];
        let err = plain.validate().expect_err("plain tcp refused").to_string();
        assert!(err.contains("tcp/10.0.0.1:7447"), "{err}");
        // And tls without credentials.
        let mut bare = config;
        bare.zenoh.credentials = None;
        assert!(bare.validate().is_err());
    }

    #[test]
    fn a_partial_file_keeps_the_other_defaults() {
        let config = EdgeConfig::parse(
            "uav = \"scout7\"\n[source]\nkind = \"images\"\npath = \"/data/frames\"\n[attitude]\nkind = \"csv\"\npath = \"att.csv\"\n[pipeline]\ntakeoff = [30.5, 114.3, 20.0]\n",
        )
        .expect("parses");
        assert_eq!(config.uav, "scout7");
        assert_eq!(config.source.fps, 30.0);
        config.validate().expect("valid");
    }

    #[test]
    fn the_report_bound_keeps_its_older_name() {
        let config = EdgeConfig::parse("[pipeline]\nmax_coast_sigma_m = 8.0\n")
            .expect("the older name parses");
        assert_eq!(config.pipeline.max_report_sigma_m, 8.0);
    }

    #[test]
    fn recorded_frames_are_all_processed_unless_pacing_is_asked_for() {
        let source = |text: &str| EdgeConfig::parse(text).expect("parses").source;
        let images = "[source]\nkind = \"images\"\npath = \"f\"\n";
        assert_eq!(source(images).pacing(), Pacing::EveryFrame);
        let video = "[source]\nkind = \"video\"\npath = \"f.mp4\"\n";
        assert_eq!(source(video).pacing(), Pacing::EveryFrame);
        assert_eq!(
            source(&format!("{images}speed = 1\n")).pacing(),
            Pacing::Speed(1.0)
        );
        assert_eq!(
            source("").pacing(),
            Pacing::Speed(SIM_DEFAULT_SPEED),
            "the simulator keeps its default"
        );
        assert_eq!(source("[source]\nspeed = 0\n").pacing(), Pacing::EveryFrame);
        let rtsp = "[source]\nkind = \"rtsp\"\npath = \"rtsp://cam\"\n";
        assert_eq!(source(rtsp).pacing(), Pacing::Live);
    }

    #[test]
    fn a_calibration_file_gives_the_lens_and_a_wrong_one_says_why() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("camera.yaml");
        let ros = |k1: f64| {
            format!(
                "image_width: 1280\nimage_height: 720\ncamera_name: nose\n\
                 camera_matrix:\n  rows: 3\n  cols: 3\n  data: [900, 0, 640, 0, 900, 360, 0, 0, 1]\n\
                 distortion_model: plumb_bob\n\
                 distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [{k1}, 0.08, 0, 0, 0]\n"
            )
        };
        let config = |width: u32| {
            EdgeConfig::parse(&format!(
                "[source]\nkind = \"images\"\npath = \"f\"\nwidth = {width}\nheight = 720\n\
                 [attitude]\nkind = \"csv\"\npath = \"a.csv\"\n\
                 [pipeline]\ntakeoff = [30.5, 114.3, 20.0]\n\
                 [camera]\ncalibration = {:?}\n[camera.mount]\npitch_deg = -10\nlever_arm_m = [0.1, 0, -0.05]\n",
                file.display().to_string()
            ))
            .expect("parses")
        };
        std::fs::write(&file, ros(-0.28)).expect("write");
        let good = config(1280);
        good.validate().expect("valid");
        let camera = good.camera.camera(1280, 720).expect("camera");
        assert!(matches!(
            camera.distortion,
            towernav_geometry::Distortion::RadialTangential { k1, .. } if k1 == -0.28
        ));
        assert!((camera.mount.pitch.to_degrees() + 10.0).abs() < 1e-12);
        assert_eq!(camera.mount.lever_arm_m, [0.1, 0.0, -0.05]);

        let err = config(1920).validate().expect_err("size").to_string();
        assert!(
            err.contains("camera.yaml") && err.contains("1280x720") && err.contains("1920x720"),
            "{err}"
        );
        // A strong positive k2 against k1 folds the image's corners back.
        std::fs::write(&file, ros(-1.5).replace("0.08,", "0.9,")).expect("write");
        let err = config(1280).validate().expect_err("folds").to_string();
        assert!(err.contains("cannot be inverted at pixel"), "{err}");
        std::fs::write(&file, "image_width: 1280\n").expect("write");
        let err = config(1280).validate().expect_err("no camera").to_string();
        assert!(
            err.contains("camera.yaml") && err.contains("no camera found"),
            "{err}"
        );
    }

    #[test]
    fn mistakes_are_named() {
        let err = EdgeConfig::parse("[source]\nfsp = 30\n").expect_err("typo");
        assert!(err.contains("fsp"), "{err}");
        let err = EdgeConfig::parse("[source]\nfps = \"fast\"\n").expect_err("type");
        assert!(err.contains("fps"), "{err}");
        let cases: [(&str, &str); 16] = [
            (
                "[source]\nkind = \"v4l2\"\npath = \"/dev/video0\"\nspeed = 2\n",
                "source.speed",
            ),
            (
                "[source]\nkind = \"images\"\npath = \"x\"\nrandom_world = 3\n",
                "source.world",
            ),
            (
                "[source]\nworld = \"t.csv\"\nrandom_world = 3\n",
                "source.world",
            ),
            ("[source]\nkind = \"video\"\n", "source.path"),
            (
                "[detector]\ndetector_type_weight = 1.5\n",
                "detector.detector_type_weight",
            ),
            ("[source]\nfps = 0\n", "source.fps"),
            ("[detector]\nedge_sigma_px = 0\n", "detector.edge_sigma_px"),
            (
                "[detector]\nedge_sigma_share = -0.1\n",
                "detector.edge_sigma_share",
            ),
            (
                "[detector]\ncovariance_scale = 0\n",
                "detector.covariance_scale",
            ),
            (
                "[detector]\ncut_margin_share = 0.9\n",
                "detector.cut_margin_share",
            ),
            (
                "[detector]\ncut_sigma_scale = 0.5\n",
                "detector.cut_sigma_scale",
            ),
            (
                "[source]\nkind = \"images\"\npath = \"x\"\n[detector]\nkind = \"oracle\"\n",
                "detector.kind",
            ),
            (
                "[source]\nkind = \"images\"\npath = \"x\"\n",
                "attitude.kind",
            ),
            (
                "[source]\nkind = \"images\"\npath = \"x\"\n[attitude]\nkind = \"csv\"\npath = \"a.csv\"\n",
                "pipeline.takeoff",
            ),
            (
                "[zenoh]\nlisten = [\"udp/0.0.0.0:7447\"]\n",
                "zenoh.listen/connect",
            ),
            (
                "[mavlink]\nenabled = true\naddress = \"udpin:0.0.0.0:14550\"\n",
                "mavlink.address",
            ),
        ];
        for (text, field) in cases {
            let err = EdgeConfig::parse(text)
                .expect("parses")
                .validate()
                .expect_err(field)
                .to_string();
            assert!(err.contains(field), "{text}: {err}");
        }
    }
}
