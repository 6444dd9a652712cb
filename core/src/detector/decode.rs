//! Decoding Ultralytics YOLO outputs: YOLOv5 `[1, N, 5 + C]` (box, objectness,
//! class scores) and YOLOv8/11 `[1, 4 + C, N]` (box, class scores), told apart
//! by shape; then class-aware non-maximum suppression. Boxes are centre-size in
//! model-input pixels.

use towernav_geometry::PixelBox;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// `[1, N, 5 + C]`.
    V5,
    /// `[1, 4 + C, N]`.
    V8,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LayoutError {
    #[error(
        "output shape {shape:?} fits neither YOLOv5 [1, N, 5 + {classes}] nor YOLOv8 [1, 4 + {classes}, N] for {classes} classes"
    )]
    Unknown { shape: Vec<usize>, classes: usize },
}

/// Which layout an output of `shape` has for `classes` classes.
pub fn layout(shape: &[usize], classes: usize) -> Result<Layout, LayoutError> {
    match shape {
        [1, a, b] if *b == 5 + classes && *a != 4 + classes => Ok(Layout::V5),
        [1, a, _] if *a == 4 + classes => Ok(Layout::V8),
        _ => Err(LayoutError::Unknown {
            shape: shape.to_vec(),
            classes,
        }),
    }
}

/// Most classes a tower detector may have (`ClassMap` refuses more at load).
pub const MAX_CLASSES: usize = 16;

/// A candidate's score for every class, in model order; classes past the
/// model's stay at zero.
pub type ClassScores = [f32; MAX_CLASSES];

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawDetection {
    pub bbox: PixelBox,
    pub class: usize,
    pub score: f32,
    /// What the detector gave each type (YOLOv5: before objectness), so a
    /// second stage can weigh its own reading of the type against it.
    pub class_scores: ClassScores,
}

fn class_scores(scores: impl Iterator<Item = f32>) -> ClassScores {
    let mut out = ClassScores::default();
    for (slot, s) in out.iter_mut().zip(scores) {
        *slot = s;
    }
    out
}

/// What a candidate's score measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScoreMode {
    /// The best class's score: how sure the model is of that tower type.
    #[default]
    BestClass,
    /// The class scores summed (at most 1): how sure it is of a tower at all,
    /// whatever the type. For a second stage that names the type itself: a
    /// tower the detector splits between two look-alike types still ranks high.
    AnyType,
}

impl ScoreMode {
    fn pick(self, scores: impl Iterator<Item = f32>) -> (usize, f32) {
        match self {
            Self::BestClass => best_class(scores),
            Self::AnyType => {
                let (mut sum, mut best) = (0.0, (0, f32::NEG_INFINITY));
                for (i, s) in scores.enumerate() {
                    sum += s.max(0.0);
                    if s > best.1 {
                        best = (i, s);
                    }
                }
                (best.0, sum.min(1.0))
            }
        }
    }
}

/// Candidates above `min_score` from a raw output (row-major `data` of `shape`).
/// In `BestClass` mode each box may come back under up to `types_per_box`
/// classes, best first (Ultralytics' `multi_label` when it is every class).
pub fn decode(
    data: &[f32],
    shape: &[usize],
    classes: usize,
    min_score: f32,
    mode: ScoreMode,
    types_per_box: usize,
) -> Result<Vec<RawDetection>, LayoutError> {
    let kind = layout(shape, classes)?;
    // Runner-up types only where the score is one type's.
    let more = if mode == ScoreMode::BestClass {
        types_per_box
    } else {
        1
    };
    let mut out = Vec::new();
    let cxcywh = |cx: f32, cy: f32, w: f32, h: f32| {
        PixelBox::new(
            f64::from(cx - w / 2.0),
            f64::from(cy - h / 2.0),
            f64::from(cx + w / 2.0),
            f64::from(cy + h / 2.0),
        )
    };
    match kind {
        Layout::V5 => {
            let stride = 5 + classes;
            for row in data.chunks_exact(stride) {
                let objectness = row[4];
                if objectness < min_score {
                    continue;
                }
                let bbox = cxcywh(row[0], row[1], row[2], row[3]);
                let scores = || row[5..].iter().copied();
                let (class, best) = mode.pick(scores());
                let picks = std::iter::once((class, best)).chain(runners_up(scores(), class, more));
                let class_scores = class_scores(scores());
                for (class, p) in picks {
                    let score = objectness * p;
                    if score >= min_score {
                        out.push(RawDetection {
                            bbox,
                            class,
                            score,
                            class_scores,
                        });
                    }
                }
            }
        }
        Layout::V8 => {
            let n = shape[2];
            let at = |r: usize, i: usize| data[r * n + i];
            for i in 0..n {
                let scores = || (0..classes).map(|c| at(4 + c, i));
                let (class, best) = mode.pick(scores());
                if best < min_score {
                    continue;
                }
                let bbox = cxcywh(at(0, i), at(1, i), at(2, i), at(3, i));
                let picks = std::iter::once((class, best)).chain(runners_up(scores(), class, more));
                let class_scores = class_scores(scores());
                for (class, score) in picks.filter(|(_, p)| *p >= min_score) {
                    out.push(RawDetection {
                        bbox,
                        class,
                        score,
                        class_scores,
                    });
                }
            }
        }
    }
    Ok(out)
}

