//! Velocity from a downward-looking optical-flow sensor (MAVLink
//! OPTICAL_FLOW_RAD, as a PX4Flow, a mouse-chip sensor or an autopilot's
//! flow driver sends it), for the filter to coast on.
//!
//! The message carries the image's angular flow and the gyro's rotation, both
//! integrated over `integration_time_us`, and the distance along the sensor's
//! axis to the ground. By MAVLink's definition, motion along the sensor's +X
//! gives positive flow about Y, motion along +Y negative flow about X, and a
//! right-handed rotation positive flow about its own axis: the gyro's part is
//! taken out, and what is left, times the distance, is the velocity across the
//! axis. The sensor is taken as mounted looking down, its axes the body's
//! (FRD). The velocity along the axis is not seen, so it gets a wide spread.

use mavlink::dialects::common::OPTICAL_FLOW_RAD_DATA;
use nalgebra::{Matrix3, Vector3};
use towernav_geometry::Attitude;

/// Spread of the flow rate, rad/s, at the best and the worst quality: the
/// defaults PX4's estimator weighs flow by (`EKF2_OF_N_MIN`, `EKF2_OF_N_MAX`).
pub const FLOW_RATE_SIGMA: (f64, f64) = (0.15, 0.5);

/// Spread, m/s, of the velocity along the sensor's axis, which flow does not see.
const ALONG_AXIS_SIGMA_MPS: f64 = 10.0;

/// Past this tilt from straight down the sensor sees the horizon, not ground
/// at the distance it reports.
const MAX_TILT_RAD: f64 = 1.0;

