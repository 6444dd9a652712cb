//! The blocking worker: takes the newest frames from the queue, looks up
//! their attitude, runs the detector (or takes the oracle's boxes), and hands
//! each detected frame to the daemon loop. It knows nothing of tracks, poses
//! or truth: the loop's `DaemonCore` does the rest.

use std::sync::Arc;
use std::time::Instant;

use image::RgbImage;
use nalgebra::Point3;
use towernav_core::daemon::DetectedFrame;
use towernav_onnx::YoloDetector;
use towernav_protocol::Detection;

use super::attitude::AttitudeSource;
use super::queue::DropOldest;
use super::source::CapturedFrame;

/// A frame after the detector, with what the loop needs beside the core's input.
pub struct Detected {
    pub frame: DetectedFrame,
    /// The pixels, for the preview and annotated frames.
    pub image: Option<RgbImage>,
    /// The source's truth, passed through for the operator's map.
    pub truth_in_world: Option<Point3<f64>>,
}

/// What the worker measured over the whole run.
#[derive(Debug, Default, Clone, Copy)]
pub struct WorkerTotals {
    pub failed: u64,
    pub detect_seconds: f64,
}

pub struct Worker {
    pub detector: Option<YoloDetector>,
    pub attitude: AttitudeSource,
}

impl Worker {
    /// Run until the queue closes or the loop goes away.
    pub fn run(
        mut self,
        queue: Arc<DropOldest<CapturedFrame>>,
        out: tokio::sync::mpsc::Sender<Detected>,
    ) -> WorkerTotals {
        let mut totals = WorkerTotals::default();
        while let Some(mut frame) = queue.pop() {
            let Some(attitude) = self.attitude.attitude(frame.time_s, frame.attitude) else {
                tracing::warn!(seq = frame.seq, "no attitude for this frame; skipped");
                totals.failed += 1;
                continue;
            };
            let t0 = Instant::now();
            let Some(detections) = self.detect(&mut frame) else {
                totals.failed += 1;
                continue;
            };
            totals.detect_seconds += t0.elapsed().as_secs_f64();
            let detected = Detected {
                frame: DetectedFrame {
                    seq: frame.seq,
                    time_s: frame.time_s,
                    captured: frame.captured,
                    attitude,
                    detections,
                    has_image: frame.image.is_some(),
                    barometric_height_m: frame.barometric_height_m,
                },
                image: frame.image,
                truth_in_world: frame.truth_in_world,
            };
            if out.blocking_send(detected).is_err() {
                break;
            }
        }
        totals
    }

    /// The frame's boxes: the oracle's, or the detector's on its pixels; `None` (logged) when neither.
    fn detect(&mut self, frame: &mut CapturedFrame) -> Option<Vec<Detection>> {
        if let Some(oracle) = frame.detections.take() {
            return Some(oracle);
        }
        match (&mut self.detector, &frame.image) {
            (Some(detector), Some(image)) => match detector.detect(image, frame.seq) {
                Ok(d) => Some(d),
                Err(e) => {
                    tracing::warn!(seq = frame.seq, error = %e, "detector failed; frame skipped");
                    None
                }
            },
            _ => {
                tracing::warn!(
                    seq = frame.seq,
                    "frame has neither pixels for the detector nor boxes; skipped"
                );
                None
            }
        }
    }
}
