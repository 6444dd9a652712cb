//! Scoring a run against the simulator's truth (pure).

use towernav_sim::FrameTruth;

use crate::landmarks::LandmarkMap;
use crate::mot_metrics::{MATCH_IOU, overlap};
use crate::pipeline::FrameOutput;

/// Whether every reported track is bound to its true tower. A track that overlaps
/// no true box (a false positive) must be unbound. `None` for a frame with no tracks.
pub fn all_bound_right(truth: &FrameTruth, out: &FrameOutput, map: &LandmarkMap) -> Option<bool> {
    if out.tracks.is_empty() {
        return None;
    }
    Some(out.tracks.iter().all(|t| {
        let best = truth
            .boxes
            .iter()
            .map(|b| (overlap(&b.bbox, &t.bbox), b))
            .filter(|(iou, _)| *iou >= MATCH_IOU)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let bound = t.tower.map(|i| map.towers[i].id.as_str());
        match best {
            Some((_, b)) => bound == Some(b.tower_id.as_str()),
            None => bound.is_none(),
        }
    }))
}

/// Horizontal error statistics, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    pub count: usize,
    pub rms: f64,
    pub p95: f64,
    pub max: f64,
}

pub fn error_stats(errors: &[f64]) -> ErrorStats {
    if errors.is_empty() {
        return ErrorStats::default();
    }
    let mut sorted = errors.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rms = (sorted.iter().map(|e| e * e).sum::<f64>() / sorted.len() as f64).sqrt();
    let rank = ((0.95 * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    ErrorStats {
        count: sorted.len(),
        rms,
        p95: sorted[rank - 1],
        max: sorted[sorted.len() - 1],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_known_errors() {
        let errors: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = error_stats(&errors);
        assert_eq!(s.count, 100);
        assert_eq!(s.p95, 95.0);
        assert_eq!(s.max, 100.0);
        assert!((s.rms - (338350.0f64 / 100.0).sqrt()).abs() < 1e-9);
        assert_eq!(error_stats(&[]), ErrorStats::default());
    }
}
