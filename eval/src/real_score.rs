//! Scores on real labelled images, whose classes are the folder's own
//! (lattice, tubular, wooden, ...) and need not be the model's: boxes are
//! matched whatever class the model gave them (class-agnostic), overall and
//! per labelled class; typed scores are added when the model's class names
//! are the folder's. Classes marked don't-care (wooden poles for a lattice
//! detector, say) are neither hits nor false positives.

use serde::Serialize;

use crate::edge_precision::{EdgePrecision, edge_precision};
pub use crate::map_eval::ScoredImage;
use crate::map_eval::{ClassMetrics, Labelled, MapAccumulator, Scored, restrict};

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Row {
    pub class: String,
    pub labels: usize,
    pub precision: f64,
    pub recall: f64,
    pub map50: f64,
    pub map50_95: f64,
}

impl Row {
    fn new(class: &str, m: &ClassMetrics) -> Self {
        Self {
            class: class.to_string(),
            labels: m.truths,
            precision: m.precision,
            recall: m.recall,
            map50: m.ap50,
            map50_95: m.ap50_95,
        }
    }
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FolderScore {
    pub images: usize,
    /// Every scored class together, boxes matched whatever their class.
    pub any_class: Row,
    /// Per labelled class, boxes matched whatever their class; the other
    /// classes' towers are don't-care in each row.
    pub per_class: Vec<Row>,
    /// Per class with the model's class required to be the label's: only
    /// when the model's class names are the folder's.
    pub typed: Option<Vec<Row>>,
    pub dont_care: Vec<String>,
    /// The boxes' tops and bottoms against the labels', by label height.
    pub edges: EdgePrecision,
}

/// Score `images` labelled with `names`, the model's classes being
/// `model_names`; P and R are read at `at_score`.
pub fn score_folder(
    images: &[ScoredImage],
    names: &[String],
    model_names: &[String],
    dont_care: &[usize],
    at_score: f32,
) -> FolderScore {
    let agnostic = |i: &ScoredImage, keep: &dyn Fn(usize) -> bool| {
        let mask: Vec<bool> = i.labels.iter().map(|l| !keep(l.class)).collect();
        let labels: Vec<Labelled> = i
            .labels
            .iter()
            .map(|l| Labelled { class: 0, ..*l })
            .collect();
        let boxes: Vec<Scored> = i.boxes.iter().map(|b| Scored { class: 0, ..*b }).collect();
        restrict(&labels, &boxes, 0.0, &mask)
    };
    let mut any = MapAccumulator::new(1, at_score);
    for i in images {
        let (l, b) = agnostic(i, &|c| !dont_care.contains(&c));
        any.add_image(&l, &b);
    }
    let per_class = (0..names.len())
        .filter(|c| !dont_care.contains(c))
        .map(|c| {
            let mut acc = MapAccumulator::new(1, at_score);
            for i in images {
                let (l, b) = agnostic(i, &|k| k == c);
                acc.add_image(&l, &b);
            }
            Row::new(&names[c], &acc.finish().overall)
        })
        .collect();
    FolderScore {
        images: images.len(),
        any_class: Row::new("any", &any.finish().overall),
        per_class,
        typed: typed_rows(images, names, model_names, dont_care, at_score),
        dont_care: dont_care.iter().map(|&c| names[c].clone()).collect(),
        edges: edge_precision(images, dont_care, at_score),
    }
}

/// Typed scores when every model class is one of the folder's, by name.
fn typed_rows(
    images: &[ScoredImage],
    names: &[String],
    model_names: &[String],
    dont_care: &[usize],
    at_score: f32,
) -> Option<Vec<Row>> {
    let to_folder: Vec<usize> = model_names
        .iter()
        .map(|m| names.iter().position(|n| n == m))
        .collect::<Option<_>>()?;
    let mut acc = MapAccumulator::new(names.len(), at_score);
    for i in images {
        let mask: Vec<bool> = i
            .labels
            .iter()
            .map(|l| dont_care.contains(&l.class))
            .collect();
        let boxes: Vec<Scored> = i
            .boxes
            .iter()
            .filter_map(|b| {
                Some(Scored {
                    class: *to_folder.get(b.class)?,
                    ..*b
                })
            })
            .collect();
        let (l, b) = restrict(&i.labels, &boxes, 0.0, &mask);
        acc.add_image(&l, &b);
    }
    let m = acc.finish();
    Some(
        (0..names.len())
            .filter(|c| !dont_care.contains(c))
            .map(|c| Row::new(&names[c], &m.per_class[c]))
            .collect(),
    )
}

/// Tower-free frames: how many got at least one box scoring `at_score` or more.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct NegativeScore {
    pub images: usize,
    pub with_a_false_box: usize,
    pub rate: f64,
    pub at_score: f32,
    /// Which frames, by index, with their best false box's score: a person
    /// looks at these, not at the rate. The report names them instead.
    #[serde(skip)]
    pub boxed: Vec<(usize, f32)>,
}

