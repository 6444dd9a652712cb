//! The blocking worker: takes the newest frames from the queue, runs the
//! detector (or takes the oracle's boxes) and the pure pipeline, applies the
//! operator's corrections and landmark changes between frames, and hands
//! ready-to-send messages to the publisher.

use std::sync::Arc;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use image::RgbImage;
use image::codecs::jpeg::JpegEncoder;
use towernav_geometry::Datum;
use towernav_protocol::{
    CorrectionAck, Detection, DetectionFrame, DetectionReport, EdgeState, IdCorrection, NodeId,
    PoseEstimate, PoseMethod, Preview, TrackReport,
};
use towernav_sim::Scenario;

use super::attitude::AttitudeSource;
use super::queue::DropOldest;
use super::source::CapturedFrame;
use crate::landmarks::LandmarkMap;
use crate::mot_metrics::MotAccumulator;
use crate::pipeline::Pipeline;
use crate::shell::annotate::annotate;
use crate::shell::yolo::YoloDetector;
use crate::tracking_eval::{add_frame, pipeline_hypotheses};
use crate::wire::{pose_estimate, track_report};

/// What the shell asks of the worker between frames.
pub enum WorkerCommand {
    Correct(IdCorrection),
    ReplaceMap(LandmarkMap),
}

/// One processed frame, as messages ready to publish.
pub struct Processed {
    pub seq: u64,
    pub time_s: f64,
    pub captured: Instant,
    pub state: EdgeState,
    pub pose: Option<PoseEstimate>,
    pub attitude: towernav_geometry::Attitude,
    pub tracks: TrackReport,
    pub detections: DetectionReport,
    pub preview: Option<Preview>,
    pub acks: Vec<CorrectionAck>,
    /// Towers in the map the frame was localized against.
    pub landmarks: u32,
    /// True position in the mission's ENU frame (simulator only), for scoring and the true track.
    pub truth_in_world: Option<nalgebra::Point3<f64>>,
}

/// What the worker measured over the whole run.
#[derive(Debug, Default)]
pub struct WorkerTotals {
    pub frames: u64,
    pub failed: u64,
    pub core_seconds: f64,
    pub detect_seconds: f64,
    pub identity: MotAccumulator,
}

pub struct Worker {
    pub uav: NodeId,
    pub datum: Datum,
    pub method: PoseMethod,
    pub pipeline: Pipeline,
    pub detector: Option<YoloDetector>,
    pub attitude: AttitudeSource,
    pub preview_every: Option<Duration>,
    pub annotate_dir: Option<std::path::PathBuf>,
    /// The simulated scenario, for scoring identity against truth.
    pub scenario: Option<Arc<Scenario>>,
}

