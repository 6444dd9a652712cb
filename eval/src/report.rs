//! The demo's closing report: what went in, what came out over Zenoh, and how right it was.

use std::fmt;

use towernav_protocol::PoseEstimate;

use crate::sim_eval::{ErrorStats, error_stats};
use crate::truth_scorer::TruthScorer;
use towernav_core::flight_record::FlightRecord;

#[derive(Debug, Clone, PartialEq)]
pub struct FlightReport {
    pub frames: u64,
    pub flight_seconds: f64,
    pub core_rate_hz: f64,
    pub wall_rate_hz: f64,
    pub poses_published: u64,
    pub poses_received: usize,
    /// Horizontal error of the poses that arrived, against truth at their frame.
    pub horizontal: ErrorStats,
    /// Of track-frames bound to a tower, the share bound to the right one.
    pub binding_accuracy: f64,
    /// Of track-frames on a tower the tracker must cover, the share bound.
    pub bound_share: f64,
    /// With a real detector: its name, mean milliseconds per frame
    /// (pre-processing, inference, post-processing), and frames that failed.
    pub detector: Option<(String, f64, u64)>,
}

impl FlightReport {
    pub fn new(
        record: &FlightRecord,
        scorer: &TruthScorer,
        received: &[PoseEstimate],
        fps: f64,
    ) -> Self {
        let errors: Vec<f64> = received
            .iter()
            .filter_map(|p| {
                let (e, n) = *scorer.truth_en.get(&p.seq)?;
                Some(((p.east_m - e).powi(2) + (p.north_m - n).powi(2)).sqrt())
            })
            .collect();
        let identity = scorer.identity.finish();
        let rate = |secs: f64| {
            if secs > 0.0 {
                record.frames as f64 / secs
            } else {
                0.0
            }
        };
        Self {
            frames: record.frames,
            flight_seconds: record.frames as f64 / fps,
            core_rate_hz: rate(record.core_seconds),
            wall_rate_hz: rate(record.wall_seconds),
            poses_published: record.poses_published,
            poses_received: received.len(),
            horizontal: error_stats(&errors),
            binding_accuracy: identity.binding_accuracy,
            bound_share: identity.binding_coverage,
            detector: record.detector.clone().map(|name| {
                (
                    name,
                    1e3 * record.detect_seconds / record.frames.max(1) as f64,
                    record.detector_errors,
                )
            }),
        }
    }
}

impl fmt::Display for FlightReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let h = &self.horizontal;
        writeln!(
            f,
            "frames             {} ({:.1} s of flight)",
            self.frames, self.flight_seconds
        )?;
        writeln!(
            f,
            "processing rate    {:.0} frames/s in the pipeline core (one thread), {:.0} frames/s end to end",
            self.core_rate_hz, self.wall_rate_hz
        )?;
        if let Some((name, detect, errors)) = &self.detector {
            writeln!(
                f,
                "detector           {name} on rendered frames: {detect:.1} ms per frame (pre + inference + post); \
                 {errors} frames failed"
            )?;
        } else {
            writeln!(
                f,
                "detector           the simulator's oracle (truth boxes with noise)"
            )?;
        }
        writeln!(
            f,
            "poses              {} published, {} received over Zenoh",
            self.poses_published, self.poses_received
        )?;
        writeln!(
            f,
            "horizontal error   RMS {:.2} m, p95 {:.2} m, max {:.2} m (over {} received poses)",
            h.rms, h.p95, h.max, h.count
        )?;
        write!(
            f,
            "tower identity     {:.2} % of bound track-frames on their true tower; {:.1} % of track-frames bound",
            100.0 * self.binding_accuracy,
            100.0 * self.bound_share
        )
    }
}
