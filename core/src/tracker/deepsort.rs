//! DeepSORT (Wojke et al. 2017): Kalman prediction gated by Mahalanobis
//! distance, appearance matched by cosine distance to a gallery of each
//! track's recent descriptors, and the matching cascade that serves recently
//! seen tracks first; then IoU matching for young and just-missed tracks.
//! Without descriptors the appearance cost falls back to 1 - IoU.

use std::collections::{HashMap, VecDeque};

use towernav_protocol::Detection;

use super::appearance::cosine_distance;
use super::common::{Track, TrackOutput, TrackSet, Tracker, TrackerInput, iou_matches};
use crate::assignment::max_score_matching;

/// Chi-square at 95 % for 4 degrees of freedom (DeepSORT's gate).
const MAHALANOBIS_GATE: f64 = 9.4877;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeepSortParams {
    /// Largest cosine distance to a gallery that still matches.
    pub max_cosine: f32,
    /// Descriptors kept per track.
    pub gallery: usize,
    /// Cascade depth and track lifetime without detections, frames.
    pub max_age_frames: u32,
    pub iou_min: f64,
    pub min_hits: u32,
    /// Frame period used to count frames from times, seconds.
    pub frame_s: f64,
}

impl Default for DeepSortParams {
    fn default() -> Self {
        Self {
            max_cosine: 0.2,
            gallery: 30,
            max_age_frames: 30,
            iou_min: 0.2,
            min_hits: 3,
            frame_s: 1.0 / 30.0,
        }
    }
}

#[derive(Debug, Clone)]
pub struct DeepSortTracker {
    params: DeepSortParams,
    set: TrackSet,
    /// Recent descriptors per track id, newest first.
    galleries: HashMap<u64, VecDeque<Vec<f32>>>,
}

impl DeepSortTracker {
    pub fn new(params: DeepSortParams) -> Self {
        Self {
            params,
            set: TrackSet::default(),
            galleries: HashMap::new(),
        }
    }

    fn frames_since_update(&self, t: &Track, time_s: f64) -> u32 {
        ((time_s - t.last_update_s) / self.params.frame_s)
            .round()
            .max(0.0) as u32
    }

    /// Appearance cost of a track for a detection, or `None` outside the gates.
    fn cost(&self, t: &Track, d: &Detection, feature: Option<&Vec<f32>>) -> Option<f32> {
        let p = self.params;
        if t.tower_type != d.tower_type || t.kf.mahalanobis2(&d.bbox) > MAHALANOBIS_GATE {
            return None;
        }
        let gallery = self.galleries.get(&t.id).filter(|g| !g.is_empty());
        let cost = match (feature, gallery) {
            (Some(f), Some(g)) => g
                .iter()
                .map(|x| cosine_distance(x, f))
                .fold(f32::INFINITY, f32::min),
            _ => (1.0 - t.kf.bbox().iou(&d.bbox)) as f32 * p.max_cosine,
        };
        (cost <= p.max_cosine).then_some(cost)
    }
}