/// The classes after `best`, best first, up to `types_per_box` in all. Empty,
/// and allocation-free, for the pipeline's one type per box. In `AnyType` mode
/// callers ask for one: the score is the tower's, not one class's.
pub(super) fn runners_up(
    scores: impl Iterator<Item = f32>,
    best: usize,
    types_per_box: usize,
) -> Vec<(usize, f32)> {
    if types_per_box < 2 {
        return Vec::new();
    }
    let mut rest: Vec<(usize, f32)> = scores.enumerate().filter(|(c, _)| *c != best).collect();
    rest.sort_by(|a, b| b.1.total_cmp(&a.1));
    rest.truncate(types_per_box - 1);
    rest
}

pub(super) fn best_class(scores: impl Iterator<Item = f32>) -> (usize, f32) {
    scores
        .enumerate()
        .fold((0, f32::NEG_INFINITY), |best, (i, s)| {
            if s > best.1 { (i, s) } else { best }
        })
}

/// Class-aware NMS: within a class, keep the best box and drop any other that
/// overlaps it by more than `iou_max`; highest scores first.
pub fn nms(dets: Vec<RawDetection>, iou_max: f64) -> Vec<RawDetection> {
    suppress(dets, iou_max, |a, b| a.class == b.class)
}

/// NMS across classes: one box per tower, for a second stage that names the
/// type itself (and would otherwise classify the same tower twice).
pub fn nms_any_class(dets: Vec<RawDetection>, iou_max: f64) -> Vec<RawDetection> {
    suppress(dets, iou_max, |_, _| true)
}

