//! Tracking and identity evaluation (pure): run a tracker (or the whole
//! pipeline, for ours) over a scenario and score it with `mot_metrics`.

use image::RgbImage;
use towernav_geometry::{PinholeCamera, PixelBox};
use towernav_sim::{Conditions, FrameTruth, Renderer, Scenario};

use crate::mot_metrics::{Hypothesis, MotAccumulator, MotMetrics};
use towernav_core::landmarks::LandmarkMap;
use towernav_core::pipeline::{FrameOutput, Pipeline, PipelineConfig};
use towernav_core::tracker::appearance::{DIM, describe};
use towernav_core::tracker::{
    ByteParams, ByteTracker, CameraMotion, DeepSortParams, DeepSortTracker, SortParams,
    SortTracker, TimelineCorrection, TimelineParams, Tracker, TrackerInput,
};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// SORT alone, as the paper ran it: identities are its track ids.
    Sort,
    /// SORT followed by the paper's timeline correction.
    SortTimeline,
    /// SORT with camera-motion compensation from the IMU.
    SortCmc,
    /// ByteTrack-style with camera-motion compensation.
    ByteTrack,
    /// DeepSORT with camera-motion compensation and appearance from rendered crops.
    DeepSort,
    /// DeepSORT followed by the paper's timeline correction.
    DeepSortTimeline,
    /// Ours: SORT with compensation, identity (map association, trusted-pose
    /// gating, evidence with hysteresis) and localization; identities are the bound towers.
    Ours,
}

impl Method {
    pub const ALL: [Method; 7] = [
        Method::Sort,
        Method::SortTimeline,
        Method::SortCmc,
        Method::ByteTrack,
        Method::DeepSort,
        Method::DeepSortTimeline,
        Method::Ours,
    ];

    /// Whether the method needs appearance descriptors of each detection.
    pub fn needs_features(self) -> bool {
        matches!(self, Self::DeepSort | Self::DeepSortTimeline)
    }

