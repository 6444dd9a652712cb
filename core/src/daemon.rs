//! The daemon's logic between frames, as a state machine without I/O in the
//! manner of quinn-proto: the shell feeds it frames (`handle_frame`), the
//! operator's commands (`handle_command`) and its timer (`handle_timeout` at
//! `poll_timeout`), and sends whatever `poll_output` hands back.
//!
//! Corrections, landmark swaps and the status heartbeat do not wait for a
//! frame, so a stalled camera still reports itself, acknowledges every
//! correction and takes new landmarks.

use hdrhistogram::Histogram;
use mavlink::dialects::common::MavMessage;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

use towernav_geometry::{Attitude, Datum, Geodetic};
use towernav_protocol::{
    CorrectionAck, Detection, DetectionFrame, DetectionReport, EdgeState, Health, IdCorrection,
    NodeId, PoseEstimate, PoseMethod, StatusHeartbeat, TrackReport,
};

use crate::autopilot::velocity_from_odometry;
use crate::autopilot_link::{AutopilotLink, LinkEstimate};
use crate::landmarks::LandmarkMap;
use crate::optical_flow::velocity_from_optical_flow;
use crate::pipeline::{FrameOutput, Pipeline};
use crate::ros_link::{RosLink, RosOutput};
use crate::wire::{pose_estimate, track_report};

/// How often the status heartbeat goes out.
pub const STATUS_EVERY: Duration = Duration::from_secs(1);
/// How many corrections' answers are kept to recognise a repeat.
pub const ANSWERED_KEPT: usize = 256;
/// A source silent this long is reported as failed, not merely degraded.
pub const STALL_FAILED_AFTER: Duration = Duration::from_secs(3);

/// What the daemon core is told once, at start.
#[derive(Debug, Clone)]
pub struct DaemonConfig {
    pub uav: NodeId,
    pub datum: Datum,
    pub method: PoseMethod,
    /// For the status: "oracle" or the model's file name.
    pub detector: String,
    /// Preview pictures at most this often; `None`: none.
    pub preview_every: Option<Duration>,
    /// This run of the edge (the shell draws it at start): its track
    /// numbers and the corrections meant for them belong to it.
    pub session: u64,
}

/// One frame after the detector: its boxes, and what the source knew of it.
#[derive(Debug, Clone)]
pub struct DetectedFrame {
    pub seq: u64,
    pub time_s: f64,
    /// When the frame entered the daemon, for frame-to-publish latency.
    pub captured: Instant,
    pub attitude: Attitude,
    pub detections: Vec<Detection>,
    /// Whether the shell holds pixels of it (a preview can be made).
    pub has_image: bool,
    /// The barometer's height above take-off at the frame, metres, when
    /// the source knows it (the simulator, a flight log).
    pub barometric_height_m: Option<f64>,
}

/// What the operator asks of the daemon.
#[derive(Debug, Clone)]
pub enum Command {
    Correct(IdCorrection),
    ReplaceMap(LandmarkMap),
    /// A message from the autopilot, for the MAVLink link, with its sender's
    /// system and component id.
    FromAutopilot {
        from: (u8, u8),
        message: MavMessage,
    },
    /// PX4's time since boot, microseconds, from a message stamped with it
    /// (its `vehicle_attitude` over Zenoh).
    Px4Time(u64),
}

/// What the shell is to send or do.
#[derive(Debug, Clone)]
pub enum Output {
    /// A fix: to Zenoh, the autopilot and the pose log.
    Pose {
        pose: PoseEstimate,
        state: EdgeState,
        attitude: Attitude,
    },
    Tracks(TrackReport),
    Detections(DetectionReport),
    /// Make and publish a preview picture of this frame.
    Preview {
        seq: u64,
        time_s: f64,
    },
    Ack(CorrectionAck),
    Status(StatusHeartbeat),
    /// To the autopilot.
    Mavlink(MavMessage),
    /// To ROS 2 and PX4 over Zenoh.
    Ros(RosOutput),
    /// The autopilot's own GNSS position, for a survey flight's record.
    AutopilotPosition(SurveyPosition),
}

