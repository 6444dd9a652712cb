//! A noisy stand-in for the detector: true boxes with pixel noise, misses and
//! false positives, all drawn from one seeded generator.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use towernav_geometry::PixelBox;
use towernav_protocol::{Detection, TowerType};

use crate::truth::FrameTruth;

/// Documented knobs of the oracle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OracleParams {
    /// Standard deviation of each box edge, pixels.
    pub edge_sigma_px: f64,
    /// Chance that a visible tower is not reported in a frame.
    pub miss_probability: f64,
    /// Boxes shorter than this are never reported.
    pub min_height_px: f64,
    /// Expected false positives per frame (Bernoulli per frame at this rate, at most one).
    pub false_positive_rate: f64,
}

impl Default for OracleParams {
    fn default() -> Self {
        Self {
            edge_sigma_px: 1.0,
            miss_probability: 0.03,
            min_height_px: 12.0,
            false_positive_rate: 0.02,
        }
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
        let mut out = Vec::with_capacity(truth.boxes.len() + 1);
        for b in &truth.boxes {
            if b.bbox.height() < self.params.min_height_px
                || self
                    .rng
                    .random_bool(probability(self.params.miss_probability))
            {
                continue;
            }
            let sigma = self.params.edge_sigma_px.max(0.0);
            let mut jitter = || sigma * self.rng.sample::<f64, _>(StandardNormal);
            let bbox = PixelBox::new(
                b.bbox.left + jitter(),
                b.bbox.top + jitter(),
                b.bbox.right + jitter(),
                b.bbox.bottom + jitter(),
            )
            .clipped(width, height);
            out.push(Detection {
                bbox,
                tower_type: b.tower_type,
                score: self.rng.random_range(0.6..0.98),
            });
        }
        if self
            .rng
            .random_bool(probability(self.params.false_positive_rate))
        {
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
        let scenario = Scenario::seed(1);
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
        let truth = Scenario::seed(1).truth(0);
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
                .filter(|b| b.bbox.height() >= params.min_height_px)
                .count()
                + 1
        );
    }

    #[test]
    fn noiseless_oracle_reports_truth() {
        let scenario = Scenario::seed(1);
        let truth = scenario.truth(0);
        let params = OracleParams {
            edge_sigma_px: 0.0,
            miss_probability: 0.0,
            min_height_px: 0.0,
            false_positive_rate: 0.0,
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
        let scenario = Scenario::seed(1);
        let params = OracleParams {
            miss_probability: 0.2,
            false_positive_rate: 0.5,
            ..OracleParams::default()
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
}