pub fn score_negatives(boxes_per_image: &[Vec<Scored>], at_score: f32) -> NegativeScore {
    let boxed: Vec<(usize, f32)> = boxes_per_image
        .iter()
        .enumerate()
        .filter_map(|(i, b)| {
            let best = b.iter().map(|d| d.score).fold(f32::NEG_INFINITY, f32::max);
            (best >= at_score).then_some((i, best))
        })
        .collect();
    NegativeScore {
        images: boxes_per_image.len(),
        with_a_false_box: boxed.len(),
        rate: boxed.len() as f64 / boxes_per_image.len().max(1) as f64,
        at_score,
        boxed,
    }
}

#[cfg(test)]
mod tests {
    use towernav_geometry::PixelBox;

    use super::*;

    fn px(left: f64, top: f64, right: f64, bottom: f64) -> PixelBox {
        PixelBox {
            left,
            top,
            right,
            bottom,
        }
    }

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    /// Two images: a lattice tower found (as the model's class 1), a
    /// tubular one missed, a wooden pole found (don't care), one box on
    /// nothing.
    fn fixture() -> Vec<ScoredImage> {
        let lattice = px(100.0, 50.0, 200.0, 400.0);
        let tubular = px(300.0, 60.0, 360.0, 300.0);
        let wooden = px(500.0, 100.0, 520.0, 300.0);
        vec![
            ScoredImage {
                frame: (1280.0, 720.0),
                labels: vec![
                    Labelled {
                        bbox: lattice,
                        class: 0,
                    },
                    Labelled {
                        bbox: wooden,
                        class: 2,
                    },
                ],
                boxes: vec![
                    Scored {
                        bbox: px(102.0, 52.0, 198.0, 398.0),
                        class: 1,
                        score: 0.9,
                    },
                    Scored {
                        bbox: px(501.0, 100.0, 520.0, 300.0),
                        class: 0,
                        score: 0.8,
                    },
                ],
            },
            ScoredImage {
                frame: (1280.0, 720.0),
                labels: vec![Labelled {
                    bbox: tubular,
                    class: 1,
                }],
                boxes: vec![Scored {
                    bbox: px(10.0, 10.0, 60.0, 90.0),
                    class: 0,
                    score: 0.6,
                }],
            },
        ]
    }

    #[test]
    fn a_fixture_scores_its_known_answers() {
        let s = score_folder(
            &fixture(),
            &names(&["lattice", "tubular", "wooden"]),
            &names(&["A", "B"]),
            &[2],
            0.25,
        );
        assert_eq!(s.images, 2);
        // Lattice and tubular: 2 labels, 1 hit, 1 false box (the pole's box is don't care).
        assert_eq!(s.any_class.labels, 2);
        assert!((s.any_class.precision - 0.5).abs() < 1e-9, "{s:?}");
        assert!((s.any_class.recall - 0.5).abs() < 1e-9);
        // One truth of two found at the top of the ranking: AP 0.5 (101-point).
        assert!((s.any_class.map50 - 0.5).abs() < 0.01, "{:?}", s.any_class);
        let lattice = &s.per_class[0];
        assert_eq!((lattice.class.as_str(), lattice.labels), ("lattice", 1));
        assert!((lattice.recall - 1.0).abs() < 1e-9 && (lattice.map50 - 1.0).abs() < 1e-9);
        let tubular = &s.per_class[1];
        assert_eq!(tubular.recall, 0.0);
        assert_eq!(s.per_class.len(), 2);
        assert!(s.typed.is_none(), "the model's names are not the folder's");
        assert_eq!(s.dont_care, ["wooden"]);
    }

    #[test]
    fn typed_rows_need_the_model_class_to_match() {
        let s = score_folder(
            &fixture(),
            &names(&["lattice", "tubular", "wooden"]),
            &names(&["tubular", "lattice"]),
            &[2],
            0.25,
        );
        let typed = s.typed.expect("same names");
        // The lattice box came as model class 1 = "lattice": a typed hit.
        assert!((typed[0].recall - 1.0).abs() < 1e-9, "{typed:?}");
        assert_eq!(typed[1].recall, 0.0);
    }

    #[test]
    fn negatives_count_frames_with_any_box_over_the_threshold() {
        let b = |score| Scored {
            bbox: px(0.0, 0.0, 10.0, 10.0),
            class: 0,
            score,
        };
        let n = score_negatives(&[vec![], vec![b(0.2)], vec![b(0.3), b(0.9)], vec![]], 0.25);
        assert_eq!((n.images, n.with_a_false_box), (4, 1));
        assert!((n.rate - 0.25).abs() < 1e-12);
        assert_eq!(n.boxed, vec![(2, 0.9)], "the frame and its best box");
    }
}