/// The autopilot's GNSS position as it arrived, with the frame seen last.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SurveyPosition {
    /// UTC when it arrived, microseconds (the link's clock).
    pub unix_us: u64,
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_msl_m: f64,
    /// Above the WGS84 ellipsoid (through the geoid).
    pub height_m: f64,
    pub heading_deg: Option<f64>,
    /// The last processed frame: its seq and source time.
    pub frame_seq: Option<u64>,
    pub frame_time_s: f64,
}

/// Frames the source dropped or failed, as totals since start.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SourceCounters {
    pub dropped: u64,
    pub failed: u64,
}

/// Watches the pipeline's output frame by frame from outside the core (the
/// demo's scoring against truth); the core itself never sees truth.
pub trait FrameObserver: Send {
    fn observe(&mut self, seq: u64, output: &FrameOutput, map: &LandmarkMap);
}

/// The daemon between frames.
pub struct DaemonCore {
    config: DaemonConfig,
    pipeline: Pipeline,
    outputs: VecDeque<Output>,
    last: Option<FrameOutput>,
    state: EdgeState,
    last_time_s: f64,
    /// The last frame's IMU attitude: what turns a flow sensor's body-frame
    /// velocity into the world.
    last_attitude: Option<Attitude>,
    fixes: u64,
    frames: u64,
    poses: u64,
    next_status: Instant,
    last_status: Instant,
    last_frame_at: Option<Instant>,
    started: Instant,
    frames_at_status: u64,
    troubles_at_status: u64,
    window_ms: Vec<f64>,
    /// Every processed frame's latency, microseconds, in fixed memory.
    latency_us: Histogram<u64>,
    last_preview: Option<Instant>,
    autopilot: Option<AutopilotLink>,
    ros: Option<RosLink>,
    /// The last corrections' answers, by request id: a repeat gets its answer again.
    answered: VecDeque<CorrectionAck>,
    /// The autopilot sends ALTITUDE: its relative altitude is preferred to
    /// GLOBAL_POSITION_INT's.
    altitude_source_seen: bool,
}

impl DaemonCore {
    pub fn new(config: DaemonConfig, pipeline: Pipeline, now: Instant) -> Self {
        Self {
            config,
            pipeline,
            outputs: VecDeque::new(),
            last: None,
            state: EdgeState::Initializing,
            last_time_s: 0.0,
            last_attitude: None,
            fixes: 0,
            frames: 0,
            poses: 0,
            next_status: now + STATUS_EVERY,
            last_status: now,
            last_frame_at: None,
            started: now,
            frames_at_status: 0,
            troubles_at_status: 0,
            window_ms: Vec::new(),
            latency_us: latency_histogram(),
            last_preview: None,
            autopilot: None,
            ros: None,
            answered: VecDeque::new(),
            altitude_source_seen: false,
        }
    }

    /// With a MAVLink link to the autopilot: its messages come out as `Output::Mavlink`.
    pub fn with_autopilot(mut self, link: AutopilotLink) -> Self {
        self.autopilot = Some(link);
        self
    }

    /// With ROS 2 topics or PX4's auxiliary global position over Zenoh:
    /// they come out as `Output::Ros`.
    pub fn with_ros(mut self, link: RosLink) -> Self {
        self.ros = Some(link);
        self
    }

    pub fn autopilot(&self) -> Option<&AutopilotLink> {
        self.autopilot.as_ref()
    }

