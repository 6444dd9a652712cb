//! The messages. Units are in the field names; angles are radians unless named `_deg`.

use serde::{Deserialize, Serialize};
use towernav_geometry::{Geodetic, PixelBox};

use crate::codec::Message;
use crate::ids::NodeId;
use crate::keys::{Topic, UavMessage};
pub use crate::tower_type::{TowerType, TowerTypeError};

/// How a pose was computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PoseMethod {
    /// The paper's localization by landmarks: level camera, mean over towers.
    /// On the wire as `seed_lbl`, its name since the first release.
    #[serde(rename = "seed_lbl", alias = "paper_lbl")]
    PaperLbl,
    /// Ours, one frame: attitude-compensated rays, robust least squares over towers.
    RaysLbl,
    /// Ours fused over time by the EKF.
    RaysEkf,
    /// The paper's fixes fused over time by the EKF; on the wire as `seed_ekf`.
    #[serde(rename = "seed_ekf", alias = "paper_ekf")]
    PaperEkf,
}

/// One pose estimate of one UAV for one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseEstimate {
    pub uav: NodeId,
    /// Capture time of the frame, seconds on the source's clock.
    pub time_s: f64,
    /// Frame sequence number from the source.
    pub seq: u64,
    /// Position in the mission's ENU frame (metres about the datum in [`StatusHeartbeat`]).
    pub east_m: f64,
    pub north_m: f64,
    pub up_m: f64,
    /// The same position in WGS84.
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
    /// Heading, counter-clockwise from east (ENU).
    pub yaw_rad: f64,
    /// Row-major covariance of (east, north, up, yaw) in m^2, m*rad and rad^2.
    pub covariance: [[f64; 4]; 4],
    pub method: PoseMethod,
    /// Database ids of the towers the fix used; empty while coasting.
    pub towers_used: Vec<String>,
    /// Seconds since the last tower fix the filter fused: 0 for a pose fixed
    /// by towers in its own frame; above 0 the pose is the filter's
    /// prediction (coasting through a gap), its covariance grown with the
    /// time, published until it passes the edge's report bound.
    #[serde(default)]
    pub coast_s: f64,
}

impl PoseEstimate {
    /// Whether this pose is a prediction, not a fix from towers in view.
    pub fn is_coasting(&self) -> bool {
        self.coast_s > 0.0
    }
}

/// One tracked box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Track {
    pub track_id: u64,
    pub bbox: PixelBox,
    pub tower_type: TowerType,
    /// Database id of the tower the track is bound to, if any.
    pub tower_id: Option<String>,
    /// Whether an operator's correction pinned the binding.
    pub pinned: bool,
    /// How sure the edge is of the binding, 0..=1: 1 when pinned or when it
    /// agrees with the tracked pose, falling as it keeps disagreeing. `None` when unbound.
    #[serde(default)]
    pub confidence: Option<f64>,
}

/// All confirmed tracks of one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackReport {
    pub uav: NodeId,
    pub time_s: f64,
    pub seq: u64,
    pub tracks: Vec<Track>,
    /// The edge's run these track numbers belong to: numbers start again
    /// with each run, so a correction names the run it was made in. 0 from
    /// an edge that does not say.
    #[serde(default)]
    pub session: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeState {
    /// Running, no fix yet.
    Initializing,
    /// The last frame gave a fix, and the filter took it.
    Localized,
    /// No fix in the last frame: the estimate is the filter's prediction,
    /// its covariance growing.
    Coasting,
    /// No estimate: towers out of sight too long, the pose is lost, or the
    /// filter's estimate is beyond its report bound (an uncertain fix held back).
    NoFix,
}

/// How well the daemon itself is doing, apart from whether it has a fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Health {
    #[default]
    Ok,
    /// Working, but falling behind (dropping frames) or failing some frames.
    Degraded,
    /// The frame source or the detector has stopped.
    Failed,
}

/// Periodic health of an edge daemon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatusHeartbeat {
    pub uav: NodeId,
    pub time_s: f64,
    pub state: EdgeState,
    pub frames_processed: u64,
    /// Frames per second over the last heartbeat period.
    pub frame_rate_hz: f64,
    pub landmarks_loaded: u32,
    pub health: Health,
    /// Frames the bounded queue dropped (oldest first) because the pipeline fell behind, since start.
    pub frames_dropped: u64,
    /// Frames whose decoding or detection failed, since start.
    pub frames_failed: u64,
    /// Capture-to-publish latency over the last heartbeat period, milliseconds.
    pub latency_p50_ms: f64,
    pub latency_p99_ms: f64,
    /// The detector: a model file name, or "oracle".
    pub detector: String,
    /// The ENU datum of this UAV's poses.
    pub datum_lat_deg: f64,
    pub datum_lon_deg: f64,
    pub datum_alt_m: f64,
}

