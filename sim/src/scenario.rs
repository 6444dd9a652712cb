//! A world, a flight and a camera: everything needed to replay a simulated flight frame by frame.

use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use towernav_geometry::PinholeCamera;
use towernav_protocol::DetectionFrame;

use crate::flight::StraightFlight;
use crate::oracle::{OracleDetector, OracleParams};
use crate::truth::{FrameTruth, frame_truth};
use crate::world::World;

#[derive(Debug, Clone)]
pub struct Scenario {
    pub world: World,
    pub flight: StraightFlight,
    pub camera: PinholeCamera,
    pub fps: f64,
    pub seed: u64,
    pub oracle: OracleParams,
    /// Standard deviation of the IMU heading, radians.
    pub imu_yaw_sigma: f64,
}

impl Scenario {
    /// The seed's field and centre-line flight at 30 frames/s with a 1280x720 camera.
    pub fn seed(seed: u64) -> Self {
        Self {
            world: World::seed_field(),
            flight: StraightFlight::seed_centre_line(),
            camera: PinholeCamera::default_hd(),
            fps: 30.0,
            seed,
            oracle: OracleParams::default(),
            imu_yaw_sigma: 0.2f64.to_radians(),
        }
    }

    pub fn frame_count(&self) -> u64 {
        (self.flight.duration_s * self.fps).floor() as u64
    }

    pub fn truth(&self, seq: u64) -> FrameTruth {
        let t = seq as f64 / self.fps;
        frame_truth(&self.camera, &self.world, seq, t, self.flight.pose_at(t))
    }

    /// Truth and what the pipeline sees (detections, IMU with heading noise) for every frame, in order; deterministic in `seed`.
    pub fn frames(&self) -> impl Iterator<Item = (FrameTruth, DetectionFrame)> + '_ {
        let mut oracle = OracleDetector::new(self.oracle, self.seed);
        let mut imu_rng = ChaCha8Rng::seed_from_u64(self.seed ^ 0x1_0000);
        let yaw_sigma = self.imu_yaw_sigma.max(0.0);
        let (w, h) = (
            f64::from(self.camera.intrinsics.width),
            f64::from(self.camera.intrinsics.height),
        );
        (0..self.frame_count()).map(move |seq| {
            let truth = self.truth(seq);
            let detections = oracle.detect(&truth, w, h);
            let mut imu_attitude = truth.pose.attitude;
            imu_attitude.yaw += yaw_sigma * imu_rng.sample::<f64, _>(StandardNormal);
            let input = DetectionFrame {
                seq,
                time_s: truth.time_s,
                imu_attitude,
                detections,
            };
            (truth, input)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn towers_are_in_view_until_the_uav_passes_the_last_ones() {
        let scenario = Scenario::seed(0);
        let frames: Vec<_> = scenario.frames().collect();
        assert_eq!(frames.len(), 2850);
        for (truth, _) in &frames {
            let east = truth.pose.position_in_world.x;
            if east < 850.0 {
                assert!(
                    !truth.boxes.is_empty(),
                    "no tower in view at east {east:.0} m"
                );
            }
        }
        let last = &frames[frames.len() - 1].0;
        assert!(last.boxes.is_empty(), "every tower is behind at the end");
    }

    #[test]
    fn replay_is_deterministic() {
        let a: Vec<_> = Scenario::seed(4)
            .frames()
            .take(50)
            .map(|(_, i)| i)
            .collect();
        let b: Vec<_> = Scenario::seed(4)
            .frames()
            .take(50)
            .map(|(_, i)| i)
            .collect();
        assert_eq!(a, b);
    }
}
