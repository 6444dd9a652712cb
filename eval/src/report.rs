//! The demo's closing report: what went in, what came out over Zenoh, and how right it was.

use std::fmt;

use nalgebra::{Matrix2, Vector2};

use towernav_protocol::PoseEstimate;

use crate::gnss_score::TWO_SIGMA_CHI2;
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
    /// Share of the scored poses whose error lies inside their own reported
    /// 2-sigma ellipse (95 % if the covariance is honest).
    pub two_sigma_coverage: f64,
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
        let scored: Vec<(f64, bool)> = received
            .iter()
            .filter_map(|p| {
                let (e, n) = *scorer.truth_en.get(&p.seq)?;
                let d = Vector2::new(p.east_m - e, p.north_m - n);
                let c = &p.covariance;
                let inside = Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1])
                    .try_inverse()
                    .is_some_and(|inv| (d.transpose() * inv * d)[(0, 0)] <= TWO_SIGMA_CHI2);
                Some((d.norm(), inside))
            })
            .collect();
        let errors: Vec<f64> = scored.iter().map(|(e, _)| *e).collect();
        let inside = scored.iter().filter(|(_, inside)| *inside).count();
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
            two_sigma_coverage: if scored.is_empty() {
                0.0
            } else {
                inside as f64 / scored.len() as f64
            },
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
            "horizontal error   RMS {:.2} m, median {:.2} m, p95 {:.2} m, max {:.2} m, within 5 m {:.1} % (over {} received poses)",
            h.rms,
            h.median,
            h.p95,
            h.max,
            100.0 * h.within_5m,
            h.count
        )?;
        writeln!(
            f,
            "estimates          {:.1} % of frames; {:.1} % of errors inside the reported 2-sigma ellipse (honest: 95 %)",
            100.0 * self.poses_received as f64 / self.frames.max(1) as f64,
            100.0 * self.two_sigma_coverage
        )?;
        write!(
            f,
            "tower identity     {:.2} % of bound track-frames on their true tower; {:.1} % of track-frames bound",
            100.0 * self.binding_accuracy,
            100.0 * self.bound_share
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use towernav_protocol::{NodeId, PoseMethod};
    use towernav_sim::{Scenario, World};

    fn pose(seq: u64, east_m: f64, variance: f64) -> PoseEstimate {
        PoseEstimate {
            uav: NodeId::new("uav1").expect("id"),
            time_s: seq as f64,
            seq,
            east_m,
            north_m: 0.0,
            up_m: 30.0,
            lat_deg: 0.0,
            lon_deg: 0.0,
            alt_m: 0.0,
            yaw_rad: 0.0,
            covariance: [
                [variance, 0.0, 0.0, 0.0],
                [0.0, variance, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 0.01],
            ],
            method: PoseMethod::PaperLbl,
            towers_used: vec![],
            coast_s: 0.0,
        }
    }

    #[test]
    fn coverage_counts_errors_inside_their_own_two_sigma_ellipse() {
        let scenario = Scenario::preset(World::paper_field(), "paper-path-1", 1).expect("preset");
        let mut scorer = TruthScorer::new(Arc::new(scenario));
        for seq in 0..4 {
            scorer.truth_en.insert(seq, (0.0, 0.0));
        }
        let record = FlightRecord {
            frames: 8,
            ..FlightRecord::default()
        };
        // 1 m off with 1 m^2 (inside), 2 m off with 1 m^2 (chi2 4: inside),
        // 3 m off with 1 m^2 (chi2 9: outside), 3 m off with 4 m^2 (inside).
        let received = [
            pose(0, 1.0, 1.0),
            pose(1, 2.0, 1.0),
            pose(2, 3.0, 1.0),
            pose(3, 3.0, 4.0),
        ];
        let report = FlightReport::new(&record, &scorer, &received, 30.0);
        assert!((report.two_sigma_coverage - 0.75).abs() < 1e-12);
        assert!((report.horizontal.within_5m - 1.0).abs() < 1e-12);
        let text = report.to_string();
        assert!(text.contains("50.0 % of frames"), "{text}");
        assert!(text.contains("75.0 % of errors inside"), "{text}");
    }
}