/// An operator's correction: bind `track_id` to `tower_id` (or unbind with `None`) until the track ends.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdCorrection {
    pub uav: NodeId,
    /// Chosen by the sender; echoed in the acknowledgement.
    pub request_id: u64,
    pub track_id: u64,
    pub tower_id: Option<String>,
    pub issued_by: String,
    /// Hand the track back to the edge's own identity: the operator's pin is
    /// dropped and `tower_id` ignored (an undo of a correction of a track the
    /// edge had bound itself). Absent in older senders' messages: false.
    #[serde(default)]
    pub release: bool,
    /// The edge run (`TrackReport::session`) whose track the operator
    /// picked; an edge in another run refuses the correction. Absent: any run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub session: Option<u64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CorrectionAck {
    pub uav: NodeId,
    pub request_id: u64,
    pub accepted: bool,
    /// Why it was refused, when it was.
    pub reason: Option<String>,
}

/// A surveyed tower as the database holds it.
///
/// Heights are metres; `ground_elev_m` is the foot's height above the WGS84
/// ellipsoid (not above mean sea level: convert survey orthometric heights first).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkRecord {
    pub id: String,
    pub tower_type: TowerType,
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Ground elevation at the tower foot, metres above the WGS84 ellipsoid.
    pub ground_elev_m: f64,
    /// Height from foot to top, metres.
    pub height_m: f64,
    /// Side of the square base, metres.
    #[serde(default)]
    pub base_width_m: Option<f64>,
    /// The power line the tower carries, e.g. "220kV Xinjin II".
    #[serde(default)]
    pub line_name: Option<String>,
    /// Where the position came from, e.g. "RTK 2026-05", "OSM", "drawing".
    #[serde(default)]
    pub survey_source: Option<String>,
    /// One-sigma horizontal accuracy of the surveyed foot, metres.
    #[serde(default)]
    pub sigma_horizontal_m: Option<f64>,
    /// One-sigma vertical accuracy of foot elevation and height, metres.
    #[serde(default)]
    pub sigma_vertical_m: Option<f64>,
    #[serde(default)]
    pub notes: String,
    /// Unix seconds of the last change; set by the database.
    #[serde(default)]
    pub updated_at_unix_s: i64,
    /// Who made the last change; set by the database from the writer's name.
    #[serde(default)]
    pub updated_by: String,
    /// Database revision of the last change to this record; set by the database.
    #[serde(default)]
    pub revision: u64,
}

impl LandmarkRecord {
    /// Where the tower stands: its foot, on the ellipsoid's height of the ground.
    pub fn foot(&self) -> Geodetic {
        Geodetic {
            lat_deg: self.lat_deg,
            lon_deg: self.lon_deg,
            height_m: self.ground_elev_m,
        }
    }

    /// A record with the required survey fields and no optional ones.
    pub fn new(
        id: impl Into<String>,
        tower_type: TowerType,
        lat_deg: f64,
        lon_deg: f64,
        ground_elev_m: f64,
        height_m: f64,
    ) -> Self {
        Self {
            id: id.into(),
            tower_type,
            lat_deg,
            lon_deg,
            ground_elev_m,
            height_m,
            base_width_m: None,
            line_name: None,
            survey_source: None,
            sigma_horizontal_m: None,
            sigma_vertical_m: None,
            notes: String::new(),
            updated_at_unix_s: 0,
            updated_by: String::new(),
            revision: 0,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum LandmarkChangeOp {
    /// Boxed: a record is ten times the size of a removal.
    Upsert {
        record: Box<LandmarkRecord>,
    },
    Remove {
        id: String,
    },
}

/// One change of the landmark database, in revision order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkChange {
    pub revision: u64,
    pub change: LandmarkChangeOp,
}

impl Message for PoseEstimate {
    const KIND: &'static str = "pose";
}
impl UavMessage for PoseEstimate {
    const TOPIC: Topic = Topic::Pose;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}
impl Message for TrackReport {
    const KIND: &'static str = "tracks";
}
impl UavMessage for TrackReport {
    const TOPIC: Topic = Topic::Tracks;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}
impl Message for StatusHeartbeat {
    const KIND: &'static str = "status";
}
impl UavMessage for StatusHeartbeat {
    const TOPIC: Topic = Topic::Status;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}
impl Message for IdCorrection {
    const KIND: &'static str = "id_correction";
}
impl UavMessage for IdCorrection {
    const TOPIC: Topic = Topic::Correction;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}
impl Message for CorrectionAck {
    const KIND: &'static str = "correction_ack";
}
impl UavMessage for CorrectionAck {
    const TOPIC: Topic = Topic::CorrectionAck;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}
impl Message for LandmarkRecord {
    const KIND: &'static str = "landmark";
}
impl Message for LandmarkChange {
    const KIND: &'static str = "landmark_change";
}

/// One detector output box: what a detector (real or the simulator's oracle) hands the tracker.
/// A wire type so detections can be recorded and replayed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub bbox: PixelBox,
    pub tower_type: TowerType,
    /// Detector confidence in 0..=1.
    pub score: f64,
}

/// The detector's boxes for one frame, before tracking.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionReport {
    pub uav: NodeId,
    pub time_s: f64,
    pub seq: u64,
    pub detections: Vec<Detection>,
}

