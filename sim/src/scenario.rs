//! A world, a flight and a camera: everything needed to replay a simulated flight frame by frame.

use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use towernav_geometry::{PinholeCamera, Pose};
use towernav_protocol::DetectionFrame;

use crate::flight::{Flight, StraightFlight};
use crate::oracle::{OracleDetector, OracleParams};
use crate::quadrotor::{QuadParams, fly};
use crate::render::{Conditions, FrameBuffers, Renderer};
use crate::truth::{FrameTruth, Outline, TruthBox, frame_truth, outlines};
use crate::waypoints::{FlightPlan, PlanError, random_crossing};
use crate::world::World;
use crate::world::WorldParams;
use nalgebra::Point3;

#[derive(Debug, Clone)]
pub struct Scenario {
    pub world: World,
    pub flight: Flight,
    pub camera: PinholeCamera,
    pub fps: f64,
    pub seed: u64,
    pub oracle: OracleParams,
    pub imu: ImuParams,
}

/// How the IMU's attitude output differs from the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuParams {
    /// White noise on roll and pitch, per frame, radians.
    pub roll_pitch_sigma: f64,
    /// White noise on the heading, per frame, radians.
    pub yaw_sigma: f64,
    /// A constant heading bias (magnetometer calibration), radians.
    pub yaw_bias: f64,
    /// Correlation time of the errors, seconds: an AHRS's attitude error
    /// wanders slowly rather than jumping every frame. 0: white per frame.
    pub correlation_s: f64,
}

impl Default for ImuParams {
    fn default() -> Self {
        Self {
            roll_pitch_sigma: 0.1f64.to_radians(),
            yaw_sigma: 0.2f64.to_radians(),
            yaw_bias: 0.0,
            correlation_s: 3.0,
        }
    }
}

impl Scenario {
    /// The walking skeleton's scenario: the paper's field, the level centre-line
    /// flight at 30 frames/s, a 1280x720 camera, and the skeleton's simple oracle.
    /// `preset` gives quadrotor attitude and the realistic oracle.
    pub fn paper(seed: u64) -> Self {
        Self {
            world: World::paper_field(),
            flight: Flight::Straight(StraightFlight::paper_centre_line()),
            camera: PinholeCamera::default_hd(),
            fps: 30.0,
            seed,
            oracle: OracleParams::skeleton(),
            imu: ImuParams {
                roll_pitch_sigma: 0.0,
                correlation_s: 0.0,
                ..ImuParams::default()
            },
        }
    }

    /// A quadrotor flying a named plan (see `waypoints::PRESETS`) over `world`.
    pub fn preset(world: World, plan: &str, seed: u64) -> Result<Self, PlanError> {
        Ok(Self::flying(world, &FlightPlan::preset(plan)?, seed))
    }

    /// A quadrotor flying `plan` over `world` with default dynamics, camera and sensors.
    pub fn flying(world: World, plan: &FlightPlan, seed: u64) -> Self {
        Self {
            world,
            flight: Flight::Quad(fly(plan, &QuadParams::default(), seed)),
            camera: PinholeCamera::default_hd(),
            fps: 30.0,
            seed,
            oracle: OracleParams::default(),
            imu: ImuParams::default(),
        }
    }

    /// World number `world_seed` of a dataset: a random field, a crossing
    /// flight over it and random weather, all drawn from the seed. Training
    /// data and held-out evaluations draw from disjoint seeds.
    pub fn random_crossing(world_seed: u64) -> (Self, Conditions) {
        Self::random_crossing_in(world_seed, &WorldParams::default())
    }

    /// [`Scenario::random_crossing`] over a world drawn with `params`.
    pub fn random_crossing_in(world_seed: u64, params: &WorldParams) -> (Self, Conditions) {
        let mut rng = ChaCha8Rng::seed_from_u64(world_seed);
        let world = World::random(world_seed, params);
        let towers: Vec<(f64, f64, f64)> = world
            .towers
            .iter()
            .map(|t| (t.foot_in_world.x, t.foot_in_world.y, t.height_m))
            .collect();
        let plan = random_crossing(params.extent_m, &towers, &mut rng);
        let scenario = Self::flying(world, &plan, world_seed);
        let conditions = Conditions::random(&mut rng);
        (scenario, conditions)
    }

    /// A renderer for this scenario's world and camera, textured from its seed.
    pub fn renderer(&self) -> Renderer {
        Renderer::new(&self.world, self.camera, self.seed)
    }

