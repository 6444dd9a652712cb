//! A replayed real flight scored against its own log's GNSS, as the paper
//! scored its flight against RTK: each estimate against the fix interpolated
//! to the frame's time on the log's clock. The GNSS is a reference here
//! only; nothing of it reaches the estimator after the start.

use nalgebra::{Matrix2, Point2, Vector2};
use towernav_geometry::{Datum, Geodetic};

use crate::sim_eval::{ErrorStats, error_stats};

/// Chi-square with two degrees of freedom at 95.45 % (the 2-sigma ellipse).
pub const TWO_SIGMA_CHI2: f64 = 6.18;

/// The log's fixes may be at most this far apart around a frame to score it.
pub const MAX_FIX_GAP_S: f64 = 2.0;

/// One published estimate of a replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayEstimate {
    pub seq: u64,
    /// The frame's time on the log's clock (camera time plus the offset).
    pub log_time_s: f64,
    /// East and north of the replay's datum, metres.
    pub east_north: Point2<f64>,
    /// Its horizontal covariance (east, north), m^2.
    pub covariance: Matrix2<f64>,
}

/// One reference fix, on the log's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceFix {
    pub time_s: f64,
    pub position: Geodetic,
}

/// One scored estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoredEstimate {
    pub estimate: ReplayEstimate,
    pub reference: Point2<f64>,
    pub error_m: f64,
    /// Inside the reported 2-sigma ellipse.
    pub inside_two_sigma: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ReplayScore {
    pub frames: u64,
    /// Frames with a published estimate.
    pub estimates: usize,
    /// Of those, scored (the log had fixes around them).
    pub scored: Vec<ScoredEstimate>,
    pub stats: ErrorStats,
    /// Share of scored estimates inside their own 2-sigma ellipse (95 % if honest).
    pub two_sigma_coverage: f64,
    /// The reference track (east, north) over the replay's span.
    pub reference_track: Vec<(f64, f64)>,
}

impl ReplayScore {
    /// Share of frames with an estimate.
    pub fn estimate_share(&self) -> f64 {
        if self.frames == 0 {
            0.0
        } else {
            self.estimates as f64 / self.frames as f64
        }
    }
}

/// Scores `estimates` (of a replay of `frames` frames) against `fixes`,
/// both placed in `datum`'s east-north.
pub fn score(
    datum: &Datum,
    frames: u64,
    estimates: &[ReplayEstimate],
    fixes: &[ReferenceFix],
) -> ReplayScore {
    let track: Vec<(f64, Point2<f64>)> = fixes
        .iter()
        .map(|f| {
            let p = datum.to_enu(&f.position);
            (f.time_s, Point2::new(p.x, p.y))
        })
        .collect();
    let scored: Vec<ScoredEstimate> = estimates
        .iter()
        .filter_map(|e| {
            let reference = interpolate(&track, e.log_time_s)?;
            let d: Vector2<f64> = e.east_north - reference;
            let inside_two_sigma = e
                .covariance
                .try_inverse()
                .is_some_and(|inv| (d.transpose() * inv * d)[(0, 0)] <= TWO_SIGMA_CHI2);
            Some(ScoredEstimate {
                estimate: *e,
                reference,
                error_m: d.norm(),
                inside_two_sigma,
            })
        })
        .collect();
    let errors: Vec<f64> = scored.iter().map(|s| s.error_m).collect();
    let inside = scored.iter().filter(|s| s.inside_two_sigma).count();
    let span = estimates
        .first()
        .zip(estimates.last())
        .map(|(a, b)| (a.log_time_s, b.log_time_s));
    ReplayScore {
        frames,
        estimates: estimates.len(),
        two_sigma_coverage: if scored.is_empty() {
            0.0
        } else {
            inside as f64 / scored.len() as f64
        },
        stats: error_stats(&errors),
        scored,
        reference_track: track
            .iter()
            .filter(|(t, _)| span.is_some_and(|(a, b)| (a - 1.0..=b + 1.0).contains(t)))
            .map(|(_, p)| (p.x, p.y))
            .collect(),
    }
}

/// The reference at `time_s`, linear between the fixes around it; none
/// outside the log or across a gap of more than [`MAX_FIX_GAP_S`].
fn interpolate(track: &[(f64, Point2<f64>)], time_s: f64) -> Option<Point2<f64>> {
    let after = track.partition_point(|(t, _)| *t < time_s);
    let (t1, p1) = *track.get(after)?;
    if t1 == time_s {
        return Some(p1);
    }
    let (t0, p0) = *track.get(after.checked_sub(1)?)?;
    if t1 - t0 > MAX_FIX_GAP_S {
        return None;
    }
    let w = (time_s - t0) / (t1 - t0);
    Some(p0 + (p1 - p0) * w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn datum() -> Datum {
        Datum::new(Geodetic::new(59.9, 10.7, 100.0).expect("valid"))
    }

    fn fix(datum: &Datum, t: f64, east: f64) -> ReferenceFix {
        ReferenceFix {
            time_s: t,
            position: datum.to_geodetic(&nalgebra::Point3::new(east, 0.0, 0.0)),
        }
    }

    fn estimate(seq: u64, t: f64, east: f64, north: f64, sigma: f64) -> ReplayEstimate {
        ReplayEstimate {
            seq,
            log_time_s: t,
            east_north: Point2::new(east, north),
            covariance: Matrix2::identity() * sigma * sigma,
        }
    }

    #[test]
    fn estimates_are_scored_against_the_fix_interpolated_to_their_time() {
        let d = datum();
        // The UAV flies east at 10 m/s; fixes each second.
        let fixes: Vec<_> = (0..=10)
            .map(|i| fix(&d, f64::from(i), 10.0 * f64::from(i)))
            .collect();
        let estimates = [
            estimate(0, 2.5, 25.0, 3.0, 2.0), // 3 m off, sigma 2: inside 2-sigma
            estimate(1, 5.25, 52.5, 0.0, 1.0), // right on
            estimate(2, 7.0, 70.0, 8.0, 1.0), // 8 m off, sigma 1: outside
            estimate(3, 12.0, 0.0, 0.0, 1.0), // after the log: not scored
        ];
        let s = score(&d, 8, &estimates, &fixes);
        assert_eq!(s.estimates, 4);
        assert_eq!(s.scored.len(), 3);
        assert!(
            (s.scored[0].error_m - 3.0).abs() < 1e-3,
            "{:?}",
            s.scored[0]
        );
        assert!(s.scored[1].error_m < 1e-3);
        assert!((s.stats.rms - ((9.0 + 64.0) / 3.0f64).sqrt()).abs() < 1e-3);
        assert!((s.two_sigma_coverage - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.stats.within_5m - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.estimate_share() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_gap_in_the_fixes_leaves_its_frames_unscored() {
        let d = datum();
        let fixes = [fix(&d, 0.0, 0.0), fix(&d, 10.0, 100.0)];
        let s = score(&d, 1, &[estimate(0, 5.0, 50.0, 0.0, 1.0)], &fixes);
        assert!(s.scored.is_empty());
        assert_eq!(s.stats.count, 0);
    }
}