impl Worker {
    /// Run until the queue closes or the publisher goes away.
    pub fn run(
        mut self,
        queue: Arc<DropOldest<CapturedFrame>>,
        commands: Receiver<WorkerCommand>,
        out: tokio::sync::mpsc::Sender<Processed>,
    ) -> WorkerTotals {
        let mut totals = WorkerTotals::default();
        let mut last_preview: Option<Instant> = None;
        let mut fixes = 0u64;
        while let Some(frame) = queue.pop() {
            let mut acks = Vec::new();
            while let Ok(command) = commands.try_recv() {
                match command {
                    WorkerCommand::Correct(c) => {
                        let result = self.pipeline.pin(c.track_id, c.tower_id.as_deref());
                        tracing::info!(track = c.track_id, tower = ?c.tower_id, ok = result.is_ok(), "operator correction");
                        acks.push(CorrectionAck {
                            uav: self.uav.clone(),
                            request_id: c.request_id,
                            accepted: result.is_ok(),
                            reason: result.err(),
                        });
                    }
                    WorkerCommand::ReplaceMap(map) => self.pipeline.replace_map(map),
                }
            }
            let Some(attitude) = self.attitude.attitude(frame.time_s, frame.attitude) else {
                tracing::warn!(seq = frame.seq, "no attitude for this frame; skipped");
                totals.failed += 1;
                continue;
            };
            let t0 = Instant::now();
            let detections: Vec<Detection> = match (
                &mut self.detector,
                &frame.image,
                frame.detections,
            ) {
                (_, _, Some(oracle)) => oracle,
                (Some(detector), Some(image), None) => match detector.detect(image, frame.seq) {
                    Ok(d) => d,
                    Err(e) => {
                        tracing::warn!(seq = frame.seq, error = %e, "detector failed; frame skipped");
                        totals.failed += 1;
                        continue;
                    }
                },
                _ => {
                    tracing::warn!(
                        seq = frame.seq,
                        "frame has neither pixels for the detector nor boxes; skipped"
                    );
                    totals.failed += 1;
                    continue;
                }
            };
            let t1 = Instant::now();
            let input = DetectionFrame {
                seq: frame.seq,
                time_s: frame.time_s,
                imu_attitude: attitude,
                detections,
            };
            let output = self.pipeline.process(&input);
            let t2 = Instant::now();
            totals.detect_seconds += (t1 - t0).as_secs_f64();
            totals.core_seconds += (t2 - t1).as_secs_f64();
            totals.frames += 1;

            let map = self.pipeline.map();
            if let (Some(scenario), Some(truth)) = (&self.scenario, &frame.truth) {
                add_frame(
                    &mut totals.identity,
                    scenario,
                    truth,
                    &pipeline_hypotheses(&output, map),
                );
            }
            let pose = output
                .estimate
                .as_ref()
                .map(|e| pose_estimate(&self.uav, &output, e, self.method, &self.datum));
            fixes += u64::from(output.estimate.is_some());
            let state = match (&output.estimate, fixes) {
                (Some(_), _) => EdgeState::Localized,
                (None, 0) => EdgeState::Initializing,
                (None, _) => EdgeState::NoFix,
            };
            let tracks = track_report(&self.uav, &output, map);
            if let (Some(dir), Some(image)) = (&self.annotate_dir, &frame.image) {
                let path = dir.join(format!("frame{:06}.jpg", frame.seq));
                let mut canvas = image.clone();
                annotate(&mut canvas, &tracks, pose.as_ref());
                if let Err(e) = canvas.save(&path) {
                    tracing::warn!(path = %path.display(), error = %e, "annotated frame not written");
                }
            }
            let preview_due = self
                .preview_every
                .is_some_and(|every| last_preview.is_none_or(|at: Instant| at.elapsed() >= every));
            let preview = match (&frame.image, preview_due) {
                (Some(image), true) => {
                    last_preview = Some(Instant::now());
                    preview_jpeg(image).map(|jpeg| Preview {
                        uav: self.uav.clone(),
                        time_s: frame.time_s,
                        seq: frame.seq,
                        frame_width: image.width(),
                        frame_height: image.height(),
                        jpeg,
                    })
                }
                _ => None,
            };
            let processed = Processed {
                seq: frame.seq,
                time_s: frame.time_s,
                captured: frame.captured,
                state,
                pose,
                attitude,
                tracks,
                detections: DetectionReport {
                    uav: self.uav.clone(),
                    time_s: frame.time_s,
                    seq: frame.seq,
                    detections: input.detections,
                },
                preview,
                acks,
                landmarks: self.pipeline.map().towers.len() as u32,
                truth_in_world: frame.truth.as_ref().map(|t| t.pose.position_in_world),
            };
            if out.blocking_send(processed).is_err() {
                break;
            }
        }
        totals
    }
}

/// A half-size JPEG of the frame for the operator's camera view.
fn preview_jpeg(image: &RgbImage) -> Option<Vec<u8>> {
    let small = image::imageops::thumbnail(image, image.width() / 2, image.height() / 2);
    let mut jpeg = Vec::new();
    JpegEncoder::new_with_quality(&mut jpeg, 70)
        .encode_image(&small)
        .map_err(|e| tracing::warn!(error = %e, "preview not encoded"))
        .ok()?;
    Some(jpeg)
}
