//! SORT: Kalman prediction plus Hungarian assignment on IoU (Bewley et al. 2016).
//! Boxes of different tower types never match.

use towernav_protocol::Detection;

use super::common::{TrackOutput, TrackSet, Tracker, TrackerInput, iou_matches};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SortParams {
    /// Least IoU between a prediction and a detection to associate them.
    pub iou_min: f64,
    /// Hits before a track is reported.
    pub min_hits: u32,
    /// Seconds a track survives without a detection.
    pub max_coast_s: f64,
    /// Detections under this score start no track.
    pub min_score: f64,
}

impl Default for SortParams {
    fn default() -> Self {
        Self {
            iou_min: 0.2,
            min_hits: 3,
            max_coast_s: 0.5,
            min_score: 0.3,
        }
    }
}

#[derive(Debug, Clone)]
pub struct SortTracker {
    params: SortParams,
    set: TrackSet,
}

impl SortTracker {
    pub fn new(params: SortParams) -> Self {
        Self {
            params,
            set: TrackSet::default(),
        }
    }

    /// One frame with no camera-motion compensation.
    pub fn update(&mut self, time_s: f64, detections: &[Detection]) -> Vec<TrackOutput> {
        self.step(&TrackerInput::new(time_s, detections))
    }
}

impl Tracker for SortTracker {
    fn name(&self) -> &'static str {
        "SORT"
    }

    fn live_ids(&self) -> Vec<u64> {
        self.set.live_ids()
    }

    fn step(&mut self, input: &TrackerInput<'_>) -> Vec<TrackOutput> {
        let p = self.params;
        let time_s = input.time_s;
        self.set.begin(time_s, input.motion);
        let detections: Vec<&Detection> = input
            .detections
            .iter()
            .filter(|d| d.bbox.is_finite())
            .collect();
        let all_tracks: Vec<usize> = (0..self.set.tracks.len()).collect();
        let all_dets: Vec<usize> = (0..detections.len()).collect();
        let matches = iou_matches(
            &self.set.tracks,
            &all_tracks,
            &detections,
            &all_dets,
            p.iou_min,
        );
        let mut matched = vec![false; detections.len()];
        let mut outputs = Vec::new();
        for (r, c) in matches {
            matched[c] = true;
            outputs.extend(self.set.tracks[r].hit(detections[c], time_s, p.min_hits));
        }
        for (d, _) in detections
            .iter()
            .zip(&matched)
            .filter(|(d, m)| !**m && d.score >= p.min_score)
        {
            self.set.spawn(d, time_s, p.min_hits);
        }
        self.set.prune(time_s, p.max_coast_s);
        outputs.sort_by_key(|o| o.track_id);
        outputs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::det;
    use towernav_protocol::TowerType;

    #[test]
    fn a_moving_box_keeps_one_id_after_confirmation() {
        let mut sort = SortTracker::new(SortParams::default());
        let mut ids = Vec::new();
        for i in 0..60 {
            let out = sort.update(
                i as f64 / 30.0,
                &[det(100.0 + 3.0 * i as f64, TowerType::A, 0.9)],
            );
            ids.extend(out.iter().map(|o| o.track_id));
        }
        assert_eq!(ids.len(), 58, "reported from the third hit on");
        assert!(ids.iter().all(|&id| id == ids[0]));
    }

    #[test]
    fn different_types_never_share_a_track() {
        let mut sort = SortTracker::new(SortParams {
            min_hits: 1,
            ..SortParams::default()
        });
        sort.update(0.0, &[det(100.0, TowerType::A, 0.9)]);
        let out = sort.update(1.0 / 30.0, &[det(100.0, TowerType::B, 0.9)]);
        assert!(out.is_empty(), "the B box must not continue the A track");
        assert_eq!(sort.live_ids().len(), 2);
    }

    #[test]
    fn a_track_dies_after_coasting_too_long() {
        let mut sort = SortTracker::new(SortParams::default());
        for i in 0..5 {
            sort.update(i as f64 / 30.0, &[det(100.0, TowerType::C, 0.9)]);
        }
        sort.update(0.5, &[]);
        assert_eq!(sort.live_ids().len(), 1);
        sort.update(1.0, &[]);
        assert_eq!(sort.live_ids().len(), 0);
    }
}
