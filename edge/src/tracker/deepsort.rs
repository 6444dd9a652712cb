//! DeepSORT (Wojke et al. 2017): Kalman prediction gated by Mahalanobis
//! distance, appearance matched by cosine distance to a gallery of each
//! track's recent descriptors, and the matching cascade that serves recently
//! seen tracks first; then IoU matching for young and just-missed tracks.
//! Without descriptors the appearance cost falls back to 1 - IoU.

use std::collections::VecDeque;

use towernav_protocol::Detection;

use super::appearance::cosine_distance;
use super::common::{Track, TrackOutput, Tracker, TrackerInput, advance, iou_matches};
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
struct DeepTrack {
    track: Track,
    gallery: VecDeque<Vec<f32>>,
}

#[derive(Debug, Clone)]
pub struct DeepSortTracker {
    params: DeepSortParams,
    tracks: Vec<DeepTrack>,
    next_id: u64,
    last_time_s: Option<f64>,
}

impl DeepSortTracker {
    pub fn new(params: DeepSortParams) -> Self {
        Self {
            params,
            tracks: Vec::new(),
            next_id: 1,
            last_time_s: None,
        }
    }

    fn frames_since_update(&self, t: &DeepTrack, time_s: f64) -> u32 {
        ((time_s - t.track.last_update_s) / self.params.frame_s)
            .round()
            .max(0.0) as u32
    }
}

impl Tracker for DeepSortTracker {
    fn name(&self) -> &'static str {
        "DeepSORT"
    }

    fn live_ids(&self) -> Vec<u64> {
        self.tracks.iter().map(|t| t.track.id).collect()
    }

    fn step(&mut self, input: &TrackerInput<'_>) -> Vec<TrackOutput> {
        let p = self.params;
        let time_s = input.time_s;
        let dt = self.last_time_s.map_or(0.0, |t| (time_s - t).max(0.0));
        self.last_time_s = Some(time_s);
        let mut plain: Vec<Track> = self.tracks.iter().map(|t| t.track.clone()).collect();
        advance(&mut plain, dt, input.motion);
        for (d, t) in self.tracks.iter_mut().zip(plain) {
            d.track = t;
        }
        let dets: Vec<(usize, &Detection)> = input
            .detections
            .iter()
            .enumerate()
            .filter(|(_, d)| d.bbox.is_finite())
            .collect();
        let detections: Vec<&Detection> = dets.iter().map(|(_, d)| *d).collect();
        let feature = |c: usize| input.features.and_then(|f| f.get(dets[c].0));
        let mut det_free = vec![true; detections.len()];
        let mut matches: Vec<(usize, usize)> = Vec::new();

        // Matching cascade: confirmed tracks, most recently seen first.
        for age in 1..=p.max_age_frames {
            let rows: Vec<usize> = (0..self.tracks.len())
                .filter(|&i| {
                    self.tracks[i].track.confirmed
                        && self.frames_since_update(&self.tracks[i], time_s) == age
                        && !matches.iter().any(|(r, _)| *r == i)
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
                    let t = &self.tracks[rows[r]];
                    let d = detections[cols[c]];
                    if t.track.tower_type != d.tower_type
                        || t.track.kf.mahalanobis2(&d.bbox) > MAHALANOBIS_GATE
                    {
                        return 0.0;
                    }
                    let cost = match feature(cols[c]) {
                        Some(f) if !t.gallery.is_empty() => t
                            .gallery
                            .iter()
                            .map(|g| cosine_distance(g, f))
                            .fold(f32::INFINITY, f32::min),
                        _ => (1.0 - t.track.kf.bbox().iou(&d.bbox)) as f32 * p.max_cosine,
                    };
                    if cost > p.max_cosine {
                        0.0
                    } else {
                        f64::from(1.0 - cost)
                    }
                },
                f64::MIN_POSITIVE,
            );
            for (r, c) in found {
                matches.push((rows[r], cols[c]));
                det_free[cols[c]] = false;
            }
        }
        // IoU for unconfirmed tracks and those missed for just one frame.
        let rows: Vec<usize> = (0..self.tracks.len())
            .filter(|&i| {
                !matches.iter().any(|(r, _)| *r == i)
                    && (!self.tracks[i].track.confirmed
                        || self.frames_since_update(&self.tracks[i], time_s) <= 1)
            })
            .collect();
        let cols: Vec<usize> = (0..detections.len()).filter(|&c| det_free[c]).collect();
        let plain: Vec<Track> = self.tracks.iter().map(|t| t.track.clone()).collect();
        for (r, c) in iou_matches(&plain, &rows, &detections, &cols, p.iou_min) {
            matches.push((r, c));
            det_free[c] = false;
        }

        let mut outputs = Vec::new();
        for &(r, c) in &matches {
            let t = &mut self.tracks[r];
            outputs.extend(t.track.hit(detections[c], time_s, p.min_hits));
            if let Some(f) = feature(c) {
                t.gallery.push_front(f.clone());
                t.gallery.truncate(p.gallery);
            }
        }
        for c in (0..detections.len()).filter(|&c| det_free[c]) {
            let mut gallery = VecDeque::new();
            if let Some(f) = feature(c) {
                gallery.push_front(f.clone());
            }
            self.tracks.push(DeepTrack {
                track: Track::new(self.next_id, detections[c], time_s, p.min_hits),
                gallery,
            });
            self.next_id += 1;
        }
        let max_age_s = f64::from(p.max_age_frames) * p.frame_s;
        self.tracks.retain(|t| {
            let missed = time_s - t.track.last_update_s;
            if t.track.confirmed {
                missed <= max_age_s
            } else {
                missed <= 0.5 * p.frame_s
            }
        });
        outputs.sort_by_key(|o| o.track_id);
        outputs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_geometry::PixelBox;
    use towernav_protocol::TowerType;

    fn det(x: f64) -> Detection {
        Detection {
            bbox: PixelBox::new(x, 100.0, x + 30.0, 300.0),
            tower_type: TowerType::B,
            score: 0.9,
        }
    }

    #[test]
    fn appearance_bridges_a_gap_that_iou_cannot() {
        let mut ds = DeepSortTracker::new(DeepSortParams::default());
        let look = |v: f32| vec![v, (1.0 - v * v).sqrt()];
        let mut ids = Vec::new();
        for i in 0..20 {
            let t = f64::from(i) / 30.0;
            // Two towers that look different; the first disappears for 10 frames.
            let dets = if (8..18).contains(&i) {
                vec![det(600.0)]
            } else {
                vec![det(100.0), det(600.0)]
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
