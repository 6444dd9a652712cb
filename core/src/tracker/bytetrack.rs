//! ByteTrack-style tracking (Zhang et al. 2022): match high-score boxes first,
//! then give the tracks left over a second chance with the low-score boxes a
//! plain tracker would throw away (a half-hidden or far tower scores low).
//! Only high-score boxes start tracks.

use towernav_protocol::Detection;

use super::common::{TrackOutput, TrackSet, Tracker, TrackerInput, iou_matches};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ByteParams {
    /// Boxes at or above this score are "high".
    pub high_score: f64,
    /// Boxes below this are dropped altogether.
    pub low_score: f64,
    pub iou_high: f64,
    /// The second pass asks more overlap: low boxes are less certain.
    pub iou_low: f64,
    pub min_hits: u32,
    pub max_coast_s: f64,
}

impl Default for ByteParams {
    fn default() -> Self {
        Self {
            high_score: 0.6,
            low_score: 0.1,
            iou_high: 0.2,
            iou_low: 0.4,
            min_hits: 3,
            max_coast_s: 0.5,
        }
    }
}

#[derive(Debug, Clone)]
pub struct ByteTracker {
    params: ByteParams,
    set: TrackSet,
}

impl ByteTracker {
    pub fn new(params: ByteParams) -> Self {
        Self {
            params,
            set: TrackSet::default(),
        }
    }
}

impl Tracker for ByteTracker {
    fn name(&self) -> &'static str {
        "ByteTrack-style"
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
            .filter(|d| d.bbox.is_finite() && d.score >= p.low_score)
            .collect();
        let (high, low): (Vec<usize>, Vec<usize>) =
            (0..detections.len()).partition(|&i| detections[i].score >= p.high_score);
        let tracks = &self.set.tracks;
        let all_tracks: Vec<usize> = (0..tracks.len()).collect();
        let first = iou_matches(tracks, &all_tracks, &detections, &high, p.iou_high);
        let left: Vec<usize> = all_tracks
            .iter()
            .copied()
            .filter(|t| !first.iter().any(|(r, _)| r == t))
            .collect();
        let second = iou_matches(tracks, &left, &detections, &low, p.iou_low);
        let mut outputs = Vec::new();
        let mut used = vec![false; detections.len()];
        for (r, c) in first.into_iter().chain(second) {
            used[c] = true;
            outputs.extend(self.set.tracks[r].hit(detections[c], time_s, p.min_hits));
        }
        for &c in &high {
            if !used[c] {
                self.set.spawn(detections[c], time_s, p.min_hits);
            }
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
    fn a_low_score_box_keeps_its_track_alive_but_starts_none() {
        let mut bt = ByteTracker::new(ByteParams::default());
        let mut ids = Vec::new();
        for i in 0..40 {
            // Scores dip low for ten frames, as a half-hidden tower's would.
            let score = if (15..25).contains(&i) { 0.2 } else { 0.9 };
            let out = bt.step(&TrackerInput::new(
                f64::from(i) / 30.0,
                &[det(100.0 + 2.0 * f64::from(i), TowerType::A, score)],
            ));
            ids.extend(out.iter().map(|o| o.track_id));
        }
        assert_eq!(
            ids.len(),
            38,
            "reported every frame after confirmation, low ones included"
        );
        assert!(ids.iter().all(|&id| id == ids[0]));
        let mut fresh = ByteTracker::new(ByteParams::default());
        for i in 0..5 {
            fresh.step(&TrackerInput::new(
                f64::from(i) / 30.0,
                &[det(500.0, TowerType::A, 0.2)],
            ));
        }
        assert!(fresh.live_ids().is_empty(), "low boxes start no track");
    }
}
