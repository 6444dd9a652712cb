//! What the autopilot is told, message by message: the pose as GPS_INPUT (a
//! GNSS stand-in, for ArduPilot's and PX4's GPS drivers), ODOMETRY (their
//! external-vision fusion) or GLOBAL_POSITION_SENSOR (PX4's auxiliary global
//! position), plus HEARTBEAT and STATUSTEXT. Pure: `autopilot_link` decides
//! when, the shell sends them.
//!
//! Read the other way: the velocity in another component's ODOMETRY (a VIO or
//! optical-flow estimator), for the filter to coast on.
//!
//! Accuracy fields come from the estimate's covariance and the fix type from
//! how fresh the last tower fix is, so an autopilot stops trusting a coasting
//! or lost estimate.

use mavlink::dialects::common::{
    GLOBAL_POSITION_SENSOR_DATA, GPS_INPUT_DATA, GlobalPositionFlags, GlobalPositionSrc,
    GpsFixType, GpsInputIgnoreFlags, HEARTBEAT_DATA, MavAutopilot, MavEstimatorType, MavFrame,
    MavModeFlag, MavSeverity, MavState, MavType, ODOMETRY_DATA, STATUSTEXT_DATA,
};
use nalgebra::{UnitQuaternion, Vector3};
use towernav_geometry::Attitude;
use towernav_protocol::{EdgeState, Health, PoseEstimate};

/// Seconds between the GPS epoch (1980-01-06) and the Unix epoch, and the
/// GPS-UTC leap seconds (18 since 2017).
const GPS_EPOCH_UNIX_S: u64 = 315_964_800;
const GPS_LEAP_S: u64 = 18;
const WEEK_S: u64 = 7 * 24 * 3600;

/// Horizontal and vertical 1-sigma accuracy, metres, from the covariance.
pub fn accuracy_m(pose: &PoseEstimate) -> (f64, f64) {
    let c = &pose.covariance;
    ((c[0][0] + c[1][1]).max(0.0).sqrt(), c[2][2].max(0.0).sqrt())
}

/// GPS_INPUT at `unix_time_us` with fix `fix`. `pose` is the estimate to
/// report (none before the first); `geoid_m` the geoid's height there, since
/// GPS_INPUT's altitude is above mean sea level and the pose's is ellipsoidal.
/// Velocity is not reported (flagged as ignored); without a pose, neither are
/// altitude and accuracies; with a pose whose height no source measured (the
/// paper's method without a barometer), the altitude is flagged as not given
/// and the fix is at most 2-D.
pub fn gps_input(
    pose: Option<&PoseEstimate>,
    fix: GpsFixType,
    geoid_m: f64,
    unix_time_us: u64,
) -> GPS_INPUT_DATA {
    let gps_s = (unix_time_us / 1_000_000).saturating_sub(GPS_EPOCH_UNIX_S) + GPS_LEAP_S;
    let mut ignore = GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VEL_HORIZ
        | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VEL_VERT
        | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_SPEED_ACCURACY;
    let mut fix = fix;
    let (lat, lon, alt, (h, v)) = match pose {
        Some(p) if crate::localizer::Height::is_unknown(accuracy_m(p).1) => {
            // No source measured the height: say so, and call it a 2-D fix.
            ignore |= GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VDOP
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VERTICAL_ACCURACY;
            if fix == GpsFixType::GPS_FIX_TYPE_3D_FIX {
                fix = GpsFixType::GPS_FIX_TYPE_2D_FIX;
            }
            (p.lat_deg, p.lon_deg, 0.0, (accuracy_m(p).0, 0.0))
        }
        Some(p) => (p.lat_deg, p.lon_deg, p.alt_m - geoid_m, accuracy_m(p)),
        None => {
            ignore |= GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_HDOP
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VDOP
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VERTICAL_ACCURACY;
            (0.0, 0.0, 0.0, (0.0, 0.0))
        }
    };
    GPS_INPUT_DATA {
        time_usec: unix_time_us,
        time_week_ms: ((gps_s % WEEK_S) * 1000 + (unix_time_us / 1000) % 1000) as u32,
        time_week: (gps_s / WEEK_S) as u16,
        lat: (lat * 1e7).round() as i32,
        lon: (lon * 1e7).round() as i32,
        alt: alt as f32,
        // With no satellites, DOP is the accuracy over a nominal 1 m range error.
        hdop: h as f32,
        vdop: v as f32,
        horiz_accuracy: h as f32,
        vert_accuracy: v as f32,
        ignore_flags: ignore,
        gps_id: 0,
        fix_type: fix,
        // Autopilots' pre-arm checks count satellites; report a healthy count only with a fix.
        satellites_visible: if fix == GpsFixType::GPS_FIX_TYPE_3D_FIX {
            12
        } else {
            0
        },
        ..GPS_INPUT_DATA::DEFAULT
    }
}