fn suppress(
    mut dets: Vec<RawDetection>,
    iou_max: f64,
    compete: impl Fn(&RawDetection, &RawDetection) -> bool,
) -> Vec<RawDetection> {
    dets.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<RawDetection> = Vec::with_capacity(dets.len());
    for d in dets {
        if kept
            .iter()
            .all(|k| !compete(k, &d) || k.bbox.iou(&d.bbox) <= iou_max)
        {
            kept.push(d);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn v5_output_decodes_with_objectness_times_class_score() {
        // Two candidates, 4 classes: [cx, cy, w, h, obj, c0..c3].
        let data = [
            100.0, 200.0, 20.0, 80.0, 0.9, 0.1, 0.8, 0.05, 0.05, //
            300.0, 200.0, 20.0, 80.0, 0.2, 0.9, 0.0, 0.0, 0.0,
        ];
        let dets = decode(&data, &[1, 2, 9], 4, 0.25, ScoreMode::BestClass, 1).expect("v5");
        assert_eq!(dets.len(), 1, "0.2 x 0.9 is under the threshold");
        assert_eq!(dets[0].class, 1);
        assert!((dets[0].score - 0.72).abs() < 1e-6);
        assert_eq!(dets[0].bbox, PixelBox::new(90.0, 160.0, 110.0, 240.0));
        assert_eq!(dets[0].class_scores[..4], [0.1, 0.8, 0.05, 0.05]);
        assert!(dets[0].class_scores[4..].iter().all(|s| *s == 0.0));
    }

    #[test]
    fn v8_output_is_channel_major_without_objectness() {
        // 3 candidates, 4 classes: rows cx, cy, w, h, c0..c3.
        let data = [
            100.0, 300.0, 500.0, // cx
            200.0, 200.0, 200.0, // cy
            20.0, 20.0, 20.0, // w
            80.0, 80.0, 80.0, // h
            0.1, 0.0, 0.0, // A
            0.0, 0.0, 0.7, // B
            0.9, 0.1, 0.0, // C
            0.0, 0.2, 0.0, // D
        ];
        let dets = decode(&data, &[1, 8, 3], 4, 0.25, ScoreMode::BestClass, 1).expect("v8");
        assert_eq!(dets.iter().map(|d| d.class).collect::<Vec<_>>(), [2, 1]);
        assert_eq!(dets[1].bbox.center_x(), 500.0);
    }

    #[test]
    fn a_box_comes_back_under_its_runner_up_types_when_asked() {
        // v5, one candidate: obj 0.9, classes 0.1 / 0.6 / 0.3 / 0.0.
        let data = [100.0, 200.0, 20.0, 80.0, 0.9, 0.1, 0.6, 0.3, 0.0];
        let classes_of = |k: usize| -> Vec<usize> {
            decode(&data, &[1, 1, 9], 4, 0.05, ScoreMode::BestClass, k)
                .expect("v5")
                .iter()
                .map(|d| d.class)
                .collect()
        };
        assert_eq!(classes_of(1), [1]);
        assert_eq!(classes_of(2), [1, 2]);
        // A is 0.09, D is 0: only those above the threshold.
        assert_eq!(classes_of(4), [1, 2, 0]);
        // In any-type mode the score is the tower's, not a type's: one box.
        let any = decode(&data, &[1, 1, 9], 4, 0.05, ScoreMode::AnyType, 4).expect("v5");
        assert_eq!(any.len(), 1);
    }

    #[test]
    fn any_type_scores_a_tower_split_between_types_by_the_sum() {
        // One candidate the model splits between C (0.2) and D (0.15).
        let data = [
            100.0, 200.0, 20.0, 80.0, // box
            0.0, 0.0, 0.2, 0.15, // A..D
        ];
        assert!(
            decode(&data, &[1, 8, 1], 4, 0.25, ScoreMode::BestClass, 1)
                .expect("v8")
                .is_empty(),
            "no one type reaches 0.25"
        );
        let dets = decode(&data, &[1, 8, 1], 4, 0.25, ScoreMode::AnyType, 1).expect("v8");
        assert_eq!(dets.len(), 1);
        assert_eq!(dets[0].class, 2);
        assert!((dets[0].score - 0.35).abs() < 1e-6);
    }

    #[test]
    fn unknown_layouts_are_refused_with_the_shape() {
        let err = layout(&[1, 84, 8400], 4)
            .expect_err("80-class COCO model")
            .to_string();
        assert!(
            err.contains("[1, 84, 8400]") && err.contains("4 classes"),
            "{err}"
        );
        assert_eq!(layout(&[1, 25200, 9], 4), Ok(Layout::V5));
        assert_eq!(layout(&[1, 8, 8400], 4), Ok(Layout::V8));
    }

    #[test]
    fn nms_is_per_class() {
        let d = |x: f64, class: usize, score: f32| RawDetection {
            bbox: PixelBox::new(x, 0.0, x + 20.0, 80.0),
            class,
            score,
            class_scores: ClassScores::default(),
        };
        let kept = nms(
            vec![
                d(0.0, 0, 0.9),
                d(2.0, 0, 0.8),
                d(2.0, 1, 0.7),
                d(100.0, 0, 0.6),
            ],
            0.5,
        );
        assert_eq!(
            kept.len(),
            3,
            "the overlapping same-class box goes, the other class stays"
        );
        let any = nms_any_class(vec![d(0.0, 0, 0.9), d(2.0, 1, 0.7), d(100.0, 0, 0.6)], 0.5);
        assert_eq!(any.len(), 2, "across classes, the overlapping box goes too");
        assert!(kept.iter().all(|k| k.score != 0.8));
    }
}