    /// Render the frame `truth` describes, blurred by the flight's attitude
    /// rates, with sensor noise repeatable per frame.
    pub fn render_into(
        &self,
        renderer: &Renderer,
        buffers: &mut FrameBuffers,
        truth: &FrameTruth,
        conditions: &Conditions,
    ) {
        let rates = self.flight.attitude_rates(truth.time_s);
        renderer.render_into(
            buffers,
            &truth.pose,
            conditions,
            rates,
            self.seed ^ truth.seq,
        );
    }

    pub fn frame_count(&self) -> u64 {
        (self.flight.duration_s() * self.fps).floor() as u64
    }

    /// Whether a tracker must cover this true box: tall enough that the
    /// detector reliably reports it, and mostly unhidden. Others are "don't
    /// care": a hypothesis on one is neither a hit nor a false positive.
    pub fn demanded(&self, b: &TruthBox) -> bool {
        b.bbox.height() >= 2.0 * self.oracle.min_height_px && b.occluded < 0.75
    }

    pub fn start_in_world(&self) -> Point3<f64> {
        self.flight.start_in_world()
    }

    pub fn truth(&self, seq: u64) -> FrameTruth {
        self.truth_with(&outlines(&self.world), seq)
    }

    /// Truth for frame `seq` seen from `pose` instead of the flight's own.
    pub fn truth_from(&self, seq: u64, pose: Pose) -> FrameTruth {
        let t = seq as f64 / self.fps;
        frame_truth(
            &self.camera,
            &self.world,
            &outlines(&self.world),
            seq,
            t,
            pose,
        )
    }

    fn truth_with(&self, outlines: &[Outline], seq: u64) -> FrameTruth {
        let t = seq as f64 / self.fps;
        frame_truth(
            &self.camera,
            &self.world,
            outlines,
            seq,
            t,
            self.flight.pose_at(t),
        )
    }

    /// Truth and what the pipeline sees (detections, IMU with heading noise) for every frame, in order; deterministic in `seed`.
    pub fn frames(&self) -> impl Iterator<Item = (FrameTruth, DetectionFrame)> + '_ {
        Self::frames_of(self)
    }

    /// `frames` owning a shared scenario, for a frame source on its own thread.
    pub fn frames_shared(
        self: &std::sync::Arc<Self>,
    ) -> impl Iterator<Item = (FrameTruth, DetectionFrame)> + Send + 'static {
        Self::frames_of(self.clone())
    }

    fn frames_of<S: std::ops::Deref<Target = Scenario>>(
        scenario: S,
    ) -> impl Iterator<Item = (FrameTruth, DetectionFrame)> {
        let this: &Scenario = &scenario;
        let mut oracle = OracleDetector::new(this.oracle, this.seed);
        let mut imu_rng = ChaCha8Rng::seed_from_u64(this.seed ^ 0x1_0000);
        let imu = this.imu;
        let (w, h) = (
            f64::from(this.camera.intrinsics.width),
            f64::from(this.camera.intrinsics.height),
        );
        let outlines = outlines(&this.world);
        // First-order Gauss-Markov errors (yaw, roll, pitch) in units of their sigma.
        let keep = if imu.correlation_s > 0.0 {
            (-1.0 / (this.fps * imu.correlation_s)).exp()
        } else {
            0.0
        };
        let drive = (1.0 - keep * keep).sqrt();
        let mut state: Option<[f64; 3]> = None;
        let count = this.frame_count();
        (0..count).map(move |seq| {
            let truth = scenario.truth_with(&outlines, seq);
            let detections = oracle.detect(&truth, w, h);
            let with_roll_pitch = imu.roll_pitch_sigma > 0.0;
            let mut draw = || imu_rng.sample::<f64, _>(StandardNormal);
            let fresh = [
                draw(),
                if with_roll_pitch { draw() } else { 0.0 },
                if with_roll_pitch { draw() } else { 0.0 },
            ];
            let e = match state {
                None => fresh,
                Some(prev) => std::array::from_fn(|i| keep * prev[i] + drive * fresh[i]),
            };
            state = Some(e);
            let mut imu_attitude = truth.pose.attitude;
            imu_attitude.yaw += imu.yaw_bias + imu.yaw_sigma.max(0.0) * e[0];
            imu_attitude.roll += imu.roll_pitch_sigma.max(0.0) * e[1];
            imu_attitude.pitch += imu.roll_pitch_sigma.max(0.0) * e[2];
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
        let scenario = Scenario::paper(0);
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
        let a: Vec<_> = Scenario::paper(4)
            .frames()
            .take(50)
            .map(|(_, i)| i)
            .collect();
        let b: Vec<_> = Scenario::paper(4)
            .frames()
            .take(50)
            .map(|(_, i)| i)
            .collect();
        assert_eq!(a, b);
    }
}
