//! From the model's raw output to tower detections in frame pixels.

use towernav_geometry::PixelBox;
use towernav_protocol::Detection;

use super::classes::ClassMap;
use super::decode::{ClassScores, LayoutError, ScoreMode, decode, nms, nms_any_class};
use super::letterbox::Letterbox;

/// Score and overlap thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PostprocessParams {
    /// Candidates below this score are dropped before NMS.
    pub min_score: f32,
    /// Same-class boxes overlapping a better one by more than this are dropped.
    /// 0.65, not 0.5: towers stand in lines, and seen along a line the far
    /// ones stand inside the near ones' boxes (held-out mAP50 0.913 -> 0.924;
    /// Ultralytics uses 0.7).
    pub nms_iou: f64,
    /// Boxes whose clipped height is below this many frame pixels are dropped.
    pub min_height_px: f64,
    /// At most this many boxes, best first (Ultralytics' `max_det`).
    pub max_detections: usize,
    /// Best-class score, or any-type score when a second stage names types.
    pub score: ScoreMode,
    /// Types a box may be reported under, best first: 1 for the pipeline (one
    /// tower, one type). Scoring mAP the way Ultralytics validates
    /// (`multi_label`) asks for every type, so a box whose second guess is
    /// right still ranks.
    pub types_per_box: usize,
    /// How much a second stage that names types weighs the detector's own
    /// type scores against its reading of the crop (0: the crop alone). The
    /// two err differently: the classifier takes cat-head A towers for D, the
    /// detector takes them for B.
    pub detector_type_weight: f32,
}

impl Default for PostprocessParams {
    fn default() -> Self {
        Self {
            min_score: 0.25,
            nms_iou: 0.65,
            min_height_px: 4.0,
            max_detections: 300,
            score: ScoreMode::BestClass,
            types_per_box: 1,
            detector_type_weight: DETECTOR_TYPE_WEIGHT,
        }
    }
}

/// The default `detector_type_weight`.
pub const DETECTOR_TYPE_WEIGHT: f32 = 0.5;

/// A detection with the detector's score for every type.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub detection: Detection,
    pub class_scores: ClassScores,
}

/// Decode, suppress, map back through the letterbox and clip to the frame.
pub fn postprocess(
    output: &[f32],
    shape: &[usize],
    classes: &ClassMap,
    letterbox: &Letterbox,
    frame_size: (u32, u32),
    params: &PostprocessParams,
) -> Result<Vec<Candidate>, LayoutError> {
    let raw = decode(
        output,
        shape,
        classes.len(),
        params.min_score,
        params.score,
        params.types_per_box,
    )?;
    let (w, h) = (f64::from(frame_size.0), f64::from(frame_size.1));
    let kept = match params.score {
        ScoreMode::BestClass => nms(raw, params.nms_iou),
        ScoreMode::AnyType => nms_any_class(raw, params.nms_iou),
    };
    Ok(kept
        .into_iter()
        .filter_map(|d| {
            let bbox: PixelBox = letterbox.to_frame(&d.bbox).clipped(w, h);
            (bbox.height() >= params.min_height_px && bbox.width() > 0.0).then_some(Candidate {
                detection: Detection {
                    bbox,
                    tower_type: classes.tower_type(d.class)?,
                    score: f64::from(d.score),
                },
                class_scores: d.class_scores,
            })
        })
        .take(params.max_detections)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_protocol::TowerType;

    #[test]
    fn v8_boxes_come_back_in_frame_pixels_clipped_and_typed() {
        let classes =
            ClassMap::from_metadata(Some("{0: 'A', 1: 'B', 2: 'C', 3: 'D'}")).expect("classes");
        let lb = Letterbox::new(1280, 720, 512, 320);
        // Candidates: a B box at input (100, 116)..(110, 156); a duplicate of it; a
        // D box hanging off the right edge; a weak one.
        let cols = [
            [105.0, 136.0, 10.0, 40.0, 0.0, 0.9, 0.0, 0.0],
            [105.5, 136.0, 10.0, 40.0, 0.0, 0.8, 0.0, 0.0],
            [510.0, 100.0, 8.0, 40.0, 0.0, 0.0, 0.0, 0.6],
            [300.0, 100.0, 8.0, 40.0, 0.1, 0.0, 0.0, 0.0],
        ];
        let mut data = vec![0f32; 8 * cols.len()];
        for (i, c) in cols.iter().enumerate() {
            for (r, v) in c.iter().enumerate() {
                data[r * cols.len() + i] = *v;
            }
        }
        let dets = postprocess(
            &data,
            &[1, 8, 4],
            &classes,
            &lb,
            (1280, 720),
            &PostprocessParams::default(),
        )
        .expect("decodes");
        assert_eq!(dets.len(), 2, "{dets:?}");
        assert_eq!(dets[0].detection.tower_type, TowerType::B);
        assert_eq!(
            dets[0].detection.bbox,
            PixelBox::new(250.0, 250.0, 275.0, 350.0)
        );
        assert_eq!(dets[0].class_scores[..4], [0.0, 0.9, 0.0, 0.0]);
        assert_eq!(dets[1].detection.tower_type, TowerType::D);
        assert_eq!(dets[1].detection.bbox.right, 1280.0, "clipped to the frame");
    }

    #[test]
    fn a_wrong_shape_is_an_error_not_an_empty_list() {
        let classes = ClassMap::from_metadata(Some("['A', 'B', 'C', 'D']")).expect("classes");
        let lb = Letterbox::new(1280, 720, 512, 320);
        let r = postprocess(
            &[0.0; 84],
            &[1, 84, 1],
            &classes,
            &lb,
            (1280, 720),
            &PostprocessParams::default(),
        );
        assert!(r.is_err());
    }
}