    /// Runs the pipeline on one detected frame and queues its messages.
    pub fn handle_frame(&mut self, now: Instant, frame: DetectedFrame) {
        if let Some(h) = frame.barometric_height_m {
            self.pipeline.barometric_height(frame.time_s, h);
        }
        let input = DetectionFrame {
            seq: frame.seq,
            time_s: frame.time_s,
            imu_attitude: frame.attitude,
            detections: frame.detections,
        };
        let output = self.pipeline.process(&input);
        let map = self.pipeline.map();
        self.fixes += u64::from(output.estimate.is_some());
        self.state = match (&output.estimate, self.fixes) {
            (Some(e), _) if e.updated => EdgeState::Localized,
            (Some(_), _) => EdgeState::Coasting,
            (None, 0) => EdgeState::Initializing,
            (None, _) => EdgeState::NoFix,
        };
        let mut for_autopilot = None;
        if let Some(estimate) = &output.estimate {
            let pose = pose_estimate(
                &self.config.uav,
                &output,
                estimate,
                self.config.method,
                &self.config.datum,
            );
            self.poses += 1;
            for_autopilot = Some(LinkEstimate {
                pose: pose.clone(),
                attitude: frame.attitude,
                velocity_in_world: estimate.velocity_in_world,
                velocity_covariance: estimate.velocity_covariance,
            });
            self.outputs.push_back(Output::Pose {
                pose,
                state: self.state,
                attitude: frame.attitude,
            });
        }
        if let Some(link) = self.ros.as_mut() {
            link.handle_estimate(now, for_autopilot.clone(), self.state);
        }
        if let Some(link) = self.autopilot.as_mut() {
            link.handle_estimate(now, for_autopilot, self.state);
        }
        self.outputs.push_back(Output::Tracks(track_report(
            &self.config.uav,
            self.config.session,
            &output,
            map,
        )));
        self.outputs.push_back(Output::Detections(DetectionReport {
            uav: self.config.uav.clone(),
            time_s: frame.time_s,
            seq: frame.seq,
            detections: input.detections,
        }));
        let preview_due = self.config.preview_every.is_some_and(|every| {
            self.last_preview
                .is_none_or(|at| now.saturating_duration_since(at) >= every)
        });
        if frame.has_image && preview_due {
            self.last_preview = Some(now);
            self.outputs.push_back(Output::Preview {
                seq: frame.seq,
                time_s: frame.time_s,
            });
        }
        let latency = now.saturating_duration_since(frame.captured).as_secs_f64() * 1e3;
        self.window_ms.push(latency);
        // Past the histogram's hour the value is clamped, not lost.
        self.latency_us.saturating_record((latency * 1e3) as u64);
        self.frames += 1;
        self.last_time_s = frame.time_s;
        self.last_attitude = Some(frame.attitude);
        self.last_frame_at = Some(now);
        self.last = Some(output);
    }

    /// Applies a correction (and queues its acknowledgement) or a new landmark set at once.
    pub fn handle_command(&mut self, now: Instant, command: Command) {
        match command {
            Command::Correct(c) => {
                // The same request again (resent by a restarted ground
                // station, or delivered twice): answered as before, never
                // applied twice, since a later correction may have undone it.
                if let Some(ack) = self.answered.iter().find(|a| a.request_id == c.request_id) {
                    tracing::info!(
                        request = c.request_id,
                        "a correction already answered: not applied again"
                    );
                    self.outputs.push_back(Output::Ack(ack.clone()));
                    return;
                }
                let result = if c.session.is_some_and(|s| s != self.config.session) {
                    Err(format!(
                        "track {} was picked in an earlier run of this edge; track numbers \
                         start again with each run: pick the track again",
                        c.track_id
                    ))
                } else if c.release {
                    self.pipeline.release(c.track_id)
                } else {
                    self.pipeline.pin(c.track_id, c.tower_id.as_deref())
                };
                tracing::info!(track = c.track_id, tower = ?c.tower_id, ok = result.is_ok(), "operator correction");
                let ack = CorrectionAck {
                    uav: self.config.uav.clone(),
                    request_id: c.request_id,
                    accepted: result.is_ok(),
                    reason: result.err(),
                };
                if self.answered.len() == ANSWERED_KEPT {
                    self.answered.pop_front();
                }
                self.answered.push_back(ack.clone());
                self.outputs.push_back(Output::Ack(ack));
            }
            Command::ReplaceMap(map) => {
                tracing::info!(towers = map.towers.len(), "landmarks replaced");
                self.pipeline.replace_map(map);
            }
            Command::Px4Time(px4_us) => {
                if let Some(link) = self.ros.as_mut() {
                    link.handle_px4_time(now, px4_us);
                }
            }
            Command::FromAutopilot { from, message } => {
                if self.autopilot.is_none() {
                    return;
                }
                self.take_other_sensors(from, &message);
                let Some(link) = self.autopilot.as_mut() else {
                    return;
                };
                link.handle_message(now, from, &message);
                let (MavMessage::GLOBAL_POSITION_INT(_), Some(p)) =
                    (&message, link.autopilot_position())
                else {
                    return;
                };
                self.outputs
                    .push_back(Output::AutopilotPosition(SurveyPosition {
                        unix_us: link.unix_us(p.received),
                        lat_deg: p.lat_deg,
                        lon_deg: p.lon_deg,
                        alt_msl_m: p.alt_msl_m,
                        height_m: p.height_m,
                        heading_deg: p.heading_rad.map(f64::to_degrees),
                        frame_seq: self.last.as_ref().map(|o| o.seq),
                        frame_time_s: self.last_time_s,
                    }));
                // The autopilot's GNSS says where to start, before the first
                // fix only: later its position may be our own estimate fed
                // back, or its dead reckoning once GNSS is gone.
                if self.fixes == 0
                    && let Ok(place) = Geodetic::new(p.lat_deg, p.lon_deg, p.height_m)
                {
                    let point = self.config.datum.to_enu(&place);
                    self.pipeline.hint_position(self.last_time_s, point);
                }
            }
        }
    }