/// PX4's auxiliary global position (GLOBAL_POSITION_SENSOR): the fix with
/// both altitudes and its 1-sigma errors; `healthy` false while coasting or lost,
/// so PX4 stops fusing it.
pub fn global_position(
    pose: &PoseEstimate,
    geoid_m: f64,
    healthy: bool,
    unix_time_us: u64,
) -> GLOBAL_POSITION_SENSOR_DATA {
    let (h, v) = accuracy_m(pose);
    GLOBAL_POSITION_SENSOR_DATA {
        time_usec: unix_time_us,
        lat: (pose.lat_deg * 1e7).round() as i32,
        lon: (pose.lon_deg * 1e7).round() as i32,
        alt_ellipsoid: pose.alt_m as f32,
        alt: (pose.alt_m - geoid_m) as f32,
        eph: h as f32,
        epv: v as f32,
        source: GlobalPositionSrc::GLOBAL_POSITION_SRC_VISION,
        flags: if healthy {
            GlobalPositionFlags::empty()
        } else {
            GlobalPositionFlags::GLOBAL_POSITION_UNHEALTHY
        },
        ..GLOBAL_POSITION_SENSOR_DATA::DEFAULT
    }
}

/// HEARTBEAT of a non-autopilot onboard component, its state the edge's:
/// standby before the first fix, active while localized or coasting,
/// critical when the pose is lost or the daemon has failed.
pub fn heartbeat(state: EdgeState, health: Health) -> HEARTBEAT_DATA {
    let system_status = match (state, health) {
        (_, Health::Failed) | (EdgeState::NoFix, _) => MavState::MAV_STATE_CRITICAL,
        (EdgeState::Initializing, _) => MavState::MAV_STATE_STANDBY,
        (EdgeState::Localized | EdgeState::Coasting, _) => MavState::MAV_STATE_ACTIVE,
    };
    HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status,
        mavlink_version: 3,
    }
}

/// STATUSTEXT, cut to the message's 50 bytes on a character boundary.
pub fn status_text(severity: MavSeverity, text: &str) -> STATUSTEXT_DATA {
    let mut end = text.len().min(50);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    STATUSTEXT_DATA {
        severity,
        text: text[..end].into(),
        ..STATUSTEXT_DATA::DEFAULT
    }
}

/// ODOMETRY in the local NED frame about the mission datum (x north, y east,
/// z down), body FRD, with the pose covariance (row-major upper triangle of
/// x, y, z, roll, pitch, yaw) and unknown velocity (NaN). `quality` is the
/// message's percentage: -1 once the pose is lost.
pub fn odometry(
    pose: &PoseEstimate,
    attitude: &Attitude,
    unix_time_us: u64,
    quality: i8,
) -> ODOMETRY_DATA {
    let c = &pose.covariance;
    // ENU (e, n, u, yaw) -> NED (n, e, d, yaw): swap e/n, negate u, yaw sign flips.
    let ned = [1usize, 0, 2];
    let sign = [1.0, 1.0, -1.0];
    let mut cov6 = [[0.0f64; 6]; 6];
    for i in 0..3 {
        for j in 0..3 {
            cov6[i][j] = sign[i] * sign[j] * c[ned[i]][ned[j]];
        }
        cov6[i][5] = -sign[i] * c[ned[i]][3];
        cov6[5][i] = cov6[i][5];
    }
    cov6[5][5] = c[3][3];
    // Roll and pitch come from the autopilot's own AHRS: a nominal 1 degree.
    cov6[3][3] = 1f64.to_radians().powi(2);
    cov6[4][4] = cov6[3][3];
    let mut pose_covariance = [0f32; 21];
    let mut k = 0;
    for (i, row) in cov6.iter().enumerate() {
        for value in &row[i..] {
            pose_covariance[k] = *value as f32;
            k += 1;
        }
    }
    let ned_attitude = UnitQuaternion::from_euler_angles(
        attitude.roll,
        attitude.pitch,
        Attitude {
            yaw: pose.yaw_rad,
            ..*attitude
        }
        .yaw_from_north(),
    );
    let q = ned_attitude.quaternion();
    let mut velocity_covariance = [0f32; 21];
    velocity_covariance[0] = f32::NAN;
    ODOMETRY_DATA {
        time_usec: unix_time_us,
        x: pose.north_m as f32,
        y: pose.east_m as f32,
        z: -pose.up_m as f32,
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        vx: f32::NAN,
        vy: f32::NAN,
        vz: f32::NAN,
        rollspeed: f32::NAN,
        pitchspeed: f32::NAN,
        yawspeed: f32::NAN,
        pose_covariance,
        velocity_covariance,
        frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        child_frame_id: MavFrame::MAV_FRAME_BODY_FRD,
        reset_counter: 0,
        estimator_type: MavEstimatorType::MAV_ESTIMATOR_TYPE_VISION,
        quality,
    }
}

