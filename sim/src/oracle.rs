//! A noisy stand-in for the detector, drawn from one seeded generator: true
//! boxes with edge noise that grows as towers shrink, misses that grow with
//! occlusion and smallness, false positives on distractors and at random,
//! and occasional type confusion.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use towernav_geometry::PixelBox;
use towernav_protocol::{Detection, TowerType};

use crate::truth::FrameTruth;

/// The oracle's knobs, each a way a real detector errs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OracleParams {
    /// Standard deviation of each box edge for a large box, pixels.
    pub edge_sigma_px: f64,
    /// Edge noise grows for small boxes: sigma = edge_sigma_px * (1 + small_box_px / h).
    pub small_box_px: f64,
    /// Chance that a clear, large tower is not reported in a frame.
    pub miss_probability: f64,
    /// Extra miss chance per unit of occluded share (0..1 of the box hidden).
    pub occlusion_miss: f64,
    /// Boxes shorter than this are never reported; up to twice this the miss
    /// chance ramps from 1 down to `miss_probability`.
    pub min_height_px: f64,
    /// Towers farther than this are never reported: the detector range the
    /// oracle's replays and targets were set with.
    pub max_range_m: f64,
    /// Chance per frame of one false box anywhere (clutter, sky, ground).
    pub false_positive_rate: f64,
    /// Chance per frame and distractor in view (pole, tree, building) that it is taken for a tower.
    pub distractor_false_positive: f64,
    /// Chance that a reported tower gets a wrong type.
    pub type_confusion: f64,
}

impl Default for OracleParams {
    fn default() -> Self {
        Self {
            edge_sigma_px: 1.0,
            small_box_px: 40.0,
            miss_probability: 0.03,
            occlusion_miss: 0.5,
            min_height_px: 12.0,
            max_range_m: 900.0,
            false_positive_rate: 0.02,
            distractor_false_positive: 0.01,
            type_confusion: 0.01,
        }
    }
}

impl OracleParams {
    /// The walking skeleton's oracle: constant edge noise, uniform misses, no
    /// distractor false positives or type confusion. Kept so its replays stay comparable.
    pub fn skeleton() -> Self {
        Self {
            small_box_px: 0.0,
            occlusion_miss: 0.0,
            distractor_false_positive: 0.0,
            type_confusion: 0.0,
            ..Self::default()
        }
    }

    fn miss_chance(&self, height_px: f64, occluded: f64) -> f64 {
        let min = self.min_height_px.max(0.0);
        let ramp = if min > 0.0 && height_px < 2.0 * min {
            (2.0 * min - height_px) / min
        } else {
            0.0
        };
        probability(self.miss_probability + ramp + self.occlusion_miss * occluded)
    }
}

pub struct OracleDetector {
    params: OracleParams,
    rng: ChaCha8Rng,
}

