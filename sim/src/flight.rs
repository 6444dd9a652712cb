//! Flights: the level straight line of the walking skeleton, and quadrotor
//! flights that follow waypoint plans with realistic attitude and wind.

use nalgebra::Point3;
use towernav_geometry::{Attitude, Pose, wrap_angle};

pub use crate::quadrotor::{QuadParams, Trajectory, WindParams};
pub use crate::waypoints::{FlightPlan, PlanError, Waypoint};

/// Constant speed and heading, height above the plate oscillating between
/// `height_m - height_swing_m` and `height_m + height_swing_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StraightFlight {
    pub start_in_world: Point3<f64>,
    /// ENU yaw of the track.
    pub yaw: f64,
    pub speed_mps: f64,
    pub duration_s: f64,
    pub height_m: f64,
    pub height_swing_m: f64,
    pub swing_period_s: f64,
}

impl StraightFlight {
    /// East along the plate's centre line, 30 +/- 5 m high, 10 m/s for 95 s.
    pub fn paper_centre_line() -> Self {
        Self {
            start_in_world: Point3::new(0.0, 250.0, 30.0),
            yaw: 0.0,
            speed_mps: 10.0,
            duration_s: 95.0,
            height_m: 30.0,
            height_swing_m: 5.0,
            swing_period_s: 40.0,
        }
    }

    pub fn pose_at(&self, t: f64) -> Pose {
        let along = self.speed_mps * t;
        let swing = self.height_swing_m * (std::f64::consts::TAU * t / self.swing_period_s).sin();
        Pose {
            position_in_world: Point3::new(
                self.start_in_world.x + along * self.yaw.cos(),
                self.start_in_world.y + along * self.yaw.sin(),
                self.height_m + swing,
            ),
            attitude: Attitude::level(self.yaw),
        }
    }
}

/// Any flight the simulator can replay: a pose for every time.
#[derive(Debug, Clone, PartialEq)]
pub enum Flight {
    /// Level, constant speed: the walking skeleton's flight.
    Straight(StraightFlight),
    /// A flown quadrotor trajectory, sampled finely.
    Quad(Trajectory),
}

impl Flight {
    pub fn pose_at(&self, t: f64) -> Pose {
        match self {
            Self::Straight(f) => f.pose_at(t),
            Self::Quad(tr) => tr.pose_at(t),
        }
    }

    pub fn duration_s(&self) -> f64 {
        match self {
            Self::Straight(f) => f.duration_s,
            Self::Quad(tr) => tr.duration_s(),
        }
    }

    /// Where the UAV took off: the rough position the pipeline starts from.
    pub fn start_in_world(&self) -> Point3<f64> {
        self.pose_at(0.0).position_in_world
    }

    /// Body angular rates (roll, pitch, yaw) at `t`, rad/s, by central difference.
    pub fn attitude_rates(&self, t: f64) -> (f64, f64, f64) {
        let dt = 0.01;
        let (a, b) = (
            self.pose_at((t - dt).max(0.0)).attitude,
            self.pose_at(t + dt).attitude,
        );
        let span = (t + dt) - (t - dt).max(0.0);
        (
            (b.roll - a.roll) / span,
            (b.pitch - a.pitch) / span,
            wrap_angle(b.yaw - a.yaw) / span,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_line_flight_stays_in_the_paper_envelope() {
        let flight = StraightFlight::paper_centre_line();
        for i in 0..=950 {
            let p = flight.pose_at(i as f64 * 0.1).position_in_world;
            assert!((20.0..=40.0).contains(&p.z), "height {}", p.z);
            assert!((p.y - 250.0).abs() < 1e-9);
        }
        let end = flight.pose_at(95.0).position_in_world;
        assert!((end.x - 950.0).abs() < 1e-9);
    }
}
