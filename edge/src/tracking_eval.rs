//! Tracking and identity evaluation (pure): run a tracker (or the whole
//! pipeline, for ours) over a scenario and score it with `mot_metrics`.

use towernav_sim::Scenario;

use crate::landmarks::LandmarkMap;
use crate::mot_metrics::{Hypothesis, MotAccumulator, MotMetrics};
use crate::pipeline::{Pipeline, PipelineConfig};
use crate::tracker::{
    ByteParams, ByteTracker, CameraMotion, SortParams, SortTracker, Tracker, TrackerInput,
};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// SORT alone, as the seed ran it: identities are its track ids.
    Sort,
    /// SORT with camera-motion compensation from the IMU.
    SortCmc,
    /// ByteTrack-style with camera-motion compensation.
    ByteTrack,
    /// Ours: SORT with compensation, identity (map association, trusted-pose
    /// gating, release) and localization; identities are the bound towers.
    Ours,
}

impl Method {
    pub const ALL: [Method; 4] = [
        Method::Sort,
        Method::SortCmc,
        Method::ByteTrack,
        Method::Ours,
    ];

    /// For file names.
    pub fn slug(self) -> &'static str {
        match self {
            Self::Sort => "sort",
            Self::SortCmc => "sort-cmc",
            Self::ByteTrack => "bytetrack-cmc",
            Self::Ours => "ours",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Sort => "SORT",
            Self::SortCmc => "SORT + CMC",
            Self::ByteTrack => "ByteTrack-style + CMC",
            Self::Ours => "ours (identity + map association)",
        }
    }
}

/// Per-frame hypotheses of one run, in MOT terms, and their metrics.
#[derive(Debug, Clone, Default)]
pub struct TrackingRun {
    /// (frame seq, hypotheses) for MOT-format output.
    pub frames: Vec<(u64, Vec<Hypothesis>)>,
    pub metrics: MotMetrics,
}

/// Whether a true box is one a tracker must cover: tall enough that the
/// detector reliably reports it, and mostly unhidden. Others are "don't care".
pub fn demanded(b: &towernav_sim::TruthBox, scenario: &Scenario) -> bool {
    b.bbox.height() >= 2.0 * scenario.oracle.min_height_px && b.occluded < 0.75
}

pub fn run(scenario: &Scenario, map: &LandmarkMap, method: Method) -> TrackingRun {
    let mut acc = MotAccumulator::default();
    let mut frames = Vec::new();
    let mut tracker: Box<dyn Tracker> = match method {
        Method::ByteTrack => Box::new(ByteTracker::new(ByteParams::default())),
        _ => Box::new(SortTracker::new(SortParams::default())),
    };
    let mut prev_attitude = None;
    let mut pipeline = Pipeline::new(
        PipelineConfig::new(scenario.camera, scenario.start_in_world()),
        map.clone(),
    );
    for (truth, frame) in scenario.frames() {
        let hyps: Vec<Hypothesis> = match method {
            Method::Sort | Method::SortCmc | Method::ByteTrack => {
                let motion = prev_attitude
                    .filter(|_| method != Method::Sort)
                    .map(|before| {
                        CameraMotion::between(&scenario.camera, &before, &frame.imu_attitude)
                    });
                prev_attitude = Some(frame.imu_attitude);
                tracker
                    .step(&TrackerInput {
                        time_s: frame.time_s,
                        detections: &frame.detections,
                        motion: motion.as_ref(),
                        features: None,
                    })
                    .into_iter()
                    .map(|t| Hypothesis {
                        id: t.track_id.to_string(),
                        bbox: t.bbox,
                        tower: None,
                    })
                    .collect()
            }
            Method::Ours => pipeline
                .process(&frame)
                .tracks
                .into_iter()
                .map(|t| {
                    let tower = t.tower.map(|i| map.towers[i].id.clone());
                    Hypothesis {
                        id: tower
                            .clone()
                            .unwrap_or_else(|| format!("track-{}", t.track_id)),
                        bbox: t.bbox,
                        tower,
                    }
                })
                .collect(),
        };
        let (gt, ignore): (Vec<_>, Vec<_>) =
            truth.boxes.iter().partition(|b| demanded(b, scenario));
        let gt: Vec<(String, _)> = gt.iter().map(|b| (b.tower_id.clone(), b.bbox)).collect();
        let ignore: Vec<_> = ignore.iter().map(|b| b.bbox).collect();
        acc.add_frame(&gt, &ignore, &hyps);
        frames.push((truth.seq, hyps));
    }
    TrackingRun {
        frames,
        metrics: acc.finish(),
    }
}
