//! What every tracker here shares: a track's state, camera-motion-compensated
//! prediction, IoU association, and the output record.

use towernav_geometry::PixelBox;
use towernav_protocol::{Detection, TowerType};

use super::cmc::CameraMotion;
use super::kalman::BoxKalman;
use crate::assignment::max_score_matching;

/// A confirmed track that a detection updated in this frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackOutput {
    pub track_id: u64,
    /// The detection's box: what the camera measured this frame.
    pub bbox: PixelBox,
    pub tower_type: TowerType,
    /// The detector's confidence in that box.
    pub score: f64,
}

/// One frame for a tracker: time, detections, and optionally the camera's own
/// motion since the last frame (from the IMU) and an appearance feature per detection.
#[derive(Debug, Clone, Copy)]
pub struct TrackerInput<'a> {
    pub time_s: f64,
    pub detections: &'a [Detection],
    pub motion: Option<&'a CameraMotion>,
    pub features: Option<&'a [Vec<f32>]>,
}

impl<'a> TrackerInput<'a> {
    pub fn new(time_s: f64, detections: &'a [Detection]) -> Self {
        Self {
            time_s,
            detections,
            motion: None,
            features: None,
        }
    }
}

/// The trackers' one interface, so evaluations and the pipeline can swap them.
pub trait Tracker {
    fn name(&self) -> &'static str;
    fn step(&mut self, input: &TrackerInput<'_>) -> Vec<TrackOutput>;
    /// Ids of every live track, reported or not.
    fn live_ids(&self) -> Vec<u64>;
}

#[derive(Debug, Clone)]
pub struct Track {
    pub id: u64,
    pub kf: BoxKalman,
    pub tower_type: TowerType,
    pub hits: u32,
    pub last_update_s: f64,
    pub confirmed: bool,
}

impl Track {
    pub fn new(id: u64, d: &Detection, time_s: f64, min_hits: u32) -> Self {
        Self {
            id,
            kf: BoxKalman::new(&d.bbox),
            tower_type: d.tower_type,
            hits: 1,
            last_update_s: time_s,
            confirmed: min_hits <= 1,
        }
    }

    /// Fold in a detection; the output if the track is (now) confirmed.
    pub fn hit(&mut self, d: &Detection, time_s: f64, min_hits: u32) -> Option<TrackOutput> {
        self.kf.update(&d.bbox);
        self.hits += 1;
        self.last_update_s = time_s;
        self.confirmed |= self.hits >= min_hits;
        self.confirmed.then_some(TrackOutput {
            track_id: self.id,
            bbox: d.bbox,
            tower_type: d.tower_type,
            score: d.score,
        })
    }
}

/// The bookkeeping every tracker shares: its tracks, the next id, frame time.
#[derive(Debug, Clone, Default)]
pub struct TrackSet {
    pub tracks: Vec<Track>,
    next_id: u64,
    last_time_s: Option<f64>,
}

impl TrackSet {
    /// Start a frame: predict every track to `time_s`, compensating camera motion.
    pub fn begin(&mut self, time_s: f64, motion: Option<&CameraMotion>) {
        let dt = self.last_time_s.map_or(0.0, |t| (time_s - t).max(0.0));
        self.last_time_s = Some(time_s);
        advance(&mut self.tracks, dt, motion);
    }

    /// A new track from an unmatched detection; returns its id.
    pub fn spawn(&mut self, d: &Detection, time_s: f64, min_hits: u32) -> u64 {
        self.next_id += 1;
        self.tracks
            .push(Track::new(self.next_id, d, time_s, min_hits));
        self.next_id
    }

    pub fn live_ids(&self) -> Vec<u64> {
        self.tracks.iter().map(|t| t.id).collect()
    }

    /// Keep tracks unseen for at most `max_coast_s`.
    pub fn prune(&mut self, time_s: f64, max_coast_s: f64) {
        self.tracks
            .retain(|t| time_s - t.last_update_s <= max_coast_s);
    }
}

/// Predict every track to now, first moving it by the camera's own rotation.
fn advance(tracks: &mut [Track], dt: f64, motion: Option<&CameraMotion>) {
    for t in tracks {
        if let Some(m) = motion
            && let Some(moved) = m.warp_box(&t.kf.bbox())
        {
            t.kf.warp(&moved);
        }
        t.kf.predict(dt);
    }
}

/// Hungarian matching on IoU between the listed tracks and detections (same type only);
/// returns (track index, detection index) pairs in the callers' indexing.
pub fn iou_matches(
    tracks: &[Track],
    track_idx: &[usize],
    detections: &[&Detection],
    det_idx: &[usize],
    min_iou: f64,
) -> Vec<(usize, usize)> {
    let predicted: Vec<PixelBox> = track_idx.iter().map(|&i| tracks[i].kf.bbox()).collect();
    max_score_matching(
        track_idx.len(),
        det_idx.len(),
        |r, c| {
            let d = detections[det_idx[c]];
            if tracks[track_idx[r]].tower_type == d.tower_type {
                predicted[r].iou(&d.bbox)
            } else {
                0.0
            }
        },
        min_iou,
    )
    .into_iter()
    .map(|(r, c)| (track_idx[r], det_idx[c]))
    .collect()
}
