//! The detector's second stage, pure parts: cutting each box out of the
//! full-resolution frame for the tower-type classifier, and giving the boxes
//! the types it reads.
//!
//! The detector sees the frame shrunk to its input (0.4x for 512x320), where a
//! 40 px tower's arms blur together: it finds towers far better than it tells
//! their types apart. The classifier looks again at full resolution.
//! `training/train_types.py` cuts its training crops the same way.

use towernav_geometry::PixelBox;
use towernav_protocol::Detection;

use super::classes::ClassMap;
use super::crop_batch::Region;
use super::decode::{ClassScores, RawDetection, best_class, nms, runners_up};
use super::postprocess::{Candidate, PostprocessParams};

/// Crop side over the box's longer edge (`PAD` in `training/train_types.py`).
pub const CROP_PAD: f64 = 1.15;

/// The square around a box that the classifier sees, in whole frame pixels
/// (it may reach past the frame's edges; `CropBatch` reads grey there).
pub fn crop_square(b: &PixelBox) -> Region {
    let side = CROP_PAD * b.width().max(b.height());
    let size = (side.round() as u32).max(1);
    Region {
        left: (b.center_x() - side / 2.0).round() as i64,
        top: (b.center_y() - side / 2.0).round() as i64,
        width: size,
        height: size,
    }
}

/// Give each box its type (its `types_per_box` likeliest, for scoring mAP as
/// Ultralytics does). `probs` holds the classifier's class probabilities, one
/// row per box in `classes`' order; they are blended with the detector's own
/// type scores (`params.detector_type_weight`). The score becomes the
/// detector's (how sure it is of a tower) times the type's probability, and
/// boxes the new types made duplicates of one another are suppressed.
pub fn retype(
    candidates: &[Candidate],
    probs: &[f32],
    classes: &ClassMap,
    params: &PostprocessParams,
) -> Vec<Detection> {
    let k = classes.len();
    let raw: Vec<RawDetection> = candidates
        .iter()
        .zip(probs.chunks_exact(k))
        .flat_map(|(c, p)| {
            let p = blend(p, &c.class_scores, params.detector_type_weight);
            let best = best_class(p.iter().copied());
            let ranked = std::iter::once(best).chain(runners_up(
                p.iter().copied(),
                best.0,
                params.types_per_box,
            ));
            ranked.filter_map(move |(class, prob)| {
                Some(RawDetection {
                    bbox: c.detection.bbox,
                    class: classes.tower_type(class).map(|_| class)?,
                    score: (c.detection.score as f32) * prob,
                    class_scores: p,
                })
            })
        })
        .collect();
    nms(raw, params.nms_iou)
        .into_iter()
        .filter_map(|r| {
            Some(Detection {
                bbox: r.bbox,
                tower_type: classes.tower_type(r.class)?,
                score: f64::from(r.score),
            })
        })
        .collect()
}

