//! Detection accuracy as the paper's Table 1 reports it: precision, recall,
//! mAP50 and mAP50-95 per class and overall (COCO-style 101-point
//! interpolation), plus recall by box-height band.

use towernav_geometry::PixelBox;

/// Box-height bands for the recall breakdown, pixels: < 40, 40-100, 100-300, > 300.
pub const HEIGHT_BANDS: [(f64, f64); 4] = [
    (0.0, 40.0),
    (40.0, 100.0),
    (100.0, 300.0),
    (300.0, f64::INFINITY),
];

/// One image: its labels (folder classes) and the model's boxes (model classes).
#[derive(Debug, Clone, Default)]
pub struct ScoredImage {
    /// The image's width and height, pixels: a label at its edge is cut there.
    pub frame: (f64, f64),
    pub labels: Vec<Labelled>,
    pub boxes: Vec<Scored>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Labelled {
    pub bbox: PixelBox,
    pub class: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    pub bbox: PixelBox,
    pub class: usize,
    pub score: f32,
}

#[derive(Debug, Clone, Default)]
pub struct MapAccumulator {
    classes: usize,
    /// Per class: (score, true-positive flags at IoU 0.50, 0.55, ... 0.95).
    detections: Vec<Vec<(f32, [bool; 10])>>,
    truths: Vec<usize>,
    /// Per height band: (found at IoU 0.5 by a detection over `recall_score`, total).
    bands: [(usize, usize); 4],
    recall_score: f32,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct ClassMetrics {
    pub truths: usize,
    pub precision: f64,
    pub recall: f64,
    pub ap50: f64,
    pub ap50_95: f64,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct MapMetrics {
    pub per_class: Vec<ClassMetrics>,
    pub overall: ClassMetrics,
    /// Recall per `HEIGHT_BANDS` entry, with its number of truths.
    pub recall_by_height: [(f64, usize); 4],
}

impl MapAccumulator {
    /// `recall_score`: the confidence at which precision, recall and the bands are read.
    pub fn new(classes: usize, recall_score: f32) -> Self {
        Self {
            classes,
            detections: vec![Vec::new(); classes],
            truths: vec![0; classes],
            bands: [(0, 0); 4],
            recall_score,
        }
    }

    /// One image: its labels and the detector's boxes.
    pub fn add_image(&mut self, truth: &[Labelled], dets: &[Scored]) {
        for t in truth.iter().filter(|t| t.class < self.classes) {
            self.truths[t.class] += 1;
        }
        for class in 0..self.classes {
            let gts: Vec<&Labelled> = truth.iter().filter(|t| t.class == class).collect();
            let mut ds: Vec<&Scored> = dets.iter().filter(|d| d.class == class).collect();
            ds.sort_by(|a, b| b.score.total_cmp(&a.score));
            let mut taken = vec![[false; 10]; gts.len()];
            for d in ds {
                let mut flags = [false; 10];
                for (k, flag) in flags.iter_mut().enumerate() {
                    let thr = 0.5 + 0.05 * k as f64;
                    // Greedy, highest score first: the best free truth above the threshold.
                    let best = gts
                        .iter()
                        .enumerate()
                        .filter(|(g, _)| !taken[*g][k])
                        .map(|(g, t)| (g, t.bbox.iou(&d.bbox)))
                        .filter(|(_, iou)| *iou >= thr)
                        .max_by(|a, b| a.1.total_cmp(&b.1));
                    if let Some((g, _)) = best {
                        taken[g][k] = true;
                        *flag = true;
                    }
                }
                self.detections[class].push((d.score, flags));
            }
        }
        for t in truth {
            let h = t.bbox.height();
            let Some(band) = HEIGHT_BANDS.iter().position(|(lo, hi)| h >= *lo && h < *hi) else {
                continue;
            };
            let found = dets.iter().any(|d| {
                d.class == t.class && d.score >= self.recall_score && d.bbox.iou(&t.bbox) >= 0.5
            });
            self.bands[band].1 += 1;
            self.bands[band].0 += usize::from(found);
        }
    }

    pub fn finish(&self) -> MapMetrics {
        let per_class: Vec<ClassMetrics> = (0..self.classes)
            .map(|c| class_metrics(&self.detections[c], self.truths[c], self.recall_score))
            .collect();
        let with_truth: Vec<&ClassMetrics> = per_class.iter().filter(|m| m.truths > 0).collect();
        let mean = |f: fn(&ClassMetrics) -> f64| {
            if with_truth.is_empty() {
                0.0
            } else {
                with_truth.iter().map(|m| f(m)).sum::<f64>() / with_truth.len() as f64
            }
        };
        let overall = ClassMetrics {
            truths: self.truths.iter().sum(),
            precision: mean(|m| m.precision),
            recall: mean(|m| m.recall),
            ap50: mean(|m| m.ap50),
            ap50_95: mean(|m| m.ap50_95),
        };
        let recall_by_height = self.bands.map(|(found, total)| {
            (
                if total == 0 {
                    0.0
                } else {
                    found as f64 / total as f64
                },
                total,
            )
        });
        MapMetrics {
            per_class,
            overall,
            recall_by_height,
        }
    }
}

/// One image restricted to towers at least `min_height` pixels tall, COCO's
/// way for area ranges: smaller truths leave, and so do detections that match
/// one of them (IoU 0.5) or are themselves smaller, so a correct box on a small
/// tower is neither a hit nor a false positive.
pub fn restrict_to_height(
    truth: &[Labelled],
    dets: &[Scored],
    min_height: f64,
) -> (Vec<Labelled>, Vec<Scored>) {
    restrict(truth, dets, min_height, &[])
}

/// As `restrict_to_height`, and the truths flagged in `dont_care` (KITTI's
/// "don't care": towers cut by the frame's edge or mostly hidden) leave the
/// same way: finding one is neither a hit nor a false positive. A shorter
/// `dont_care` leaves the rest cared for.
pub fn restrict(
    truth: &[Labelled],
    dets: &[Scored],
    min_height: f64,
    dont_care: &[bool],
) -> (Vec<Labelled>, Vec<Scored>) {
    let cared = |(i, t): &(usize, &Labelled)| {
        t.bbox.height() >= min_height && !dont_care.get(*i).copied().unwrap_or(false)
    };
    let (kept, left): (Vec<_>, Vec<_>) = truth.iter().enumerate().partition(cared);
    let dets = dets
        .iter()
        .filter(|d| {
            d.bbox.height() >= min_height
                && !left
                    .iter()
                    .any(|(_, s)| s.class == d.class && s.bbox.iou(&d.bbox) >= 0.5)
        })
        .copied()
        .collect();
    (kept.into_iter().map(|(_, t)| *t).collect(), dets)
}

fn class_metrics(dets: &[(f32, [bool; 10])], truths: usize, at_score: f32) -> ClassMetrics {
    let mut sorted: Vec<&(f32, [bool; 10])> = dets.iter().collect();
    sorted.sort_by(|a, b| b.0.total_cmp(&a.0));
    let ap = |k: usize| average_precision(sorted.iter().map(|d| d.1[k]), truths);
    let above: Vec<_> = sorted.iter().filter(|d| d.0 >= at_score).collect();
    let tp = above.iter().filter(|d| d.1[0]).count();
    ClassMetrics {
        truths,
        precision: if above.is_empty() {
            0.0
        } else {
            tp as f64 / above.len() as f64
        },
        recall: if truths == 0 {
            0.0
        } else {
            tp as f64 / truths as f64
        },
        ap50: ap(0),
        ap50_95: (0..10).map(ap).sum::<f64>() / 10.0,
    }
}

/// Area under the precision-recall curve, COCO's 101 recall points, precision
/// made monotone from the right.
fn average_precision(hits: impl Iterator<Item = bool>, truths: usize) -> f64 {
    if truths == 0 {
        return 0.0;
    }
    let (mut tp, mut n) = (0usize, 0usize);
    let mut curve: Vec<(f64, f64)> = Vec::new();
    for hit in hits {
        n += 1;
        tp += usize::from(hit);
        curve.push((tp as f64 / truths as f64, tp as f64 / n as f64));
    }
    for i in (0..curve.len().saturating_sub(1)).rev() {
        curve[i].1 = curve[i].1.max(curve[i + 1].1);
    }
    (0..=100)
        .map(|r| {
            let r = f64::from(r) / 100.0;
            curve
                .iter()
                .find(|(rec, _)| *rec >= r)
                .map_or(0.0, |(_, p)| *p)
        })
        .sum::<f64>()
        / 101.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x: f64, h: f64) -> PixelBox {
        PixelBox::new(x, 100.0, x + 20.0, 100.0 + h)
    }

    #[test]
    fn perfect_detections_score_one_and_misses_show_in_their_band() {
        let mut acc = MapAccumulator::new(2, 0.25);
        acc.add_image(
            &[
                Labelled {
                    bbox: b(0.0, 50.0),
                    class: 0,
                },
                Labelled {
                    bbox: b(100.0, 350.0),
                    class: 1,
                },
                Labelled {
                    bbox: b(200.0, 20.0),
                    class: 1,
                },
            ],
            &[
                Scored {
                    bbox: b(0.0, 50.0),
                    class: 0,
                    score: 0.9,
                },
                Scored {
                    bbox: b(100.0, 350.0),
                    class: 1,
                    score: 0.8,
                },
            ],
        );
        let m = acc.finish();
        assert_eq!(m.per_class[0].ap50, 1.0);
        assert_eq!(m.per_class[0].ap50_95, 1.0);
        assert!((m.per_class[1].recall - 0.5).abs() < 1e-12);
        assert_eq!(
            m.recall_by_height[0],
            (0.0, 1),
            "the 20 px tower was missed"
        );
        assert_eq!(m.recall_by_height[1], (1.0, 1));
        assert_eq!(m.recall_by_height[3], (1.0, 1));
    }

    #[test]
    fn restricting_to_tall_towers_drops_small_truths_and_their_boxes_only() {
        let truth = [
            Labelled {
                bbox: b(0.0, 30.0),
                class: 0,
            },
            Labelled {
                bbox: b(100.0, 80.0),
                class: 0,
            },
        ];
        let dets = [
            Scored {
                bbox: b(0.0, 30.0),
                class: 0,
                score: 0.9,
            },
            Scored {
                bbox: b(100.0, 80.0),
                class: 0,
                score: 0.8,
            },
            Scored {
                bbox: b(300.0, 60.0),
                class: 0,
                score: 0.7,
            },
        ];
        let (t, d) = restrict_to_height(&truth, &dets, 40.0);
        assert_eq!(t.len(), 1);
        assert_eq!(
            d.iter().map(|d| d.score).collect::<Vec<_>>(),
            [0.8, 0.7],
            "the small tower's box leaves; the tall false positive stays"
        );
    }

    #[test]
    fn a_dont_care_tower_is_neither_hit_nor_miss() {
        let truth = [
            Labelled {
                bbox: b(0.0, 100.0),
                class: 0,
            },
            Labelled {
                bbox: b(200.0, 100.0),
                class: 0,
            },
        ];
        let dets = [
            Scored {
                bbox: b(200.0, 100.0),
                class: 0,
                score: 0.9,
            },
            Scored {
                bbox: b(400.0, 100.0),
                class: 0,
                score: 0.8,
            },
        ];
        let (t, d) = restrict(&truth, &dets, 40.0, &[false, true]);
        assert_eq!(t.len(), 1, "the hidden tower leaves");
        assert_eq!(t[0].bbox, truth[0].bbox);
        assert_eq!(
            d.iter().map(|d| d.score).collect::<Vec<_>>(),
            [0.8],
            "its box leaves with it; the false positive stays"
        );
        let (t, d) = restrict(&truth, &dets, 40.0, &[]);
        assert_eq!(
            (t.len(), d.len()),
            (2, 2),
            "nothing flagged, nothing leaves"
        );
    }

    #[test]
    fn a_false_positive_ranked_first_lowers_ap_and_precision() {
        let mut acc = MapAccumulator::new(1, 0.1);
        acc.add_image(
            &[Labelled {
                bbox: b(0.0, 100.0),
                class: 0,
            }],
            &[
                Scored {
                    bbox: b(500.0, 100.0),
                    class: 0,
                    score: 0.95,
                },
                Scored {
                    bbox: b(0.0, 100.0),
                    class: 0,
                    score: 0.9,
                },
            ],
        );
        let m = acc.finish();
        assert!((m.per_class[0].precision - 0.5).abs() < 1e-12);
        assert!(
            (m.per_class[0].ap50 - 0.5).abs() < 1e-9,
            "{}",
            m.per_class[0].ap50
        );
        // A box shifted so IoU is ~0.6 counts at 0.5 but not at 0.95.
        let mut acc = MapAccumulator::new(1, 0.1);
        acc.add_image(
            &[Labelled {
                bbox: b(0.0, 100.0),
                class: 0,
            }],
            &[Scored {
                bbox: b(5.0, 100.0),
                class: 0,
                score: 0.9,
            }],
        );
        let m = acc.finish();
        assert_eq!(m.per_class[0].ap50, 1.0);
        assert!(m.per_class[0].ap50_95 < 1.0);
    }
}
