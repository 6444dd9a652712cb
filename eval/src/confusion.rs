//! Which tower type the detector called each labelled tower: tells a model
//! that finds towers but confuses their types (a resolution or training
//! problem) from one that misses them.

use crate::map_eval::{Labelled, Scored};

/// Rows: the labelled class, then one row for detections that matched no
/// tower. Columns: the detected class, then one column for towers missed.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfusionMatrix {
    classes: usize,
    min_score: f32,
    min_iou: f64,
    counts: Vec<Vec<usize>>,
}

impl ConfusionMatrix {
    /// Detections below `min_score` are ignored; a detection explains a
    /// labelled tower when their IoU is at least `min_iou`, whatever its class.
    pub fn new(classes: usize, min_score: f32, min_iou: f64) -> Self {
        Self {
            classes,
            min_score,
            min_iou,
            counts: vec![vec![0; classes + 1]; classes + 1],
        }
    }

    /// One image. Each labelled tower takes the highest-scoring free detection
    /// over it; what no tower took is a false positive (the background row).
    pub fn add_image(&mut self, truth: &[Labelled], dets: &[Scored]) {
        let mut dets: Vec<&Scored> = dets
            .iter()
            .filter(|d| d.score >= self.min_score && d.class < self.classes)
            .collect();
        dets.sort_by(|a, b| b.score.total_cmp(&a.score));
        let mut taken = vec![false; dets.len()];
        for t in truth.iter().filter(|t| t.class < self.classes) {
            let hit = dets
                .iter()
                .enumerate()
                .find(|(i, d)| !taken[*i] && d.bbox.iou(&t.bbox) >= self.min_iou);
            let column = match hit {
                Some((i, d)) => {
                    taken[i] = true;
                    d.class
                }
                None => self.classes,
            };
            self.counts[t.class][column] += 1;
        }
        for (d, _) in dets.iter().zip(&taken).filter(|(_, t)| !**t) {
            self.counts[self.classes][d.class] += 1;
        }
    }

    /// Count of towers labelled `truth` (or `None`: background) detected as
    /// `detected` (or `None`: missed).
    pub fn count(&self, truth: Option<usize>, detected: Option<usize>) -> usize {
        let row = truth.unwrap_or(self.classes);
        let column = detected.unwrap_or(self.classes);
        self.counts
            .get(row)
            .and_then(|r| r.get(column))
            .copied()
            .unwrap_or(0)
    }

    /// Share of the towers that were found at all whose type was right.
    pub fn type_accuracy_of_found(&self) -> f64 {
        let (mut right, mut found) = (0, 0);
        for (c, row) in self.counts.iter().take(self.classes).enumerate() {
            right += row[c];
            found += row[..self.classes].iter().sum::<usize>();
        }
        if found == 0 {
            0.0
        } else {
            right as f64 / found as f64
        }
    }

    pub fn rows(&self) -> &[Vec<usize>] {
        &self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_geometry::PixelBox;

    fn b(x: f64) -> PixelBox {
        PixelBox::new(x, 100.0, x + 20.0, 180.0)
    }

    #[test]
    fn right_wrong_missed_and_spurious_boxes_land_in_their_cells() {
        let mut m = ConfusionMatrix::new(2, 0.25, 0.5);
        let truth = [
            Labelled {
                bbox: b(0.0),
                class: 0,
            },
            Labelled {
                bbox: b(100.0),
                class: 1,
            },
            Labelled {
                bbox: b(200.0),
                class: 1,
            },
        ];
        let dets = [
            Scored {
                bbox: b(0.0),
                class: 0,
                score: 0.9,
            },
            Scored {
                bbox: b(101.0),
                class: 0,
                score: 0.8,
            },
            Scored {
                bbox: b(400.0),
                class: 1,
                score: 0.7,
            },
            Scored {
                bbox: b(200.0),
                class: 1,
                score: 0.1,
            },
        ];
        m.add_image(&truth, &dets);
        assert_eq!(m.count(Some(0), Some(0)), 1);
        assert_eq!(m.count(Some(1), Some(0)), 1, "a B called A");
        assert_eq!(
            m.count(Some(1), None),
            1,
            "the only box on it scored under 0.25"
        );
        assert_eq!(m.count(None, Some(1)), 1, "the box over nothing");
        assert!((m.type_accuracy_of_found() - 0.5).abs() < 1e-12);
    }
}