impl Message for DetectionReport {
    const KIND: &'static str = "detection_report";
}
impl UavMessage for DetectionReport {
    const TOPIC: Topic = Topic::Detections;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}

/// A JPEG of the camera view, sent at a low rate for the operator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Preview {
    pub uav: NodeId,
    pub time_s: f64,
    pub seq: u64,
    /// The frame's size before any downscaling: track boxes are in these pixels.
    pub frame_width: u32,
    pub frame_height: u32,
    #[serde(with = "base64_bytes")]
    pub jpeg: Vec<u8>,
}

impl Message for Preview {
    const KIND: &'static str = "preview";
}
impl UavMessage for Preview {
    const TOPIC: Topic = Topic::Preview;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}

/// Where a simulated UAV really was at a frame: published only by edges on
/// the simulator, so the ground station can draw the true track beside the estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthPose {
    pub uav: NodeId,
    pub time_s: f64,
    pub seq: u64,
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

impl Message for TruthPose {
    const KIND: &'static str = "truth";
}
impl UavMessage for TruthPose {
    const TOPIC: Topic = Topic::Truth;
    fn uav(&self) -> &NodeId {
        &self.uav
    }
}

/// Everything the pipeline reads of one camera frame: the detector's boxes and the IMU attitude
/// at capture time. A wire type so flights can be recorded and replayed without sockets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionFrame {
    pub seq: u64,
    pub time_s: f64,
    pub imu_attitude: towernav_geometry::Attitude,
    pub detections: Vec<Detection>,
}

impl Message for DetectionFrame {
    const KIND: &'static str = "detection_frame";
}

/// Asked of the ground station's landmark queryable (as the query payload).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkSyncRequest {
    /// The replica's revision; `None` asks for the full set.
    pub since: Option<u64>,
}

/// The ground station's answer: the full set, or the changes after `since`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkSyncReply {
    /// The ground station's revision when it answered.
    pub revision: u64,
    /// `Some` for a full set (asked for, or the replica was ahead of the ground station).
    pub full: Option<Vec<LandmarkRecord>>,
    /// Changes after the request's `since`, in revision order (empty with `full`).
    pub changes: Vec<LandmarkChange>,
}

impl Message for LandmarkSyncRequest {
    const KIND: &'static str = "landmark_sync_request";
}
impl Message for LandmarkSyncReply {
    const KIND: &'static str = "landmark_sync_reply";
}

/// Binary payloads inside the JSON envelope as base64 text, a third over raw
/// rather than the four times of a number array.
mod base64_bytes {
    use base64::Engine;
    use base64::engine::general_purpose::STANDARD;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(bytes: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&STANDARD.encode(bytes))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        let text = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        STANDARD
            .decode(text.as_bytes())
            .map_err(|e| serde::de::Error::custom(format!("jpeg is not base64: {e}")))
    }
}

#[cfg(test)]
mod topic_tests {
    use super::*;

    /// Each per-UAV topic carries exactly one payload type, and each such
    /// payload one topic: the pairing is total and one-to-one.
    #[test]
    fn every_topic_has_one_payload() {
        let pairs = [
            (PoseEstimate::TOPIC, PoseEstimate::KIND),
            (TrackReport::TOPIC, TrackReport::KIND),
            (StatusHeartbeat::TOPIC, StatusHeartbeat::KIND),
            (IdCorrection::TOPIC, IdCorrection::KIND),
            (CorrectionAck::TOPIC, CorrectionAck::KIND),
            (DetectionReport::TOPIC, DetectionReport::KIND),
            (Preview::TOPIC, Preview::KIND),
            (TruthPose::TOPIC, TruthPose::KIND),
        ];
        for topic in Topic::ALL {
            let carried: Vec<_> = pairs.iter().filter(|(t, _)| *t == topic).collect();
            assert_eq!(carried.len(), 1, "{topic:?} carries {carried:?}");
        }
        let kinds: std::collections::HashSet<_> = pairs.iter().map(|(_, k)| k).collect();
        assert_eq!(kinds.len(), pairs.len());
    }
}