/// East-north-up velocity, m/s, and its covariance, from one message and the
/// body's attitude at the time; the reason when it cannot be used.
pub fn velocity_from_optical_flow(
    o: &OPTICAL_FLOW_RAD_DATA,
    attitude: &Attitude,
) -> Result<(Vector3<f64>, Matrix3<f64>), String> {
    if o.quality == 0 {
        return Err("its quality is 0 (no valid flow)".into());
    }
    if o.integration_time_us == 0 {
        return Err("its integration time is 0".into());
    }
    let distance = f64::from(o.distance);
    if !distance.is_finite() || distance <= 0.0 {
        return Err(format!("its distance is unknown ({distance} m)"));
    }
    let flow = [
        o.integrated_x,
        o.integrated_y,
        o.integrated_xgyro,
        o.integrated_ygyro,
    ]
    .map(f64::from);
    if !flow.iter().all(|f| f.is_finite()) {
        return Err("its flow or gyro is not a number".into());
    }
    let world_from_body = attitude.world_from_body();
    // The sensor looks along the body's down axis (FRD +Z, FLU -Z).
    let down = world_from_body * Vector3::new(0.0, 0.0, -1.0);
    let tilt = (-down.z).clamp(-1.0, 1.0).acos();
    if tilt > MAX_TILT_RAD {
        return Err(format!(
            "the sensor is tilted {:.0} degrees from straight down",
            tilt.to_degrees()
        ));
    }
    let dt = f64::from(o.integration_time_us) * 1e-6;
    let [x, y, x_gyro, y_gyro] = flow;
    // Across the axis, in the sensor's (body FRD) x and y.
    let forward = (y - y_gyro) / dt * distance;
    let right = -(x - x_gyro) / dt * distance;
    // Quality 1..=255 from the worst spread to the best.
    let (best, worst) = FLOW_RATE_SIGMA;
    let share = f64::from(o.quality - 1) / 254.0;
    let sigma = (worst - share * (worst - best)) * distance;
    // Body FLU: y is left, z up.
    let in_body = Vector3::new(forward, -right, 0.0);
    let covariance_in_body = Matrix3::from_diagonal(&Vector3::new(
        sigma * sigma,
        sigma * sigma,
        ALONG_AXIS_SIGMA_MPS * ALONG_AXIS_SIGMA_MPS,
    ));
    let r = world_from_body.to_rotation_matrix().into_inner();
    Ok((r * in_body, r * covariance_in_body * r.transpose()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A message from a sensor `distance` m from the ground, over 0.1 s.
    fn flow(x: f32, y: f32, x_gyro: f32, y_gyro: f32, distance: f32) -> OPTICAL_FLOW_RAD_DATA {
        OPTICAL_FLOW_RAD_DATA {
            integration_time_us: 100_000,
            integrated_x: x,
            integrated_y: y,
            integrated_xgyro: x_gyro,
            integrated_ygyro: y_gyro,
            distance,
            quality: 255,
            ..OPTICAL_FLOW_RAD_DATA::DEFAULT
        }
    }

    fn close(a: &Vector3<f64>, b: [f64; 3]) -> bool {
        (a - Vector3::from(b)).norm() < 1e-6
    }

    #[test]
    fn flow_about_y_is_forward_and_flow_about_x_is_to_the_left() {
        // Level, facing east, 10 m up: 0.02 rad in 0.1 s is 0.2 rad/s, 2 m/s.
        let east = Attitude::level(0.0);
        let (v, _) =
            velocity_from_optical_flow(&flow(0.0, 0.02, 0.0, 0.0, 10.0), &east).expect("used");
        assert!(close(&v, [2.0, 0.0, 0.0]), "{v}");
        // Positive flow about X is motion to the left (FRD -Y): north here.
        let (v, _) =
            velocity_from_optical_flow(&flow(0.02, 0.0, 0.0, 0.0, 10.0), &east).expect("used");
        assert!(close(&v, [0.0, 2.0, 0.0]), "{v}");
        // Facing north, forward is north.
        let north = Attitude::level(std::f64::consts::FRAC_PI_2);
        let (v, _) =
            velocity_from_optical_flow(&flow(0.0, 0.02, 0.0, 0.0, 10.0), &north).expect("used");
        assert!(close(&v, [0.0, 2.0, 0.0]), "{v}");
    }

    #[test]
    fn a_rotation_the_gyro_saw_is_no_motion() {
        // Pitching up 0.05 rad in 0.1 s, hovering: the image flows, the gyro
        // saw the same.
        let (v, _) =
            velocity_from_optical_flow(&flow(0.0, 0.05, 0.0, 0.05, 10.0), &Attitude::level(0.3))
                .expect("used");
        assert!(v.norm() < 1e-6, "{v}");
    }

    #[test]
    fn the_spread_grows_with_distance_and_falls_with_quality() {
        let level = Attitude::level(0.0);
        let sigma = |quality: u8, distance: f32| {
            let o = OPTICAL_FLOW_RAD_DATA {
                quality,
                ..flow(0.0, 0.0, 0.0, 0.0, distance)
            };
            let (_, c) = velocity_from_optical_flow(&o, &level).expect("used");
            c[(0, 0)].sqrt()
        };
        assert!((sigma(255, 10.0) - 1.5).abs() < 1e-9);
        assert!((sigma(1, 10.0) - 5.0).abs() < 1e-9);
        assert!((sigma(255, 20.0) - 3.0).abs() < 1e-9);
        // Level, the axis is vertical: up is all but unmeasured.
        let (_, c) =
            velocity_from_optical_flow(&flow(0.0, 0.0, 0.0, 0.0, 10.0), &level).expect("used");
        assert!(c[(2, 2)].sqrt() >= ALONG_AXIS_SIGMA_MPS - 1e-9);
    }

    #[test]
    fn a_message_that_cannot_give_a_velocity_says_why() {
        let level = Attitude::level(0.0);
        let reason = |o: OPTICAL_FLOW_RAD_DATA, attitude: &Attitude| {
            velocity_from_optical_flow(&o, attitude).expect_err("refused")
        };
        let good = flow(0.0, 0.02, 0.0, 0.0, 10.0);
        let no_quality = OPTICAL_FLOW_RAD_DATA { quality: 0, ..good };
        assert!(reason(no_quality, &level).contains("quality"));
        let unknown = flow(0.0, 0.02, 0.0, 0.0, -1.0);
        assert!(reason(unknown, &level).contains("distance"));
        let no_time = OPTICAL_FLOW_RAD_DATA {
            integration_time_us: 0,
            ..good
        };
        assert!(reason(no_time, &level).contains("integration time"));
        let nan = flow(f32::NAN, 0.02, 0.0, 0.0, 10.0);
        assert!(reason(nan, &level).contains("not a number"));
        let banked = Attitude { roll: 1.2, ..level };
        assert!(reason(good, &banked).contains("tilted"));
    }
}
