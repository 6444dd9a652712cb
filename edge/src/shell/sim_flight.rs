//! Flies a simulated scenario through the pipeline and out over Zenoh.

use std::time::{Duration, Instant};

use nalgebra::Vector3;
use towernav_protocol::{CorrectionAck, EdgeState, StatusHeartbeat};
use towernav_sim::Scenario;

use super::ShellError;
use super::landmark_sync::LandmarkSync;
use super::node::EdgeNode;
use super::rendered_detector::RenderedDetector;
use crate::landmarks::LandmarkMap;
use crate::localizer::Method;
use crate::mot_metrics::MotAccumulator;
use crate::pipeline::{Pipeline, PipelineConfig};
use crate::tracking_eval::{add_frame, pipeline_hypotheses};
use crate::wire::{pose_estimate, pose_method, track_report};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimFlightOptions {
    /// Playback speed relative to real time; `None` runs as fast as it can.
    pub speed: Option<f64>,
    /// How far the assumed take-off position is from the true one, metres (east, north).
    pub takeoff_error_m: (f64, f64),
    /// Stop after this many frames (the whole flight if `None`).
    pub max_frames: Option<u64>,
    pub method: Method,
    /// Fuse fixes with the EKF (else publish raw fixes).
    pub filter: bool,
}

impl Default for SimFlightOptions {
    fn default() -> Self {
        Self {
            speed: None,
            takeoff_error_m: (3.0, -4.0),
            max_frames: None,
            method: Method::default(),
            filter: true,
        }
    }
}

/// What happened, frame by frame, for the report.
#[derive(Debug, Clone, Default)]
pub struct FlightRecord {
    pub frames: u64,
    pub poses_published: u64,
    /// Seconds spent in the pure pipeline, summed.
    pub core_seconds: f64,
    pub wall_seconds: f64,
    /// Tower identities scored against truth (binding accuracy, bound share).
    pub identity: MotAccumulator,
    /// True horizontal position per frame, for scoring received poses by `seq`.
    pub truth_en: Vec<(f64, f64)>,
    /// With the real detector: seconds rendering and detecting, and frames
    /// whose detection failed (flown on with no boxes).
    pub render_seconds: f64,
    pub detect_seconds: f64,
    pub detector_errors: u64,
}

pub async fn fly(
    node: &EdgeNode,
    scenario: &Scenario,
    map: LandmarkMap,
    options: SimFlightOptions,
    mut sync: Option<&mut LandmarkSync>,
    mut detector: Option<&mut RenderedDetector>,
    mut on_frame: impl FnMut(u64),
) -> Result<FlightRecord, ShellError> {
    let start = scenario.start_in_world();
    let takeoff = start + Vector3::new(options.takeoff_error_m.0, options.takeoff_error_m.1, 0.0);
    let mut config = PipelineConfig::new(scenario.camera, takeoff);
    config.method = options.method;
    if !options.filter {
        config.filter = None;
    }
    let method = pose_method(options.method, options.filter);
    let mut pipeline = Pipeline::new(config, map);
    let datum = scenario.world.datum;
    let mut record = FlightRecord::default();
    let wall = Instant::now();
    let mut last_status = Instant::now() - Duration::from_secs(10);
    let mut frames_since_status = 0u64;

    for (truth, mut frame) in scenario
        .frames()
        .take(options.max_frames.unwrap_or(u64::MAX) as usize)
    {
        if let Some(speed) = options.speed.filter(|s| *s > 0.0) {
            let due = Duration::from_secs_f64(frame.time_s / speed);
            if let Some(wait) = due.checked_sub(wall.elapsed()) {
                tokio::time::sleep(wait).await;
            }
        }
        if let Some(sync) = sync.as_deref_mut()
            && sync.poll().await?
        {
            let replica = sync.replica();
            tracing::info!(
                revision = replica.revision,
                towers = replica.len(),
                "landmarks updated from the ground station"
            );
            pipeline.replace_map(LandmarkMap::from_records(&replica.records(), &datum));
        }
        for correction in node.pending_corrections() {
            let result = pipeline.pin(correction.track_id, correction.tower_id.as_deref());
            tracing::info!(track = correction.track_id, tower = ?correction.tower_id, ok = result.is_ok(), "operator correction");
            node.acknowledge(&CorrectionAck {
                uav: node.uav().clone(),
                request_id: correction.request_id,
                accepted: result.is_ok(),
                reason: result.err(),
            })
            .await?;
        }

        if let Some(detector) = detector.as_deref_mut() {
            frame.detections = detector.detect(scenario, &truth).unwrap_or_else(|e| {
                tracing::warn!(seq = frame.seq, error = %e, "detector failed; frame flown without boxes");
                record.detector_errors += 1;
                Vec::new()
            });
        }
        let t0 = Instant::now();
        let out = pipeline.process(&frame);
        record.core_seconds += t0.elapsed().as_secs_f64();

        if let Some(estimate) = &out.estimate {
            node.publish_pose(&pose_estimate(node.uav(), &out, estimate, method, &datum))
                .await?;
            record.poses_published += 1;
        }
        node.publish_tracks(&track_report(node.uav(), &out, pipeline.map()))
            .await?;
        add_frame(
            &mut record.identity,
            scenario,
            &truth,
            &pipeline_hypotheses(&out, pipeline.map()),
        );
        let p = truth.pose.position_in_world;
        record.truth_en.push((p.x, p.y));
        record.frames += 1;
        frames_since_status += 1;

        if last_status.elapsed() >= Duration::from_secs(1) {
            let rate = frames_since_status as f64 / last_status.elapsed().as_secs_f64().min(10.0);
            node.publish_status(&StatusHeartbeat {
                uav: node.uav().clone(),
                time_s: frame.time_s,
                state: match (&out.estimate, record.poses_published) {
                    (Some(_), _) => EdgeState::Localized,
                    (None, 0) => EdgeState::Initializing,
                    (None, _) => EdgeState::NoFix,
                },
                frames_processed: record.frames,
                frame_rate_hz: rate,
                landmarks_loaded: pipeline.map().towers.len() as u32,
                datum_lat_deg: datum.origin.lat_deg,
                datum_lon_deg: datum.origin.lon_deg,
                datum_alt_m: datum.origin.height_m,
            })
            .await?;
            last_status = Instant::now();
            frames_since_status = 0;
        }
        on_frame(record.frames);
    }
    record.wall_seconds = wall.elapsed().as_secs_f64();
    if let Some(detector) = detector {
        record.render_seconds = detector.render_seconds;
        record.detect_seconds = detector.detect_seconds;
    }
    Ok(record)
}
