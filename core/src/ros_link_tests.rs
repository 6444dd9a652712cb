//! The ROS 2 / PX4 link on virtual time.

use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Vector3};
use towernav_geometry::{Attitude, Datum, Geodetic, geoid_height_m};
use towernav_protocol::ros2::msgs::nav_sat_status;
use towernav_protocol::{EdgeState, NodeId, PoseEstimate, PoseMethod};

use super::*;

const UNIX_START_US: u64 = 1_795_305_600_000_000;

fn datum() -> Datum {
    Datum::new(Geodetic::new(30.52, 114.36, 20.0).expect("a place"))
}

fn config() -> RosLinkConfig {
    RosLinkConfig {
        every: Duration::from_millis(100),
        ros2: true,
        px4_source_id: Some(1),
        fix: FixRules {
            fresh_fix: Duration::from_secs(1),
            coast_fix: Duration::from_secs(20),
            coast_max_sigma_m: 5.0,
            accel_sigma: 1.5,
        },
        map_frame: "map".into(),
        base_frame: "base_link".into(),
        roll_pitch_sigma_rad: 1f64.to_radians(),
    }
}

/// An estimate at `east` m heading north (yaw 90 degrees ENU), moving north at 10 m/s.
fn estimate(north: f64) -> LinkEstimate {
    let mut covariance = [[0.0; 4]; 4];
    covariance[0][0] = 4.0;
    covariance[1][1] = 1.0;
    covariance[0][1] = 0.5;
    covariance[1][0] = 0.5;
    covariance[2][2] = 9.0;
    covariance[3][3] = 0.01;
    covariance[0][3] = 0.02;
    covariance[3][0] = 0.02;
    let g = datum().to_geodetic(&nalgebra::Point3::new(0.0, north, 60.0));
    LinkEstimate {
        pose: PoseEstimate {
            uav: NodeId::new("uav1").expect("an id"),
            time_s: 0.0,
            seq: 0,
            east_m: 0.0,
            north_m: north,
            up_m: 60.0,
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
            alt_m: g.height_m,
            yaw_rad: std::f64::consts::FRAC_PI_2,
            covariance,
            method: PoseMethod::RaysEkf,
            towers_used: vec!["A1".into()],
            coast_s: 0.0,
        },
        attitude: Attitude {
            roll: 0.1,
            pitch: 0.0,
            yaw: 0.0,
        },
        velocity_in_world: Vector3::new(0.0, 10.0, 0.0),
        velocity_covariance: Matrix3::from_diagonal(&Vector3::new(0.25, 0.5, 0.1)),
    }
}

fn tick(link: &mut RosLink, now: Instant) -> Vec<RosOutput> {
    link.handle_timeout(now);
    std::iter::from_fn(|| link.poll_transmit()).collect()
}

