//! The detector's second stage, pure parts: cutting each box out of the
//! full-resolution frame for the tower-type classifier, and giving the boxes
//! the types it reads.
//!
//! The detector sees the frame shrunk to its input (0.4x for 512x320), where a
//! 40 px tower's arms blur together: it finds towers far better than it tells
//! their types apart. The classifier looks again at full resolution.
//! `training/train_types.py` cuts its training crops the same way.

use towernav_geometry::PixelBox;
use towernav_protocol::{Detection, TowerType};

use super::classes::ClassMap;
use super::crop_batch::Region;
use super::decode::{RawDetection, best_class, nms, runners_up};

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

/// Give each box the classifier's type (its `types_per_box` likeliest, for
/// scoring mAP as Ultralytics does). `probs` holds one row of class
/// probabilities per box, in `classes`' order. The score becomes the
/// detector's (how sure it is of a tower) times the type's probability, and
/// boxes the new types made duplicates of one another are suppressed.
pub fn retype(
    dets: &[Detection],
    probs: &[f32],
    classes: &ClassMap,
    nms_iou: f64,
    types_per_box: usize,
) -> Vec<Detection> {
    let k = classes.len();
    let raw: Vec<RawDetection> = dets
        .iter()
        .zip(probs.chunks_exact(k))
        .flat_map(|(d, p)| {
            let best = best_class(p.iter().copied());
            let ranked =
                std::iter::once(best).chain(runners_up(p.iter().copied(), best.0, types_per_box));
            ranked.filter_map(|(class, prob)| {
                Some(RawDetection {
                    bbox: d.bbox,
                    class: classes.tower_type(class)?.index(),
                    score: (d.score as f32) * prob,
                })
            })
        })
        .collect();
    nms(raw, nms_iou)
        .into_iter()
        .map(|r| Detection {
            bbox: r.bbox,
            tower_type: TowerType::ALL[r.class],
            score: f64::from(r.score),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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

    #[test]
    fn boxes_take_the_classifier_type_and_new_duplicates_go() {
        let b = PixelBox::new(100.0, 100.0, 120.0, 180.0);
        let shifted = PixelBox::new(101.0, 100.0, 121.0, 180.0);
        let dets = [
            Detection {
                bbox: b,
                tower_type: TowerType::C,
                score: 0.8,
            },
            // The detector's second guess at the same tower.
            Detection {
                bbox: shifted,
                tower_type: TowerType::D,
                score: 0.6,
            },
        ];
        let probs = [0.0, 0.9, 0.1, 0.0, 0.1, 0.7, 0.2, 0.0];
        let out = retype(&dets, &probs, &classes(), 0.5, 1);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].tower_type, TowerType::B);
        assert!((out[0].score - 0.72).abs() < 1e-6);
        assert_eq!(out[0].bbox, b);
    }

    #[test]
    fn a_box_may_carry_its_likelier_types_each_with_its_own_score() {
        let b = PixelBox::new(100.0, 100.0, 120.0, 180.0);
        let dets = [Detection {
            bbox: b,
            tower_type: TowerType::A,
            score: 0.5,
        }];
        let probs = [0.1, 0.6, 0.3, 0.0];
        let out = retype(&dets, &probs, &classes(), 0.5, 2);
        let got: Vec<(TowerType, f64)> = out.iter().map(|d| (d.tower_type, d.score)).collect();
        assert_eq!(got.len(), 2, "{got:?}");
        assert_eq!((got[0].0, got[1].0), (TowerType::B, TowerType::C));
        assert!((got[0].1 - 0.3).abs() < 1e-6 && (got[1].1 - 0.15).abs() < 1e-6);
        assert!(out.iter().all(|d| d.bbox == b));
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
    }
}