impl Tracker for DeepSortTracker {
    fn name(&self) -> &'static str {
        "DeepSORT"
    }

    fn live_ids(&self) -> Vec<u64> {
        self.set.live_ids()
    }

    fn step(&mut self, input: &TrackerInput<'_>) -> Vec<TrackOutput> {
        let p = self.params;
        let time_s = input.time_s;
        self.set.begin(time_s, input.motion);
        let dets: Vec<(usize, &Detection)> = input
            .detections
            .iter()
            .enumerate()
            .filter(|(_, d)| d.bbox.is_finite())
            .collect();
        let detections: Vec<&Detection> = dets.iter().map(|(_, d)| *d).collect();
        let feature = |c: usize| input.features.and_then(|f| f.get(dets[c].0));
        let mut det_free = vec![true; detections.len()];
        let mut track_free = vec![true; self.set.tracks.len()];
        let mut matches: Vec<(usize, usize)> = Vec::new();

        // Matching cascade: confirmed tracks, most recently seen first.
        for age in 1..=p.max_age_frames {
            let tracks = &self.set.tracks;
            let rows: Vec<usize> = (0..tracks.len())
                .filter(|&i| {
                    track_free[i]
                        && tracks[i].confirmed
                        && self.frames_since_update(&tracks[i], time_s) == age
                })
                .collect();
            let cols: Vec<usize> = (0..detections.len()).filter(|&c| det_free[c]).collect();
            if rows.is_empty() || cols.is_empty() {
                continue;
            }
            let found = max_score_matching(
                rows.len(),
                cols.len(),
                |r, c| {
                    self.cost(&tracks[rows[r]], detections[cols[c]], feature(cols[c]))
                        .map_or(0.0, |cost| f64::from(1.0 - cost))
                },
                f64::MIN_POSITIVE,
            );
            for (r, c) in found {
                matches.push((rows[r], cols[c]));
                track_free[rows[r]] = false;
                det_free[cols[c]] = false;
            }
        }
        // IoU for unconfirmed tracks and those missed for just one frame.
        let rows: Vec<usize> = (0..self.set.tracks.len())
            .filter(|&i| {
                let t = &self.set.tracks[i];
                track_free[i] && (!t.confirmed || self.frames_since_update(t, time_s) <= 1)
            })
            .collect();
        let cols: Vec<usize> = (0..detections.len()).filter(|&c| det_free[c]).collect();
        for (r, c) in iou_matches(&self.set.tracks, &rows, &detections, &cols, p.iou_min) {
            matches.push((r, c));
            det_free[c] = false;
        }

        let mut outputs = Vec::new();
        for &(r, c) in &matches {
            let t = &mut self.set.tracks[r];
            outputs.extend(t.hit(detections[c], time_s, p.min_hits));
            if let Some(f) = feature(c) {
                let g = self.galleries.entry(t.id).or_default();
                g.push_front(f.clone());
                g.truncate(p.gallery);
            }
        }
        for c in (0..detections.len()).filter(|&c| det_free[c]) {
            let id = self.set.spawn(detections[c], time_s, p.min_hits);
            if let Some(f) = feature(c) {
                self.galleries.insert(id, VecDeque::from([f.clone()]));
            }
        }
        // Confirmed tracks live through the cascade's depth; a tentative one
        // dies at its first miss.
        let max_age_s = f64::from(p.max_age_frames) * p.frame_s;
        self.set.tracks.retain(|t| {
            let missed = time_s - t.last_update_s;
            missed
                <= if t.confirmed {
                    max_age_s
                } else {
                    0.5 * p.frame_s
                }
        });
        let live: Vec<u64> = self.set.live_ids();
        self.galleries.retain(|id, _| live.contains(id));
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
    fn appearance_bridges_a_gap_that_iou_cannot() {
        let mut ds = DeepSortTracker::new(DeepSortParams::default());
        let look = |v: f32| vec![v, (1.0 - v * v).sqrt()];
        let mut ids = Vec::new();
        for i in 0..20 {
            let t = f64::from(i) / 30.0;
            // Two towers that look different; the first disappears for 10 frames.
            let dets = if (8..18).contains(&i) {
                vec![det(600.0, TowerType::B, 0.9)]
            } else {
                vec![det(100.0, TowerType::B, 0.9), det(600.0, TowerType::B, 0.9)]
            };
            let feats: Vec<Vec<f32>> = if (8..18).contains(&i) {
                vec![look(0.0)]
            } else {
                vec![look(1.0), look(0.0)]
            };
            let out = ds.step(&TrackerInput {
                time_s: t,
                detections: &dets,
                motion: None,
                features: Some(&feats),
            });
            ids.extend(
                out.iter()
                    .filter(|o| o.bbox.left < 300.0)
                    .map(|o| o.track_id),
            );
        }
        assert!(ids.len() >= 7);
        assert!(
            ids.iter().all(|&id| id == ids[0]),
            "one id across the gap: {ids:?}"
        );
    }
}
