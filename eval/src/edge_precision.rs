//! How far a detector's box tops and bottoms stray from the labels'. Range
//! comes from a box's height, so two models with the same mAP50 can
//! localize a metre apart; and the spread measured here is what the
//! localizer's `detector.edge_sigma_share` stands for.

use serde::Serialize;

use crate::map_eval::ScoredImage;

/// The rows: labelled box heights in pixels of the image, from each bound
/// up to the next.
pub const HEIGHT_BINS_PX: [f64; 5] = [0.0, 40.0, 70.0, 120.0, 200.0];

/// The IoU at which a box is taken as the label's.
const MATCH_IOU: f64 = 0.5;

/// A label whose top or bottom is within this many pixels of the image's
/// edge is cut there: its height is not the tower's.
const CUT_PX: f64 = 2.0;

/// The fewest matched boxes a spread is given for.
const MIN_MATCHED: usize = 10;

/// One row: labels of one height range.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EdgeRow {
    pub min_px: f64,
    /// `None`: no upper bound.
    pub max_px: Option<f64>,
    /// Whole labels (not cut by the image's top or bottom) in the range.
    pub labels: usize,
    /// Of those, the ones a box scoring at least the threshold matched.
    pub matched: usize,
    /// Median of box height over label height, less one: a model that
    /// draws its boxes short puts every tower farther than it is.
    pub height_bias: Option<f64>,
    /// Robust spread (1.4826 MAD) of that ratio.
    pub height_spread: Option<f64>,
    /// Robust spread of the top's and the bottom's errors together, as a
    /// share of the label's height.
    pub edge_spread: Option<f64>,
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EdgePrecision {
    pub rows: Vec<EdgeRow>,
    /// Every whole label of 40 px or more: the row to compare with
    /// `detector.edge_sigma_share` (the localizer drops smaller boxes'
    /// weight through its small-box term).
    pub over_40px: EdgeRow,
}

/// The edge errors of `images`' boxes scoring `at_score` or more against
/// their whole labels, with `dont_care` classes left out.
pub fn edge_precision(images: &[ScoredImage], dont_care: &[usize], at_score: f32) -> EdgePrecision {
    let mut matches: Vec<Match> = Vec::new();
    let mut whole: Vec<f64> = Vec::new();
    for image in images {
        let frame_height = image.frame.1;
        for label in &image.labels {
            let l = label.bbox;
            if dont_care.contains(&label.class)
                || l.height() <= 0.0
                || l.top <= CUT_PX
                || l.bottom >= frame_height - CUT_PX
            {
                continue;
            }
            whole.push(l.height());
            let best = image
                .boxes
                .iter()
                .filter(|b| b.score >= at_score)
                .map(|b| (b.bbox.iou(&l), b.bbox))
                .filter(|(iou, _)| *iou >= MATCH_IOU)
                .max_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, b)) = best {
                matches.push(Match {
                    height: l.height(),
                    ratio: b.height() / l.height(),
                    top: (b.top - l.top) / l.height(),
                    bottom: (b.bottom - l.bottom) / l.height(),
                });
            }
        }
    }
    let rows = HEIGHT_BINS_PX
        .iter()
        .enumerate()
        .map(|(i, &min_px)| row(min_px, HEIGHT_BINS_PX.get(i + 1).copied(), &whole, &matches))
        .collect();
    EdgePrecision {
        rows,
        over_40px: row(HEIGHT_BINS_PX[1], None, &whole, &matches),
    }
}

struct Match {
    height: f64,
    ratio: f64,
    top: f64,
    bottom: f64,
}

