//! World (ENU), body (FLU) and the attitude that links them.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Attitude of the body in the world, in the words a pilot uses.
///
/// `world_from_body = Rz(yaw) * Ry(-pitch) * Rx(roll)`, so that:
/// - `yaw` is counter-clockwise from east (ENU, as in ROS REP-103);
/// - `pitch` is positive nose-up;
/// - `roll` is positive right-wing-down.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Attitude {
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}

impl Attitude {
    pub fn level(yaw: f64) -> Self {
        Self {
            roll: 0.0,
            pitch: 0.0,
            yaw,
        }
    }

    /// From an autopilot's NED/FRD Euler angles (MAVLink ATTITUDE): roll and
    /// pitch mean the same in both conventions; yaw is clockwise from north there.
    pub fn from_ned(roll: f64, pitch: f64, yaw_from_north: f64) -> Self {
        Self {
            roll,
            pitch,
            yaw: wrap_angle(std::f64::consts::FRAC_PI_2 - yaw_from_north),
        }
    }

    /// Yaw clockwise from north, in (-pi, pi], for NED consumers.
    pub fn yaw_from_north(&self) -> f64 {
        wrap_angle(std::f64::consts::FRAC_PI_2 - self.yaw)
    }

    pub fn world_from_body(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw)
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -self.pitch)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), self.roll)
    }
}

/// Compass heading in degrees (clockwise from north, 0..360) of an ENU yaw.
pub fn heading_deg_from_yaw(yaw: f64) -> f64 {
    (90.0 - yaw.to_degrees()).rem_euclid(360.0)
}

/// Wraps an angle into (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

/// Position and attitude of the body in the world.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position_in_world: Point3<f64>,
    pub attitude: Attitude,
}

impl Pose {
    pub fn world_from_body(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.position_in_world.coords),
            self.attitude.world_from_body(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn level_yaw_zero_looks_east() {
        let forward = Attitude::level(0.0).world_from_body() * Vector3::x();
        assert!((forward - Vector3::x()).norm() < 1e-12);
    }

    #[test]
    fn positive_pitch_raises_the_nose() {
        let a = Attitude {
            pitch: 0.1,
            ..Attitude::level(FRAC_PI_2)
        };
        let forward = a.world_from_body() * Vector3::x();
        assert!(forward.z > 0.09 && forward.y > 0.99);
    }

    #[test]
    fn positive_roll_lowers_the_right_wing() {
        let a = Attitude {
            roll: 0.2,
            ..Attitude::level(0.0)
        };
        let right = a.world_from_body() * -Vector3::y();
        assert!(right.z < -0.19);
    }

    #[test]
    fn compass_heading_of_north_and_east() {
        assert!((heading_deg_from_yaw(FRAC_PI_2) - 0.0).abs() < 1e-9);
        assert!((heading_deg_from_yaw(0.0) - 90.0).abs() < 1e-9);
    }

    #[test]
    fn ned_yaw_is_clockwise_from_north() {
        let east = Attitude::from_ned(0.0, 0.0, FRAC_PI_2);
        assert!(east.yaw.abs() < 1e-12, "heading 90 is ENU yaw 0");
        let north = Attitude::from_ned(0.1, -0.2, 0.0);
        assert!((north.yaw - FRAC_PI_2).abs() < 1e-12);
        assert_eq!((north.roll, north.pitch), (0.1, -0.2));
    }

    proptest! {
        #[test]
        fn ned_conversion_round_trips(yaw in -3.1f64..3.1) {
            let a = Attitude::from_ned(0.0, 0.0, yaw);
            prop_assert!((wrap_angle(a.yaw_from_north() - yaw)).abs() < 1e-12);
        }

        #[test]
        fn wrap_angle_stays_in_range_and_keeps_direction(a in -50.0f64..50.0) {
            let w = wrap_angle(a);
            prop_assert!(w > -std::f64::consts::PI - 1e-12 && w <= std::f64::consts::PI + 1e-12);
            prop_assert!((w.sin() - a.sin()).abs() < 1e-9 && (w.cos() - a.cos()).abs() < 1e-9);
        }

        #[test]
        fn rotation_preserves_length(roll in -1.0f64..1.0, pitch in -1.0f64..1.0, yaw in -4.0f64..4.0,
                                     x in -100.0f64..100.0, y in -100.0f64..100.0, z in -100.0f64..100.0) {
            let v = Vector3::new(x, y, z);
            let r = Attitude { roll, pitch, yaw }.world_from_body();
            prop_assert!(((r * v).norm() - v.norm()).abs() < 1e-9);
        }
    }
}