    /// What the filter can use from the autopilot's messages: another
    /// component's velocity (ODOMETRY from a VIO or optical-flow estimator;
    /// the edge's own carries none) and the barometric height above home
    /// (ALTITUDE, else GLOBAL_POSITION_INT's relative altitude).
    fn take_other_sensors(&mut self, from: (u8, u8), message: &MavMessage) {
        let time_s = self.last_time_s;
        match message {
            MavMessage::ODOMETRY(o) => match velocity_from_odometry(o) {
                Ok((v, c)) => {
                    let fused = self.pipeline.fuse_velocity(time_s, &v, &c);
                    tracing::trace!(?from, fused, "outside velocity");
                }
                Err(reason) => {
                    tracing::debug!(?from, %reason, "an ODOMETRY's velocity is not used");
                }
            },
            MavMessage::OPTICAL_FLOW_RAD(o) => {
                let Some(attitude) = self.last_attitude else {
                    tracing::debug!(
                        ?from,
                        "an OPTICAL_FLOW_RAD before any frame's attitude is not used"
                    );
                    return;
                };
                match velocity_from_optical_flow(o, &attitude) {
                    Ok((v, c)) => {
                        let fused = self.pipeline.fuse_velocity(time_s, &v, &c);
                        tracing::trace!(?from, fused, "optical-flow velocity");
                    }
                    Err(reason) => {
                        tracing::debug!(?from, %reason, "an OPTICAL_FLOW_RAD's velocity is not used");
                    }
                }
            }
            MavMessage::ALTITUDE(a) if a.altitude_relative.is_finite() => {
                self.altitude_source_seen = true;
                self.pipeline
                    .barometric_height(time_s, f64::from(a.altitude_relative));
            }
            MavMessage::GLOBAL_POSITION_INT(p) if !self.altitude_source_seen => {
                self.pipeline
                    .barometric_height(time_s, f64::from(p.relative_alt) / 1000.0);
            }
            _ => {}
        }
    }

    /// When `handle_timeout` is next due.
    pub fn poll_timeout(&self) -> Instant {
        let mut due = self.next_status;
        if let Some(link) = &self.autopilot {
            due = due.min(link.poll_timeout());
        }
        if let Some(link) = &self.ros {
            due = due.min(link.poll_timeout());
        }
        due
    }