fn row(min_px: f64, max_px: Option<f64>, whole: &[f64], matches: &[Match]) -> EdgeRow {
    let inside = |h: f64| h >= min_px && max_px.is_none_or(|m| h < m);
    let m: Vec<&Match> = matches.iter().filter(|m| inside(m.height)).collect();
    let mut ratios: Vec<f64> = m.iter().map(|m| m.ratio).collect();
    let mut edges: Vec<f64> = m.iter().flat_map(|m| [m.top, m.bottom]).collect();
    let height_bias = (m.len() >= MIN_MATCHED).then(|| median(&mut ratios) - 1.0);
    EdgeRow {
        min_px,
        max_px,
        labels: whole.iter().filter(|&&h| inside(h)).count(),
        matched: m.len(),
        height_bias,
        height_spread: robust_sigma(&mut ratios),
        // Two edges a box: ten boxes, as for the height.
        edge_spread: robust_sigma(&mut edges).filter(|_| m.len() >= MIN_MATCHED),
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// 1.4826 times the median absolute deviation: a sigma that outliers do
/// not inflate. `None` under ten values.
pub fn robust_sigma(values: &mut [f64]) -> Option<f64> {
    if values.len() < MIN_MATCHED {
        return None;
    }
    let centre = median(values);
    let mut dev: Vec<f64> = values.iter().map(|v| (v - centre).abs()).collect();
    Some(1.4826 * median(&mut dev))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map_eval::{Labelled, Scored};
    use towernav_geometry::PixelBox;

    fn label(top: f64, height: f64) -> Labelled {
        Labelled {
            bbox: PixelBox::new(100.0, top, 100.0 + height / 4.0, top + height),
            class: 0,
        }
    }

    /// A box on `l` with its top and bottom moved by the given shares of its height.
    fn boxed(l: &Labelled, top: f64, bottom: f64, score: f32) -> Scored {
        let (b, h) = (l.bbox, l.bbox.height());
        Scored {
            bbox: PixelBox::new(b.left, b.top + top * h, b.right, b.bottom + bottom * h),
            class: 0,
            score,
        }
    }

    /// 100 px towers whose boxes stop 2 % short at the top and stray ±1 %
    /// at the bottom, and 50 px ones drawn exactly; one of each cut by the
    /// frame, one of each under the score threshold.
    fn flight() -> Vec<ScoredImage> {
        (0..40)
            .map(|i| {
                let tall = label(200.0, 100.0);
                let short = label(300.0, 50.0);
                let cut = label(0.0, 150.0);
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                let score = if i == 0 { 0.1 } else { 0.9 };
                ScoredImage {
                    frame: (1280.0, 720.0),
                    boxes: vec![
                        boxed(&tall, 0.02, 0.01 * sign, score),
                        boxed(&short, 0.0, 0.0, 0.9),
                        boxed(&cut, 0.3, 0.0, 0.9),
                    ],
                    labels: vec![tall, short, cut],
                }
            })
            .collect()
    }

    #[test]
    fn short_boxes_show_as_a_bias_and_stray_edges_as_a_spread() {
        let e = edge_precision(&flight(), &[], 0.25);
        let tall = &e.rows[2];
        assert_eq!((tall.min_px, tall.max_px), (70.0, Some(120.0)));
        assert_eq!(
            (tall.labels, tall.matched),
            (40, 39),
            "one box under the threshold"
        );
        // Height 0.98 ± 0.01 of the label's: a 2-3 % short box.
        let bias = tall.height_bias.expect("39 boxes");
        assert!((bias + 0.02).abs() < 0.011, "{tall:?}");
        let short = &e.rows[1];
        assert_eq!((short.labels, short.matched), (40, 40));
        assert!(short.height_bias.expect("40 boxes").abs() < 1e-9);
        assert!(short.edge_spread.expect("40 boxes").abs() < 1e-9);
        // Tops 2 % off and bottoms ±1 %: the pooled edges spread by over 1 %.
        assert!(tall.edge_spread.expect("39 boxes") > 0.01, "{tall:?}");
        assert_eq!(e.over_40px.labels, 80, "the cut towers are not counted");
        assert_eq!(e.rows[0].labels + e.rows[3].labels + e.rows[4].labels, 0);
        assert_eq!(e.rows[4].height_bias, None);
        let few = edge_precision(&flight()[..9], &[], 0.25);
        assert_eq!(few.rows[1].edge_spread, None, "18 edges but 9 boxes");
    }

    #[test]
    fn dont_care_labels_are_left_out() {
        let mut images = flight();
        for image in &mut images {
            image.labels[1].class = 2;
        }
        let e = edge_precision(&images, &[2], 0.25);
        assert_eq!(e.rows[1].labels, 0);
        assert_eq!(e.over_40px.labels, 40);
    }

    #[test]
    fn the_robust_sigma_ignores_a_few_outliers() {
        // 0 to 100: median 50, median absolute deviation 25.
        let mut v: Vec<f64> = (0..=100).map(f64::from).collect();
        v[99] = 1e9;
        v[100] = 1e9;
        let s = robust_sigma(&mut v).expect("101 values");
        assert!((s - 1.4826 * 25.0).abs() < 1e-9, "{s}");
        assert_eq!(robust_sigma(&mut [1.0; 9]), None);
    }
}
