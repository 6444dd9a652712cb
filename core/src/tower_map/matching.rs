//! Measured towers against the database: confirmed, missed, new.
//!
//! A measured tower confirms the nearest known one inside the gate: the two
//! uncertainties together (the estimate's ellipse, the record's
//! `sigma_horizontal_m`) at `gate_sigmas`, and never less than `min_gate_m`
//! (records without a sigma are taken at `unknown_sigma_m`, as good as a
//! map's). Each known tower is confirmed once, by its nearest estimate. A
//! known tower the camera should have seen in enough frames, with nothing
//! measured near it, is missed; an estimate near no known tower is new.

use nalgebra::{Matrix2, Point3, Vector2};

use super::triangulate::TowerEstimate;

/// A tower of the database, in the flight's world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct KnownTower {
    pub id: String,
    pub foot_in_world: Point3<f64>,
    pub height_m: f64,
    /// The record's one-sigma horizontal accuracy, if it states one.
    pub sigma_horizontal_m: Option<f64>,
    /// Frames where the camera should have seen it whole, by the log's poses.
    pub frames_in_view: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchParams {
    pub gate_sigmas: f64,
    pub min_gate_m: f64,
    pub unknown_sigma_m: f64,
    /// A known tower in view this many frames should have been measured.
    pub min_frames_in_view: usize,
}

impl Default for MatchParams {
    fn default() -> Self {
        Self {
            gate_sigmas: 3.0,
            min_gate_m: 5.0,
            unknown_sigma_m: 5.0,
            min_frames_in_view: 10,
        }
    }
}

/// What one estimate is, against the database.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// It is the known tower `known`, off by `offset_en` (estimate minus
    /// record, m) and `height_difference_m` (estimate minus record).
    Confirms {
        known: usize,
        offset_en: Vector2<f64>,
        height_difference_m: Option<f64>,
    },
    /// No known tower is near it.
    New,
}

/// The estimates' verdicts (in their order) and the known towers missed.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchReport {
    pub verdicts: Vec<Verdict>,
    /// Known towers in view long enough and measured by nothing.
    pub missed: Vec<usize>,
    /// Known towers neither confirmed nor in view long enough.
    pub not_seen: Vec<usize>,
}

/// Squared Mahalanobis distance of `d` under `cov`, and the gate's radius in
/// metres along `d` for reporting.
fn gated(d: &Vector2<f64>, cov: &Matrix2<f64>, p: &MatchParams) -> Option<f64> {
    let m2 = (d.transpose() * cov.try_inverse()? * d)[0];
    let inside = m2 <= p.gate_sigmas * p.gate_sigmas || d.norm() <= p.min_gate_m;
    inside.then_some(m2)
}

pub fn match_towers(
    estimates: &[TowerEstimate],
    known: &[KnownTower],
    p: &MatchParams,
) -> MatchReport {
    // Every (estimate, known) pair inside the gate, nearest first; each side
    // taken once.
    let mut pairs = Vec::new();
    for (i, e) in estimates.iter().enumerate() {
        for (k, t) in known.iter().enumerate() {
            let d = (e.foot_in_world - t.foot_in_world).xy();
            let s = t.sigma_horizontal_m.unwrap_or(p.unknown_sigma_m);
            let cov = e.covariance_en + Matrix2::identity() * s * s;
            if let Some(m2) = gated(&d, &cov, p) {
                pairs.push((m2, i, k));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut verdicts = vec![Verdict::New; estimates.len()];
    let mut taken = vec![false; known.len()];
    let mut decided = vec![false; estimates.len()];
    for (_, i, k) in pairs {
        if decided[i] || taken[k] {
            continue;
        }
        let (e, t) = (&estimates[i], &known[k]);
        verdicts[i] = Verdict::Confirms {
            known: k,
            offset_en: (e.foot_in_world - t.foot_in_world).xy(),
            height_difference_m: e.height_m.map(|h| h - t.height_m),
        };
        decided[i] = true;
        taken[k] = true;
    }
    let (missed, not_seen) = (0..known.len())
        .filter(|&k| !taken[k])
        .partition(|&k| known[k].frames_in_view >= p.min_frames_in_view);
    MatchReport {
        verdicts,
        missed,
        not_seen,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(east: f64, north: f64, sigma: f64) -> TowerEstimate {
        TowerEstimate {
            foot_in_world: Point3::new(east, north, 0.0),
            covariance_en: Matrix2::identity() * sigma * sigma,
            height_m: Some(31.0),
            height_sigma_m: 0.2,
            views: 20,
            height_views: 20,
            spread_rad: 1.0,
            inlier_share: 1.0,
        }
    }

    fn known(id: &str, east: f64, north: f64, frames_in_view: usize) -> KnownTower {
        KnownTower {
            id: id.into(),
            foot_in_world: Point3::new(east, north, 0.0),
            height_m: 32.0,
            sigma_horizontal_m: None,
            frames_in_view,
        }
    }

    #[test]
    fn the_three_cases() {
        let estimates = [estimate(0.0, 0.0, 0.5), estimate(300.0, 0.0, 0.5)];
        let known = [
            known("A1", 7.0, 0.0, 50),   // OSM-grade, 7 m off: confirmed
            known("A2", 150.0, 0.0, 40), // in view, nothing measured: missed
            known("A3", 900.0, 0.0, 0),  // never in view: not seen
        ];
        let r = match_towers(&estimates, &known, &MatchParams::default());
        match &r.verdicts[0] {
            Verdict::Confirms {
                known,
                offset_en,
                height_difference_m,
            } => {
                assert_eq!(*known, 0);
                assert!((offset_en.x - -7.0).abs() < 1e-9);
                assert_eq!(*height_difference_m, Some(-1.0));
            }
            v => panic!("{v:?}"),
        }
        assert_eq!(r.verdicts[1], Verdict::New);
        assert_eq!(r.missed, vec![1]);
        assert_eq!(r.not_seen, vec![2]);
    }

    #[test]
    fn a_surveyed_tower_gates_tighter_and_one_record_is_confirmed_once() {
        let mut surveyed = known("B1", 6.0, 0.0, 50);
        surveyed.sigma_horizontal_m = Some(0.1);
        let r = match_towers(
            &[estimate(0.0, 0.0, 0.3)],
            &[surveyed],
            &MatchParams::default(),
        );
        assert_eq!(
            r.verdicts[0],
            Verdict::New,
            "6 m off a 0.1 m survey is another tower"
        );

        let twins = [estimate(0.0, 0.0, 0.5), estimate(2.0, 0.0, 0.5)];
        let r = match_towers(
            &twins,
            &[known("C1", 1.8, 0.0, 50)],
            &MatchParams::default(),
        );
        assert!(
            matches!(r.verdicts[1], Verdict::Confirms { known: 0, .. }),
            "the nearer"
        );
        assert_eq!(r.verdicts[0], Verdict::New);
    }
}