    /// For file names.
    pub fn slug(self) -> &'static str {
        match self {
            Self::Sort => "sort",
            Self::SortTimeline => "sort-timeline",
            Self::SortCmc => "sort-cmc",
            Self::ByteTrack => "bytetrack-cmc",
            Self::DeepSort => "deepsort-cmc",
            Self::DeepSortTimeline => "deepsort-cmc-timeline",
            Self::Ours => "ours",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Sort => "SORT",
            Self::SortTimeline => "SORT + timeline correction",
            Self::SortCmc => "SORT + CMC",
            Self::ByteTrack => "ByteTrack-style + CMC",
            Self::DeepSort => "DeepSORT + CMC",
            Self::DeepSortTimeline => "DeepSORT + CMC + timeline correction",
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

/// Score one frame's hypotheses against its truth (demanded boxes; the rest "don't care").
pub fn add_frame(
    acc: &mut MotAccumulator,
    scenario: &Scenario,
    truth: &FrameTruth,
    hyps: &[Hypothesis],
) {
    let (gt, ignore): (Vec<_>, Vec<_>) = truth.boxes.iter().partition(|b| scenario.demanded(b));
    let gt: Vec<(String, _)> = gt.iter().map(|b| (b.tower_id.clone(), b.bbox)).collect();
    let ignore: Vec<_> = ignore.iter().map(|b| b.bbox).collect();
    acc.add_frame(&gt, &ignore, hyps);
}

/// Ours, as hypotheses: a bound track is named by its tower, an unbound one
/// by its track. A track whose box is left out for a frame keeps its name
/// (its binding holds), but claims no tower for that frame.
pub fn pipeline_hypotheses(out: &FrameOutput, map: &LandmarkMap) -> Vec<Hypothesis> {
    out.tracks
        .iter()
        .map(|t| {
            let name = |i: usize| map.towers[i].id.clone();
            Hypothesis {
                id: t
                    .held
                    .or(t.tower)
                    .map_or_else(|| format!("track-{}", t.track_id), name),
                bbox: t.bbox,
                tower: t.tower.map(name),
            }
        })
        .collect()
}

/// Turns one rendered frame's boxes into appearance descriptors.
pub type Describer<'a> = dyn FnMut(&RgbImage, &[PixelBox]) -> Vec<Vec<f32>> + 'a;

/// The Rust crop descriptor for each box of a frame.
pub fn describe_all(image: &RgbImage, boxes: &[PixelBox]) -> Vec<Vec<f32>> {
    boxes
        .iter()
        .map(|b| describe(image, b).unwrap_or_else(|| vec![0.0; DIM]))
        .collect()
}

/// Appearance descriptors of every detection of every frame, from the frames
/// rendered at half resolution; `describe` turns a frame's boxes into
/// descriptors (`describe_all`, or a re-identification model in the shell).
/// `on_frame` reports progress.
pub fn render_features(
    scenario: &Scenario,
    describe: &mut Describer<'_>,
    mut on_frame: impl FnMut(u64),
) -> Vec<Vec<Vec<f32>>> {
    let half = PinholeCamera {
        intrinsics: scenario.camera.intrinsics.scaled(0.5),
        ..scenario.camera
    };
    let renderer = Renderer::new(&scenario.world, half, scenario.seed);
    let mut buffers = renderer.buffers();
    let conditions = Conditions::default();
    scenario
        .frames()
        .map(|(truth, frame)| {
            let rates = scenario.flight.attitude_rates(truth.time_s);
            renderer.render_into(&mut buffers, &truth.pose, &conditions, rates, truth.seq);
            on_frame(truth.seq);
            let boxes: Vec<PixelBox> = frame
                .detections
                .iter()
                .map(|d| {
                    PixelBox::new(
                        d.bbox.left * 0.5,
                        d.bbox.top * 0.5,
                        d.bbox.right * 0.5,
                        d.bbox.bottom * 0.5,
                    )
                })
                .collect();
            describe(&buffers.image, &boxes)
        })
        .collect()
}

/// Run `method` over `scenario`. `features` (from `render_features`) feed the
/// DeepSORT methods, which fall back to IoU without them.
pub fn run(
    scenario: &Scenario,
    map: &LandmarkMap,
    method: Method,
    features: Option<&[Vec<Vec<f32>>]>,
) -> TrackingRun {
    let mut acc = MotAccumulator::default();
    let mut frames = Vec::new();
    let mut tracker: Box<dyn Tracker> = match method {
        Method::ByteTrack => Box::new(ByteTracker::new(ByteParams::default())),
        Method::DeepSort | Method::DeepSortTimeline => {
            Box::new(DeepSortTracker::new(DeepSortParams::default()))
        }
        _ => Box::new(SortTracker::new(SortParams::default())),
    };
    let mut timeline = TimelineCorrection::new(TimelineParams::default());
    let mut prev_attitude = None;
    let mut pipeline = Pipeline::new(
        PipelineConfig::new(scenario.camera, scenario.start_in_world()),
        map.clone(),
    );
    for (truth, frame) in scenario.frames() {
        let hyps: Vec<Hypothesis> = if method == Method::Ours {
            pipeline_hypotheses(&pipeline.process(&frame), map)
        } else {
            let compensate = !matches!(method, Method::Sort | Method::SortTimeline);
            let motion = prev_attitude.filter(|_| compensate).map(|before| {
                CameraMotion::between(&scenario.camera, &before, &frame.imu_attitude)
            });
            prev_attitude = Some(frame.imu_attitude);
            let feats = features
                .filter(|_| method.needs_features())
                .and_then(|f| f.get(truth.seq as usize))
                .map(Vec::as_slice);
            let outputs = tracker.step(&TrackerInput {
                time_s: frame.time_s,
                detections: &frame.detections,
                motion: motion.as_ref(),
                features: feats,
            });
            let outputs = if matches!(method, Method::SortTimeline | Method::DeepSortTimeline) {
                timeline.apply(truth.seq, outputs)
            } else {
                outputs
            };
            outputs
                .into_iter()
                .map(|t| Hypothesis {
                    id: t.track_id.to_string(),
                    bbox: t.bbox,
                    tower: None,
                })
                .collect()
        };
        add_frame(&mut acc, scenario, &truth, &hyps);
        frames.push((truth.seq, hyps));
    }
    TrackingRun {
        frames,
        metrics: acc.finish(),
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;
    use towernav_core::filter::FixVerdict;
    use towernav_core::{BoundTrack, MapTower};
    use towernav_geometry::{Datum, Geodetic};
    use towernav_protocol::TowerType;

    use super::*;

    #[test]
    fn a_track_left_out_for_a_frame_keeps_its_name_but_claims_no_tower() {
        let tower = MapTower {
            id: "L1-A1".into(),
            tower_type: TowerType::A,
            foot_in_world: Point3::new(100.0, 0.0, 0.0),
            height_m: 30.0,
            sigma_horizontal_m: 0.0,
            sigma_vertical_m: 0.0,
        };
        let datum = Datum::new(Geodetic {
            lat_deg: 30.5,
            lon_deg: 114.3,
            height_m: 0.0,
        });
        let map = LandmarkMap::new(vec![tower], datum);
        let track = |id: u64, tower: Option<usize>, held: Option<usize>| BoundTrack {
            track_id: id,
            bbox: PixelBox::new(600.0, 200.0, 640.0, 400.0),
            tower_type: TowerType::A,
            tower,
            held,
            pinned: false,
            confidence: None,
        };
        let out = FrameOutput {
            seq: 0,
            time_s: 0.0,
            fix: None,
            estimate: None,
            verdict: FixVerdict::NoFix,
            paper_fix: None,
            tracks: vec![
                track(1, Some(0), Some(0)),
                track(2, None, Some(0)),
                track(3, None, None),
            ],
        };
        let named: Vec<(String, Option<String>)> = pipeline_hypotheses(&out, &map)
            .into_iter()
            .map(|h| (h.id, h.tower))
            .collect();
        assert_eq!(
            named,
            [
                ("L1-A1".to_owned(), Some("L1-A1".to_owned())),
                ("L1-A1".to_owned(), None),
                ("track-3".to_owned(), None),
            ]
        );
    }
}