impl OracleDetector {
    pub fn new(params: OracleParams, seed: u64) -> Self {
        Self {
            params,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    pub fn detect(&mut self, truth: &FrameTruth, width: f64, height: f64) -> Vec<Detection> {
        let p = self.params;
        let mut out = Vec::with_capacity(truth.boxes.len() + 1);
        for b in &truth.boxes {
            let h = b.bbox.height();
            if h < p.min_height_px
                || b.distance_m > p.max_range_m
                || self.rng.random_bool(p.miss_chance(h, b.occluded))
            {
                continue;
            }
            let sigma = p.edge_sigma_px.max(0.0) * (1.0 + p.small_box_px.max(0.0) / h.max(1.0));
            let mut jitter = || sigma * self.rng.sample::<f64, _>(StandardNormal);
            let bbox = PixelBox::new(
                b.bbox.left + jitter(),
                b.bbox.top + jitter(),
                b.bbox.right + jitter(),
                b.bbox.bottom + jitter(),
            )
            .clipped(width, height);
            // Confusion swaps among the rendered designs; other types stay as surveyed.
            let tower_type = match b.tower_type.rendered_index() {
                Some(i)
                    if p.type_confusion > 0.0
                        && self.rng.random_bool(probability(p.type_confusion)) =>
                {
                    TowerType::ALL[(i + self.rng.random_range(1..4)) % 4]
                }
                _ => b.tower_type,
            };
            out.push(Detection {
                bbox,
                tower_type,
                score: self.rng.random_range(0.6..0.98),
            });
        }
        if p.distractor_false_positive > 0.0 {
            for d in &truth.distractors {
                if self
                    .rng
                    .random_bool(probability(p.distractor_false_positive))
                {
                    out.push(Detection {
                        bbox: *d,
                        tower_type: TowerType::ALL[self.rng.random_range(0..4)],
                        score: self.rng.random_range(0.3..0.6),
                    });
                }
            }
        }
        if self.rng.random_bool(probability(p.false_positive_rate)) {
            let h = self.rng.random_range(15.0..120.0);
            let w = h * self.rng.random_range(0.15..0.4);
            let x = self.rng.random_range(0.0..(width - w).max(1.0));
            let y = self.rng.random_range(0.0..(height - h).max(1.0));
            let t = TowerType::ALL[self.rng.random_range(0..4)];
            out.push(Detection {
                bbox: PixelBox::new(x, y, x + w, y + h),
                tower_type: t,
                score: self.rng.random_range(0.3..0.7),
            });
        }
        out
    }
}

/// A rate as a probability `random_bool` accepts: clamped to 0..=1, NaN as 0.
fn probability(p: f64) -> f64 {
    if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn same_seed_same_detections() {
        let scenario = Scenario::paper(1);
        let truth = scenario.truth(100);
        let mut a = OracleDetector::new(OracleParams::default(), 7);
        let mut b = OracleDetector::new(OracleParams::default(), 7);
        assert_eq!(
            a.detect(&truth, 1280.0, 720.0),
            b.detect(&truth, 1280.0, 720.0)
        );
    }

    #[test]
    fn out_of_range_rates_do_not_panic() {
        let truth = Scenario::paper(1).truth(0);
        let params = OracleParams {
            miss_probability: f64::NAN,
            false_positive_rate: 7.0,
            ..OracleParams::default()
        };
        let dets = OracleDetector::new(params, 1).detect(&truth, 1280.0, 720.0);
        assert_eq!(
            dets.len(),
            truth
                .boxes
                .iter()
                .filter(|b| b.bbox.height() >= params.min_height_px
                    && b.distance_m <= params.max_range_m)
                .count()
                + 1
        );
    }

    #[test]
    fn towers_beyond_range_are_never_reported() {
        let truth = Scenario::paper(1).truth(0);
        let params = OracleParams {
            miss_probability: 0.0,
            min_height_px: 0.0,
            false_positive_rate: 0.0,
            ..OracleParams::skeleton()
        };
        let far = truth
            .boxes
            .iter()
            .filter(|b| b.distance_m > params.max_range_m)
            .count();
        assert!(
            far > 0,
            "the paper's field has towers past the oracle's range"
        );
        let dets = OracleDetector::new(params, 1).detect(&truth, 1280.0, 720.0);
        assert_eq!(dets.len(), truth.boxes.len() - far);
    }

    #[test]
    fn noiseless_oracle_reports_truth() {
        let scenario = Scenario::paper(1);
        let truth = scenario.truth(0);
        let params = OracleParams {
            edge_sigma_px: 0.0,
            miss_probability: 0.0,
            min_height_px: 0.0,
            false_positive_rate: 0.0,
            max_range_m: f64::INFINITY,
            ..OracleParams::skeleton()
        };
        let dets = OracleDetector::new(params, 1).detect(&truth, 1280.0, 720.0);
        assert_eq!(dets.len(), truth.boxes.len());
        assert!(
            dets.iter()
                .zip(&truth.boxes)
                .all(|(d, t)| d.bbox == t.bbox && d.tower_type == t.tower_type)
        );
    }

    #[test]
    fn misses_and_false_positives_happen_at_about_their_rates() {
        let scenario = Scenario::paper(1);
        let params = OracleParams {
            miss_probability: 0.2,
            false_positive_rate: 0.5,
            min_height_px: 6.0,
            ..OracleParams::skeleton()
        };
        let mut oracle = OracleDetector::new(params, 3);
        let (mut truths, mut dets) = (0usize, 0usize);
        for seq in 0..300 {
            let truth = scenario.truth(seq);
            truths += truth
                .boxes
                .iter()
                .filter(|b| b.bbox.height() >= params.min_height_px)
                .count();
            dets += oracle.detect(&truth, 1280.0, 720.0).len();
        }
        let expected = truths as f64 * 0.8 + 150.0;
        assert!(
            (dets as f64 - expected).abs() < 0.1 * expected,
            "{dets} vs {expected}"
        );
    }

    fn one_tower(height_px: f64, occluded: f64) -> FrameTruth {
        let mut truth = Scenario::paper(1).truth(600);
        truth.boxes.truncate(1);
        let b = &mut truth.boxes[0];
        b.bbox = PixelBox::new(600.0, 300.0, 600.0 + height_px / 4.0, 300.0 + height_px);
        b.occluded = occluded;
        truth.distractors.clear();
        truth
    }

    fn rate(params: OracleParams, truth: &FrameTruth, what: impl Fn(&[Detection]) -> bool) -> f64 {
        let mut oracle = OracleDetector::new(params, 11);
        let n = 4000;
        let hits = (0..n)
            .filter(|_| what(&oracle.detect(truth, 1280.0, 720.0)))
            .count();
        hits as f64 / f64::from(n)
    }

    #[test]
    fn small_and_occluded_towers_are_missed_more_and_boxed_worse() {
        let p = OracleParams {
            false_positive_rate: 0.0,
            ..OracleParams::default()
        };
        let seen = |d: &[Detection]| !d.is_empty();
        let big = rate(p, &one_tower(200.0, 0.0), seen);
        let small = rate(p, &one_tower(18.0, 0.0), seen);
        let hidden = rate(p, &one_tower(200.0, 0.8), seen);
        assert!(
            big > 0.95 && small < 0.5 && hidden < 0.7,
            "{big} {small} {hidden}"
        );
        let spread = |h: f64| {
            let truth = one_tower(h, 0.0);
            let mut oracle = OracleDetector::new(p, 5);
            let errs: Vec<f64> = (0..2000)
                .flat_map(|_| oracle.detect(&truth, 1280.0, 720.0))
                .map(|d| d.bbox.top - truth.boxes[0].bbox.top)
                .collect();
            (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt()
        };
        let (near, far) = (spread(400.0), spread(30.0));
        assert!(
            far > 2.0 * near,
            "edge sigma {near} at 400 px, {far} at 30 px"
        );
    }

    #[test]
    fn distractors_draw_false_positives_and_types_get_confused() {
        let mut truth = one_tower(200.0, 0.0);
        truth.distractors = vec![PixelBox::new(100.0, 300.0, 110.0, 360.0)];
        let p = OracleParams {
            false_positive_rate: 0.0,
            miss_probability: 0.0,
            distractor_false_positive: 0.2,
            type_confusion: 0.1,
            ..OracleParams::default()
        };
        let fp = rate(p, &truth, |d| d.iter().any(|d| d.bbox.left == 100.0));
        let confused = rate(p, &truth, |d| {
            d.iter()
                .any(|d| d.bbox.left > 500.0 && d.tower_type != truth.boxes[0].tower_type)
        });
        assert!((fp - 0.2).abs() < 0.03, "distractor false positives {fp}");
        assert!((confused - 0.1).abs() < 0.03, "type confusion {confused}");
    }
}