/// The classifier's probabilities and the detector's type scores (made to
/// sum to one) in a weighted geometric mean, normalised: a type either model
/// rules out stays unlikely, and where they disagree the surer one leads.
fn blend(probs: &[f32], detector: &ClassScores, weight: f32) -> ClassScores {
    /// Floor on each probability: a zero would veto a type outright.
    const FLOOR: f32 = 1e-4;
    let total: f32 = detector.iter().take(probs.len()).map(|s| s.max(0.0)).sum();
    let mut out = ClassScores::default();
    for (i, (slot, &p)) in out.iter_mut().zip(probs).enumerate() {
        let q = if total > 0.0 {
            detector[i].max(0.0) / total
        } else {
            1.0 / probs.len() as f32
        };
        *slot = (1.0 - weight) * p.max(FLOOR).ln() + weight * q.max(FLOOR).ln();
    }
    let top = out[..probs.len()]
        .iter()
        .copied()
        .fold(f32::NEG_INFINITY, f32::max);
    let mut sum = 0.0;
    for v in &mut out[..probs.len()] {
        *v = (*v - top).exp();
        sum += *v;
    }
    for v in &mut out[..probs.len()] {
        *v /= sum;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use towernav_protocol::TowerType;

    fn classes() -> ClassMap {
        ClassMap::from_metadata(Some("{0: 'A', 1: 'B', 2: 'C', 3: 'D'}")).expect("classes")
    }

    #[test]
    fn the_square_is_centred_on_the_box_and_may_pass_the_edge() {
        let b = PixelBox::new(0.0, 20.0, 20.0, 60.0);
        assert_eq!(
            crop_square(&b),
            Region {
                left: -13,
                top: 17,
                width: 46,
                height: 46
            }
        );
    }

    fn candidate(bbox: PixelBox, tower_type: TowerType, score: f64) -> Candidate {
        let mut class_scores = ClassScores::default();
        class_scores[tower_type.rendered_index().expect("a rendered design")] = 1.0;
        Candidate {
            detection: Detection {
                bbox,
                tower_type,
                score,
            },
            class_scores,
        }
    }

    /// The classifier alone names the type.
    fn crop_only(types_per_box: usize) -> PostprocessParams {
        PostprocessParams {
            nms_iou: 0.5,
            types_per_box,
            detector_type_weight: 0.0,
            ..PostprocessParams::default()
        }
    }

    #[test]
    fn boxes_take_the_classifier_type_and_new_duplicates_go() {
        let b = PixelBox::new(100.0, 100.0, 120.0, 180.0);
        let shifted = PixelBox::new(101.0, 100.0, 121.0, 180.0);
        let dets = [
            candidate(b, TowerType::C, 0.8),
            // The detector's second guess at the same tower.
            candidate(shifted, TowerType::D, 0.6),
        ];
        let probs = [0.0, 0.9, 0.1, 0.0, 0.1, 0.7, 0.2, 0.0];
        let out = retype(&dets, &probs, &classes(), &crop_only(1));
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].tower_type, TowerType::B);
        assert!((out[0].score - 0.72).abs() < 1e-3);
        assert_eq!(out[0].bbox, b);
    }

    #[test]
    fn a_box_may_carry_its_likelier_types_each_with_its_own_score() {
        let b = PixelBox::new(100.0, 100.0, 120.0, 180.0);
        let dets = [candidate(b, TowerType::A, 0.5)];
        let probs = [0.1, 0.6, 0.3, 0.0];
        let out = retype(&dets, &probs, &classes(), &crop_only(2));
        let got: Vec<(TowerType, f64)> = out.iter().map(|d| (d.tower_type, d.score)).collect();
        assert_eq!(got.len(), 2, "{got:?}");
        assert_eq!((got[0].0, got[1].0), (TowerType::B, TowerType::C));
        assert!((got[0].1 - 0.3).abs() < 1e-3 && (got[1].1 - 0.15).abs() < 1e-3);
        assert!(out.iter().all(|d| d.bbox == b));
    }

    #[test]
    fn a_detector_sure_of_the_type_tips_a_classifier_in_doubt() {
        let b = PixelBox::new(100.0, 100.0, 120.0, 180.0);
        // The crop reads D a little more than A; the detector saw an A.
        let mut dets = [candidate(b, TowerType::A, 0.9)];
        dets[0].class_scores[..4].copy_from_slice(&[0.8, 0.05, 0.0, 0.1]);
        let probs = [0.4, 0.02, 0.03, 0.55];
        let params = PostprocessParams::default();
        assert!(params.detector_type_weight > 0.0);
        assert_eq!(
            retype(&dets, &probs, &classes(), &params)[0].tower_type,
            TowerType::A
        );
        assert_eq!(
            retype(&dets, &probs, &classes(), &crop_only(1))[0].tower_type,
            TowerType::D
        );
        // A classifier that is sure keeps its type against the detector.
        let sure = [0.05, 0.0, 0.0, 0.95];
        assert_eq!(
            retype(&dets, &sure, &classes(), &params)[0].tower_type,
            TowerType::D
        );
    }

    proptest! {
        #[test]
        fn the_square_holds_the_box(
            left in -50.0..1300.0f64, top in -50.0..700.0f64,
            w in 1.0..400.0f64, h in 1.0..700.0f64,
        ) {
            let b = PixelBox::new(left, top, left + w, top + h);
            let r = crop_square(&b);
            let (x, y, side) = (r.left, r.top, f64::from(r.width));
            prop_assert_eq!(r.width, r.height);
            prop_assert!(x as f64 <= b.left + 0.5 && y as f64 <= b.top + 0.5);
            prop_assert!(x as f64 + side >= b.right - 0.5 && y as f64 + side >= b.bottom - 0.5);
            prop_assert!((side - CROP_PAD * w.max(h)).abs() <= 0.5);
        }

        #[test]
        fn a_blend_is_a_distribution_and_weight_zero_is_the_classifier(
            raw in proptest::array::uniform4(0.001..1.0f32),
            detector in proptest::array::uniform4(0.0..1.0f32),
            weight in 0.0..1.0f32,
        ) {
            let total: f32 = raw.iter().sum();
            let probs: Vec<f32> = raw.iter().map(|p| p / total).collect();
            let mut scores = ClassScores::default();
            scores[..4].copy_from_slice(&detector);
            let detector = scores;
            let b = blend(&probs, &detector, weight);
            prop_assert!((b.iter().sum::<f32>() - 1.0).abs() < 1e-4);
            prop_assert!(b.iter().all(|p| (0.0..=1.0).contains(p)));
            let alone = blend(&probs, &detector, 0.0);
            for (a, p) in alone.iter().zip(&probs) {
                prop_assert!((a - p).abs() < 1e-4, "{alone:?} vs {probs:?}");
            }
        }
    }
}