#[test]
fn a_fresh_fix_goes_out_on_every_topic_in_ros_conventions() {
    let t0 = Instant::now();
    let mut link = RosLink::new(config(), datum(), t0, UNIX_START_US);
    link.handle_estimate(t0, Some(estimate(100.0)), EdgeState::Localized);
    let out = tick(&mut link, t0 + Duration::from_millis(500));
    assert_eq!(out.len(), 4, "{out:?}");
    let RosOutput::NavSatFix(fix) = &out[0] else {
        panic!("{out:?}")
    };
    assert_eq!(fix.status, nav_sat_status::STATUS_FIX);
    assert_eq!(
        fix.position_covariance_type,
        nav_sat_status::COVARIANCE_TYPE_KNOWN
    );
    assert_eq!(fix.header.stamp.sec as u64, UNIX_START_US / 1_000_000);
    assert_eq!(fix.header.stamp.nanosec, 500_000_000);
    // Predicted 0.5 s on at 10 m/s north: 105 m north of the datum.
    let expected = datum().to_geodetic(&nalgebra::Point3::new(0.0, 105.0, 60.0));
    assert!((fix.latitude - expected.lat_deg).abs() < 1e-9);
    // ENU covariance, grown by the velocity's: east 4 + 0.25 * 0.25 + accel.
    assert!(fix.position_covariance[0] > 4.06 && fix.position_covariance[0] < 4.1);
    assert_eq!(fix.position_covariance[1], fix.position_covariance[3]);

    let RosOutput::Pose(pose) = &out[1] else {
        panic!("{out:?}")
    };
    assert_eq!(pose.header.frame_id, "map");
    assert!((pose.pose.position[1] - 105.0).abs() < 1e-9);
    // Heading north, rolled right 0.1 rad: FLU's x points north.
    let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        pose.pose.orientation[3],
        pose.pose.orientation[0],
        pose.pose.orientation[1],
        pose.pose.orientation[2],
    ));
    let forward = q * Vector3::x();
    assert!((forward - Vector3::y()).norm() < 1e-9, "{forward}");
    let (roll, _, yaw) = q.euler_angles();
    assert!((roll - 0.1).abs() < 1e-9 && (yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    // Row-major 6x6: yaw's variance at rz, its cross term with east at (x, rz).
    let c = &pose.pose.covariance;
    assert_eq!((c[35], c[5], c[30]), (0.01, 0.02, 0.02));
    assert_eq!(c[21], 1f64.to_radians().powi(2));

    let RosOutput::Odometry(odom) = &out[2] else {
        panic!("{out:?}")
    };
    assert_eq!(odom.child_frame_id, "base_link");
    // 10 m/s north is forward in the body.
    assert!((odom.linear[0] - 10.0).abs() < 1e-9 && odom.linear[1].abs() < 1e-9);
    // North's variance (0.5) is the body's forward one.
    assert!((odom.twist_covariance[0] - 0.5).abs() < 1e-12);
    assert_eq!(odom.twist_covariance[35], UNMEASURED_VARIANCE);

    let RosOutput::Px4(px4) = &out[3] else {
        panic!("{out:?}")
    };
    assert!((px4.lat_deg - fix.latitude).abs() < 1e-12);
    let geoid = geoid_height_m(fix.latitude, fix.longitude);
    assert!((f64::from(px4.alt_amsl_m) - (fix.altitude - geoid)).abs() < 0.01);
    assert!(px4.eph_m > 2.0 && px4.eph_m < 2.2, "{}", px4.eph_m);
    // Up: 9 m^2, grown a little by the prediction.
    assert!((px4.epv_m - 3.0).abs() < 0.02, "{}", px4.epv_m);
    assert_eq!(px4.timestamp_sample_us, 0, "PX4's clock not seen yet");
}

#[test]
fn coasting_keeps_the_ros_fix_but_not_px4_s_and_past_the_limit_says_no_fix() {
    let t0 = Instant::now();
    let mut link = RosLink::new(config(), datum(), t0, UNIX_START_US);
    link.handle_estimate(t0, Some(estimate(0.0)), EdgeState::Localized);
    let at = |s: f64| t0 + Duration::from_secs_f64(s);
    // 2 s on: coasting within 5 m.
    let out = tick(&mut link, at(2.0));
    assert!(matches!(&out[0], RosOutput::NavSatFix(f) if f.status == nav_sat_status::STATUS_FIX));
    assert!(matches!(out[1], RosOutput::Pose(_)));
    assert!(matches!(&out[3], RosOutput::Px4(p) if p.lat_deg.is_nan() && p.eph_m.is_nan()));
    // 15 s on: the prediction's sigma is far past 5 m.
    let out = tick(&mut link, at(15.0));
    assert_eq!(out.len(), 2, "NavSatFix and PX4's only: {out:?}");
    let RosOutput::NavSatFix(fix) = &out[0] else {
        panic!("{out:?}")
    };
    assert_eq!(fix.status, nav_sat_status::STATUS_NO_FIX);
    assert!(fix.latitude.is_nan());
}

#[test]
fn a_fix_after_a_loss_counts_a_reset_for_px4() {
    let t0 = Instant::now();
    let mut link = RosLink::new(config(), datum(), t0, UNIX_START_US);
    let at = |s: f64| t0 + Duration::from_secs_f64(s);
    let px4 = |out: Vec<RosOutput>| match out.last() {
        Some(RosOutput::Px4(p)) => p.clone(),
        other => panic!("{other:?}"),
    };
    link.handle_estimate(at(0.0), Some(estimate(0.0)), EdgeState::Localized);
    assert_eq!(px4(tick(&mut link, at(0.1))).lat_lon_reset_counter, 0);
    link.handle_estimate(at(1.0), None, EdgeState::NoFix);
    assert!(px4(tick(&mut link, at(3.0))).lat_deg.is_nan());
    link.handle_estimate(at(4.0), Some(estimate(40.0)), EdgeState::Localized);
    let p = px4(tick(&mut link, at(4.1)));
    assert!(p.lat_deg.is_finite());
    assert_eq!(p.lat_lon_reset_counter, 1);
    assert_eq!(px4(tick(&mut link, at(4.3))).lat_lon_reset_counter, 1);
}

#[test]
fn px4_s_clock_is_its_stamps_plus_the_least_latency_and_a_reboot_resets_it() {
    let t0 = Instant::now();
    let mut link = RosLink::new(config(), datum(), t0, UNIX_START_US);
    let at = |s: f64| t0 + Duration::from_secs_f64(s);
    // PX4 booted 100 s before t0; its messages arrive 20 ms, then 5 ms, late.
    link.handle_px4_time(at(1.0), 101_000_000 - 20_000);
    link.handle_px4_time(at(1.1), 101_100_000 - 5_000);
    link.handle_px4_time(at(1.2), 101_200_000 - 30_000);
    let t = link.px4_time_us(at(2.0)).expect("seen");
    assert!(
        (102_000_000 - 5_500..=102_000_000 - 4_500).contains(&t),
        "{t}"
    );
    // Rebooted: its clock restarts near zero.
    link.handle_px4_time(at(3.0), 2_000_000);
    let t = link.px4_time_us(at(3.5)).expect("seen");
    assert!((2_400_000..=2_600_000).contains(&t), "{t}");
    link.handle_estimate(at(3.5), Some(estimate(0.0)), EdgeState::Localized);
    let out = tick(&mut link, at(3.5));
    assert!(matches!(out.last(), Some(RosOutput::Px4(p)) if p.timestamp_sample_us == t));
}

#[test]
fn ros_2_alone_sends_no_px4_message_and_px4_alone_no_ros_topic() {
    let t0 = Instant::now();
    let mut ros_only = RosLink::new(
        RosLinkConfig {
            px4_source_id: None,
            ..config()
        },
        datum(),
        t0,
        UNIX_START_US,
    );
    assert!(matches!(
        tick(&mut ros_only, t0)[..],
        [RosOutput::NavSatFix(_)]
    ));
    let mut px4_only = RosLink::new(
        RosLinkConfig {
            ros2: false,
            ..config()
        },
        datum(),
        t0,
        UNIX_START_US,
    );
    assert!(matches!(tick(&mut px4_only, t0)[..], [RosOutput::Px4(_)]));
    // Not due again until a period on.
    assert!(tick(&mut px4_only, t0 + Duration::from_millis(50)).is_empty());
}