/// Velocities with no covariance are taken at this 1-sigma per axis, m/s.
pub const DEFAULT_VELOCITY_SIGMA_MPS: f64 = 0.5;

/// The velocity in another component's ODOMETRY (a visual-inertial odometry
/// or optical-flow estimator), east-north-up in m/s with its covariance.
/// Velocity given in the body (FRD) frame is turned into the world by the
/// message's own attitude; in LOCAL_NED it is already there. Other frames, a
/// missing velocity and a quality of -1 (the sender says it failed) give the
/// reason it is not used.
pub fn velocity_from_odometry(
    o: &ODOMETRY_DATA,
) -> Result<(Vector3<f64>, nalgebra::Matrix3<f64>), String> {
    if o.quality == -1 {
        return Err("its quality is -1 (failed)".into());
    }
    let v = Vector3::new(f64::from(o.vx), f64::from(o.vy), f64::from(o.vz));
    if !v.iter().all(|c| c.is_finite()) {
        return Err("it carries no velocity".into());
    }
    // Upper triangle of the 6x6 (vx, vy, vz, rates): row 0 is 0..6, row 1 7..11, row 2 12..15.
    let c = &o.velocity_covariance;
    let covariance_frd_or_ned = if c[0].is_finite() {
        let m = nalgebra::Matrix3::new(c[0], c[1], c[2], c[1], c[6], c[7], c[2], c[7], c[11])
            .map(f64::from);
        if !m.iter().all(|x| x.is_finite()) || (0..3).any(|i| m[(i, i)] <= 0.0) {
            return Err("its velocity covariance is not positive".into());
        }
        m
    } else {
        nalgebra::Matrix3::identity() * DEFAULT_VELOCITY_SIGMA_MPS.powi(2)
    };
    // NED -> ENU as a matrix: swap north and east, negate down.
    let enu_from_ned = nalgebra::Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    let world_from_frame = match o.child_frame_id {
        MavFrame::MAV_FRAME_LOCAL_NED => enu_from_ned,
        MavFrame::MAV_FRAME_BODY_FRD => {
            let [w, x, y, z] = o.q.map(f64::from);
            if ![w, x, y, z].iter().all(|c| c.is_finite()) || (w * w + x * x + y * y + z * z) < 0.5
            {
                return Err(
                    "its velocity is in the body frame and its attitude is not valid".into(),
                );
            }
            let ned_from_frd =
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            enu_from_ned * ned_from_frd.to_rotation_matrix().into_inner()
        }
        other => {
            return Err(format!(
                "its velocity is in {other:?}, not BODY_FRD or LOCAL_NED"
            ));
        }
    };
    Ok((
        world_from_frame * v,
        world_from_frame * covariance_frd_or_ned * world_from_frame.transpose(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_protocol::{NodeId, PoseMethod};

    fn pose() -> PoseEstimate {
        let mut covariance = [[0.0; 4]; 4];
        covariance[0][0] = 4.0; // east 2 m
        covariance[1][1] = 5.0; // north
        covariance[2][2] = 9.0; // up 3 m
        covariance[3][3] = 0.01;
        covariance[0][1] = 1.0;
        covariance[1][0] = 1.0;
        PoseEstimate {
            uav: NodeId::new("u1").expect("valid"),
            time_s: 1.0,
            seq: 30,
            east_m: 10.0,
            north_m: 20.0,
            up_m: 50.0,
            lat_deg: 30.5205123,
            lon_deg: 114.3601234,
            alt_m: 75.5,
            yaw_rad: std::f64::consts::FRAC_PI_2,
            covariance,
            method: PoseMethod::RaysEkf,
            towers_used: vec!["A1".into()],
            coast_s: 0.0,
        }
    }

    #[test]
    fn gps_input_carries_position_msl_altitude_accuracy_and_the_fix_given() {
        // 2026-11-22 00:00:00 UTC.
        let unix_us = 1_795_305_600_000_000;
        let g = gps_input(
            Some(&pose()),
            GpsFixType::GPS_FIX_TYPE_3D_FIX,
            -12.5,
            unix_us,
        );
        assert_eq!((g.lat, g.lon), (305_205_123, 1_143_601_234));
        assert!(
            (g.alt - 88.0).abs() < 1e-4,
            "75.5 m ellipsoidal over a geoid at -12.5 m"
        );
        assert!((g.horiz_accuracy - 3.0).abs() < 1e-6, "sqrt(4 + 5)");
        assert!((g.vert_accuracy - 3.0).abs() < 1e-6);
        assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_3D_FIX);
        assert!(g.satellites_visible >= 6);
        assert!(
            !g.ignore_flags
                .contains(GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT)
        );
        // GPS week of 2026-11-22 (a Sunday, so the week just began): 2446.
        assert_eq!(g.time_week, 2446);
        assert_eq!(g.time_week_ms, 18_000, "18 leap seconds into the week");
        let coasting = gps_input(Some(&pose()), GpsFixType::GPS_FIX_TYPE_2D_FIX, 0.0, unix_us);
        assert_eq!(coasting.satellites_visible, 0);
        let lost = gps_input(None, GpsFixType::GPS_FIX_TYPE_NO_FIX, 0.0, unix_us);
        assert_eq!(lost.fix_type, GpsFixType::GPS_FIX_TYPE_NO_FIX);
        assert!(lost.ignore_flags.contains(
            GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY
        ));
    }

    #[test]
    fn a_height_no_source_measured_is_flagged_and_the_fix_is_2d() {
        let mut p = pose();
        let unknown = crate::localizer::Height::UNKNOWN_SIGMA_M;
        p.covariance[2][2] = unknown * unknown;
        let g = gps_input(Some(&p), GpsFixType::GPS_FIX_TYPE_3D_FIX, -12.5, 0);
        assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_2D_FIX);
        assert!(g.ignore_flags.contains(
            GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_ALT
                | GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_VERTICAL_ACCURACY
        ));
        assert!(
            !g.ignore_flags
                .contains(GpsInputIgnoreFlags::GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY)
        );
        assert!((g.horiz_accuracy - 3.0).abs() < 1e-6);
        assert_eq!(g.satellites_visible, 0);
    }

    fn vio(child: MavFrame, v: [f32; 3], q: [f32; 4]) -> ODOMETRY_DATA {
        let mut velocity_covariance = [0f32; 21];
        (
            velocity_covariance[0],
            velocity_covariance[6],
            velocity_covariance[11],
        ) = (0.04, 0.09, 0.16);
        ODOMETRY_DATA {
            vx: v[0],
            vy: v[1],
            vz: v[2],
            q,
            velocity_covariance,
            child_frame_id: child,
            frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
            quality: 80,
            ..ODOMETRY_DATA::DEFAULT
        }
    }

    #[test]
    fn another_components_velocity_is_turned_into_the_world_frame() {
        // Local NED: 2 m/s north, 1 east, 0.5 down.
        let (v, c) = velocity_from_odometry(&vio(
            MavFrame::MAV_FRAME_LOCAL_NED,
            [2.0, 1.0, 0.5],
            [1.0, 0.0, 0.0, 0.0],
        ))
        .expect("used");
        assert!((v - Vector3::new(1.0, 2.0, -0.5)).norm() < 1e-6, "{v}");
        // North's variance 0.04 becomes the second (north) axis of ENU.
        assert!((c[(1, 1)] - 0.04).abs() < 1e-6 && (c[(0, 0)] - 0.09).abs() < 1e-6);
        // Body FRD, heading 90 degrees (east): 3 m/s forward is 3 m/s east.
        let half = std::f32::consts::FRAC_PI_4;
        let east = vio(
            MavFrame::MAV_FRAME_BODY_FRD,
            [3.0, 0.0, 0.0],
            [half.cos(), 0.0, 0.0, half.sin()],
        );
        let (v, c) = velocity_from_odometry(&east).expect("used");
        assert!((v - Vector3::new(3.0, 0.0, 0.0)).norm() < 1e-5, "{v}");
        assert!(
            (c[(0, 0)] - 0.04).abs() < 1e-6,
            "forward's variance is east's"
        );
        // Our own ODOMETRY carries no velocity; a failed or oddly framed one is refused.
        let own = odometry(&pose(), &Attitude::level(0.0), 0, 100);
        assert!(velocity_from_odometry(&own).is_err());
        let failed = ODOMETRY_DATA {
            quality: -1,
            ..east.clone()
        };
        assert!(velocity_from_odometry(&failed).is_err());
        let odd = ODOMETRY_DATA {
            child_frame_id: MavFrame::MAV_FRAME_GLOBAL,
            ..east
        };
        let reason = velocity_from_odometry(&odd).expect_err("refused");
        assert!(reason.contains("MAV_FRAME_GLOBAL"), "{reason}");
    }

    #[test]
    fn heartbeat_is_an_onboard_controller_whose_state_follows_the_edge() {
        let h = heartbeat(EdgeState::Localized, Health::Ok);
        assert_eq!(h.mavtype, MavType::MAV_TYPE_ONBOARD_CONTROLLER);
        assert_eq!(h.autopilot, MavAutopilot::MAV_AUTOPILOT_INVALID);
        assert_eq!(h.system_status, MavState::MAV_STATE_ACTIVE);
        assert_eq!(h.mavlink_version, 3);
        let states = [
            (
                EdgeState::Initializing,
                Health::Ok,
                MavState::MAV_STATE_STANDBY,
            ),
            (
                EdgeState::Coasting,
                Health::Degraded,
                MavState::MAV_STATE_ACTIVE,
            ),
            (EdgeState::NoFix, Health::Ok, MavState::MAV_STATE_CRITICAL),
            (
                EdgeState::Localized,
                Health::Failed,
                MavState::MAV_STATE_CRITICAL,
            ),
        ];
        for (state, health, expected) in states {
            assert_eq!(
                heartbeat(state, health).system_status,
                expected,
                "{state:?}"
            );
        }
    }

    #[test]
    fn status_text_is_cut_to_fifty_bytes_on_a_character() {
        // One byte, then two-byte characters: byte 50 falls inside one.
        let t = status_text(
            MavSeverity::MAV_SEVERITY_WARNING,
            &format!("a{}", "é".repeat(40)),
        );
        let bytes: [u8; 50] = t.text.into();
        assert_eq!(bytes[49], 0, "the split character is left out");
        assert_eq!(std::str::from_utf8(&bytes[..49]).map(str::len), Ok(49));
    }

    #[test]
    fn global_position_carries_both_altitudes_and_health() {
        let g = global_position(&pose(), -12.5, true, 7);
        assert_eq!((g.lat, g.lon, g.time_usec), (305_205_123, 1_143_601_234, 7));
        assert_eq!((g.alt_ellipsoid, g.alt), (75.5, 88.0));
        assert!((g.eph - 3.0).abs() < 1e-6 && (g.epv - 3.0).abs() < 1e-6);
        assert_eq!(g.source, GlobalPositionSrc::GLOBAL_POSITION_SRC_VISION);
        assert!(g.flags.is_empty());
        let coasting = global_position(&pose(), 0.0, false, 7);
        assert_eq!(
            coasting.flags,
            GlobalPositionFlags::GLOBAL_POSITION_UNHEALTHY
        );
    }

    #[test]
    fn odometry_is_ned_with_the_covariance_rotated() {
        let o = odometry(&pose(), &Attitude::level(0.0), 0, 100);
        assert_eq!((o.x, o.y, o.z), (20.0, 10.0, -50.0));
        assert_eq!(o.pose_covariance[0], 5.0, "x is north");
        assert_eq!(o.pose_covariance[1], 1.0, "x-y");
        assert_eq!(o.pose_covariance[6], 4.0, "y is east");
        assert_eq!(o.pose_covariance[11], 9.0, "z");
        assert!((o.pose_covariance[20] - 0.01).abs() < 1e-9, "yaw");
        // ENU yaw pi/2 (facing north) is NED yaw 0: identity quaternion.
        assert!((o.q[0] - 1.0).abs() < 1e-6, "{:?}", o.q);
        assert!(o.vx.is_nan(), "velocity is not estimated");
        assert_eq!(o.quality, 100);
    }
}