    /// Sends the status heartbeat and the autopilot's messages when due;
    /// `counters` are the source's totals.
    pub fn handle_timeout(&mut self, now: Instant, counters: SourceCounters) {
        self.status_timeout(now, counters);
        if let Some(link) = self.autopilot.as_mut() {
            link.handle_timeout(now);
        }
        if let Some(link) = self.ros.as_mut() {
            link.handle_timeout(now);
        }
    }

    fn status_timeout(&mut self, now: Instant, counters: SourceCounters) {
        if now < self.next_status {
            return;
        }
        let period = now
            .saturating_duration_since(self.last_status)
            .as_secs_f64();
        let frames = self.frames - self.frames_at_status;
        let troubles = counters.dropped + counters.failed;
        let silent_for = now.saturating_duration_since(self.last_frame_at.unwrap_or(self.started));
        let health = if silent_for >= STALL_FAILED_AFTER {
            Health::Failed
        } else if troubles > self.troubles_at_status || frames == 0 {
            Health::Degraded
        } else {
            Health::Ok
        };
        let (p50, p99) = percentiles(&mut self.window_ms);
        let origin = self.config.datum.origin;
        self.outputs.push_back(Output::Status(StatusHeartbeat {
            uav: self.config.uav.clone(),
            time_s: self.last_time_s,
            state: self.state,
            frames_processed: self.frames,
            frame_rate_hz: frames as f64 / period.max(1e-9),
            landmarks_loaded: self.pipeline.map().towers.len() as u32,
            datum_lat_deg: origin.lat_deg,
            datum_lon_deg: origin.lon_deg,
            datum_alt_m: origin.height_m,
            health,
            frames_dropped: counters.dropped,
            frames_failed: counters.failed,
            latency_p50_ms: p50,
            latency_p99_ms: p99,
            detector: self.config.detector.clone(),
        }));
        if let Some(link) = self.autopilot.as_mut() {
            link.handle_health(health);
        }
        self.window_ms.clear();
        self.frames_at_status = self.frames;
        self.troubles_at_status = troubles;
        self.last_status = now;
        // A late timer does not fire a burst: the next beat is a period from now.
        self.next_status = (self.next_status + STATUS_EVERY).max(now + STATUS_EVERY / 2);
    }

    /// The next message to send, oldest first.
    pub fn poll_output(&mut self) -> Option<Output> {
        self.outputs
            .pop_front()
            .or_else(|| {
                self.autopilot
                    .as_mut()
                    .and_then(AutopilotLink::poll_transmit)
                    .map(Output::Mavlink)
            })
            .or_else(|| {
                self.ros
                    .as_mut()
                    .and_then(RosLink::poll_transmit)
                    .map(Output::Ros)
            })
    }

    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }

    /// The pipeline's output for the last frame, for observers outside the core.
    pub fn last_output(&self) -> Option<&FrameOutput> {
        self.last.as_ref()
    }

    pub fn frames(&self) -> u64 {
        self.frames
    }

    pub fn poses(&self) -> u64 {
        self.poses
    }

    /// Frame-to-publish latency over every processed frame: p50 and p99 in
    /// milliseconds (to 1 %), zeros before the first frame.
    pub fn latency_percentiles(&self) -> (f64, f64) {
        if self.latency_us.is_empty() {
            return (0.0, 0.0);
        }
        let at = |q: f64| self.latency_us.value_at_quantile(q) as f64 / 1e3;
        (at(0.5), at(0.99))
    }

    /// Frames whose latency was recorded.
    pub fn latency_count(&self) -> u64 {
        self.latency_us.len()
    }
}

/// 1 us to an hour at two significant digits: about 30 KB, whatever the run's length.
fn latency_histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 3_600_000_000, 2)
        .unwrap_or_else(|_| Histogram::new(2).expect("two significant digits are valid"))
}

/// p50 and p99 of `values` (sorted in place); zeros when empty.
pub fn percentiles(values: &mut [f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    values.sort_by(f64::total_cmp);
    let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.99))
}

#[cfg(test)]
#[path = "daemon_tests.rs"]
mod tests;
