//! The autopilot link on virtual time: a clock of `Instant`s the test moves.

use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    GLOBAL_POSITION_INT_DATA, GPS_INPUT_DATA, GpsFixType, MavMessage, SYSTEM_TIME_DATA,
    TIMESYNC_DATA,
};
use nalgebra::{Matrix3, Vector3};
use towernav_geometry::{Attitude, Datum, Geodetic, geoid_height_m};
use towernav_protocol::{EdgeState, NodeId, PoseEstimate, PoseMethod};

use super::*;

const UNIX_START_US: u64 = 1_795_305_600_000_000;

fn datum() -> Datum {
    Datum::new(Geodetic::new(30.52, 114.36, 20.0).expect("a place"))
}

fn link(config: LinkConfig, start: Instant) -> AutopilotLink {
    AutopilotLink::new(config, datum(), start, UNIX_START_US)
}

/// An estimate at `east` m, 2 m sigma, moving east at 10 m/s.
fn estimate(east: f64, towers: &[&str]) -> LinkEstimate {
    let mut covariance = [[0.0; 4]; 4];
    covariance[0][0] = 2.0;
    covariance[1][1] = 2.0;
    covariance[2][2] = 4.0;
    covariance[3][3] = 0.01;
    let g = datum().to_geodetic(&nalgebra::Point3::new(east, 0.0, 60.0));
    LinkEstimate {
        pose: PoseEstimate {
            uav: NodeId::new("uav1").expect("an id"),
            time_s: 0.0,
            seq: 0,
            east_m: east,
            north_m: 0.0,
            up_m: 60.0,
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
            alt_m: g.height_m,
            yaw_rad: 0.0,
            covariance,
            method: PoseMethod::RaysEkf,
            towers_used: towers.iter().map(|t| t.to_string()).collect(),
            coast_s: 0.0,
        },
        attitude: Attitude::level(0.0),
        velocity_in_world: Vector3::new(10.0, 0.0, 0.0),
        velocity_covariance: Matrix3::identity() * 0.25,
    }
}

fn drain(link: &mut AutopilotLink) -> Vec<MavMessage> {
    std::iter::from_fn(|| link.poll_transmit()).collect()
}

/// Fires the link's timer whenever it is due between `from` and `to`, as
/// the shell does, and collects what it sends.
fn run_timer(link: &mut AutopilotLink, from: Instant, to: Instant) -> Vec<MavMessage> {
    let mut sent = Vec::new();
    let mut now = from;
    while now < to {
        now = link.poll_timeout().max(now);
        if now >= to {
            break;
        }
        link.handle_timeout(now);
        sent.extend(drain(link));
    }
    sent
}

fn gps(messages: &[MavMessage]) -> Vec<&GPS_INPUT_DATA> {
    messages
        .iter()
        .filter_map(|m| match m {
            MavMessage::GPS_INPUT(g) => Some(g),
            _ => None,
        })
        .collect()
}

fn count(messages: &[MavMessage], name: &str) -> usize {
    messages
        .iter()
        .filter(|m| mavlink::Message::message_name(*m) == name)
        .count()
}

#[test]
fn heartbeat_and_no_fix_keep_going_with_no_estimate_at_all() {
    let start = Instant::now();
    let mut link = link(LinkConfig::default(), start);
    let sent = run_timer(&mut link, start, start + Duration::from_secs(10));
    assert_eq!(count(&sent, "HEARTBEAT"), 10, "1 Hz");
    let fixes = gps(&sent);
    assert_eq!(fixes.len(), 50, "5 Hz");
    assert!(
        fixes
            .iter()
            .all(|g| g.fix_type == GpsFixType::GPS_FIX_TYPE_NO_FIX)
    );
    assert_eq!(
        count(&sent, "STATUSTEXT"),
        0,
        "no fix to begin with is no change"
    );
}

#[test]
fn the_fix_is_3d_when_fresh_2d_coasting_and_none_when_lost_each_change_told() {
    let start = Instant::now();
    let at = |s: f64| start + Duration::from_secs_f64(s);
    let config = LinkConfig {
        coast_fix: Duration::from_secs(5),
        ..LinkConfig::default()
    };
    let mut link = link(config, start);
    link.handle_estimate(
        at(0.0),
        Some(estimate(0.0, &["T1", "T2"])),
        EdgeState::Localized,
    );
    assert_eq!(link.fix_type(at(0.5)), GpsFixType::GPS_FIX_TYPE_3D_FIX);
    // Frames keep coming, without towers: the filter coasts.
    for i in 1..=20 {
        let t = 0.5 * f64::from(i);
        link.handle_estimate(at(t), Some(estimate(10.0 * t, &[])), EdgeState::Coasting);
    }
    assert_eq!(link.fix_type(at(1.5)), GpsFixType::GPS_FIX_TYPE_2D_FIX);
    assert_eq!(
        link.fix_type(at(5.5)),
        GpsFixType::GPS_FIX_TYPE_NO_FIX,
        "past coast_fix"
    );
    let mut sent = drain(&mut link);
    // The filter gives up: lost.
    link.handle_estimate(at(10.5), None, EdgeState::NoFix);
    let lost = run_timer(&mut link, at(10.5), at(12.0));
    assert!(
        gps(&lost)
            .iter()
            .all(|g| g.fix_type == GpsFixType::GPS_FIX_TYPE_NO_FIX)
    );
    assert!(gps(&lost).len() >= 7, "still at 5 Hz");
    sent.extend(lost);
    // Towers again.
    link.handle_estimate(
        at(12.0),
        Some(estimate(120.0, &["T3", "T4"])),
        EdgeState::Localized,
    );
    sent.extend(drain(&mut link));
    let texts: Vec<String> = sent
        .iter()
        .filter_map(|m| match m {
            MavMessage::STATUSTEXT(t) => Some(t.text.to_str().unwrap_or("").to_string()),
            _ => None,
        })
        .collect();
    assert_eq!(
        texts,
        [
            "towernav: 3D fix from towers",
            "towernav: coasting, no tower fix",
            "towernav: position lost",
            "towernav: 3D fix from towers"
        ]
    );
}

#[test]
fn a_stalled_camera_degrades_the_fix_with_time_alone() {
    let start = Instant::now();
    let at = |s: f64| start + Duration::from_secs_f64(s);
    let mut link = link(LinkConfig::default(), start);
    link.handle_estimate(
        at(0.0),
        Some(estimate(0.0, &["T1", "T2"])),
        EdgeState::Localized,
    );
    // No frame for 8 s: the timer alone carries the fix down.
    let sent = run_timer(&mut link, at(0.0), at(8.0));
    let fixes = gps(&sent);
    let kind = |t: f64| fixes[(t * 5.0) as usize].fix_type;
    assert_eq!(kind(0.4), GpsFixType::GPS_FIX_TYPE_3D_FIX);
    assert_eq!(kind(1.5), GpsFixType::GPS_FIX_TYPE_2D_FIX);
    assert_eq!(kind(7.0), GpsFixType::GPS_FIX_TYPE_NO_FIX);
    // Coasting, the reported accuracy grows with the predicted covariance,
    // and the fix is dropped once the prediction's 1-sigma passes 5 m,
    // long before the 20 s time limit.
    let coasting: Vec<&&GPS_INPUT_DATA> = fixes[1..]
        .iter()
        .take_while(|g| g.fix_type != GpsFixType::GPS_FIX_TYPE_NO_FIX)
        .collect();
    let h: Vec<f32> = coasting.iter().map(|g| g.horiz_accuracy).collect();
    assert!(h.len() > 10 && h.windows(2).all(|w| w[1] > w[0]), "{h:?}");
    let last = f64::from(*h.last().expect("coasted"));
    assert!((5.0..7.5).contains(&last), "dropped at {last} m (2-D RMS)");
    assert!(
        (fixes[0].horiz_accuracy - 2.0).abs() < 1e-3,
        "sqrt(2 + 2) at the fix"
    );
}

#[test]
fn gps_input_altitude_is_above_mean_sea_level() {
    let start = Instant::now();
    let mut link = link(LinkConfig::default(), start);
    let e = estimate(0.0, &["T1", "T2"]);
    let (lat, lon, h) = (e.pose.lat_deg, e.pose.lon_deg, e.pose.alt_m);
    link.handle_estimate(start, Some(e), EdgeState::Localized);
    link.handle_timeout(start);
    let sent = drain(&mut link);
    let g = gps(&sent)[0];
    let msl = h - geoid_height_m(lat, lon);
    assert!((f64::from(g.alt) - msl).abs() < 0.01, "{} vs {msl}", g.alt);
    assert!((h - msl).abs() > 5.0, "the geoid matters here");
}

#[test]
fn odometry_predicts_between_frames_at_its_own_rate() {
    let start = Instant::now();
    let at = |s: f64| start + Duration::from_secs_f64(s);
    let config = LinkConfig {
        position: None,
        odometry_every: Some(Duration::from_secs_f64(1.0 / 30.0)),
        ..LinkConfig::default()
    };
    let mut link = link(config, start);
    link.handle_estimate(
        at(0.0),
        Some(estimate(0.0, &["T1", "T2"])),
        EdgeState::Localized,
    );
    let sent = run_timer(&mut link, at(0.0), at(1.0));
    let odometry: Vec<_> = sent
        .iter()
        .filter_map(|m| match m {
            MavMessage::ODOMETRY(o) => Some(o),
            _ => None,
        })
        .collect();
    // 30 Hz from one fix (a 31st at 1 s less the period's rounding).
    assert!((30..=31).contains(&odometry.len()), "{}", odometry.len());
    // NED: y is east; 10 m/s east.
    let last = odometry[29];
    assert!((last.y - 10.0 * 29.0 / 30.0).abs() < 0.05, "{}", last.y);
    assert_eq!(last.quality, 100);
    assert!(odometry.windows(2).all(|w| w[1].time_usec > w[0].time_usec));
}

#[test]
fn timesync_is_answered_and_system_time_sets_the_clock() {
    let start = Instant::now();
    let mut link = link(LinkConfig::default(), start);
    let later = start + Duration::from_millis(1500);
    link.handle_message(
        later,
        (1, 1),
        &MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1: 42,
            ..TIMESYNC_DATA::DEFAULT
        }),
    );
    let reply = drain(&mut link);
    let MavMessage::TIMESYNC(t) = &reply[0] else {
        panic!("{reply:?}");
    };
    assert_eq!(t.ts1, 42, "the request's own stamp comes back");
    assert_eq!(
        (t.target_system, t.target_component),
        (1, 1),
        "to its sender"
    );
    assert_eq!(t.tc1, ((UNIX_START_US + 1_500_000) * 1000) as i64);
    // An autopilot with GNSS time resets ours; one without (0) does not.
    link.handle_message(
        later,
        (1, 1),
        &MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: 0,
            time_boot_ms: 9,
        }),
    );
    assert_eq!(link.unix_us(later), UNIX_START_US + 1_500_000);
    link.handle_message(
        later,
        (1, 1),
        &MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: UNIX_START_US + 10_000_000,
            time_boot_ms: 9,
        }),
    );
    assert_eq!(
        link.unix_us(later + Duration::from_secs(1)),
        UNIX_START_US + 11_000_000
    );
}

#[test]
fn the_autopilot_s_own_position_is_kept_when_it_has_one() {
    let start = Instant::now();
    let mut link = link(LinkConfig::default(), start);
    let position = |lat, lon| {
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            lat,
            lon,
            alt: 35_500,
            hdg: 9000,
            ..GLOBAL_POSITION_INT_DATA::DEFAULT
        })
    };
    link.handle_message(start, (1, 1), &position(0, 0));
    assert!(
        link.autopilot_position().is_none(),
        "zeros before a GNSS fix"
    );
    link.handle_message(start, (1, 1), &position(305_200_000, 1_143_600_000));
    let p = link.autopilot_position().expect("kept");
    assert!((p.lat_deg - 30.52).abs() < 1e-9 && (p.alt_msl_m - 35.5).abs() < 1e-9);
    assert!((p.heading_rad.unwrap_or(0.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    let n = geoid_height_m(p.lat_deg, p.lon_deg);
    assert!(
        (p.height_m - (35.5 + n)).abs() < 1e-6,
        "ellipsoidal through the geoid"
    );
}

#[test]
fn the_autopilot_s_system_id_is_learned_from_its_heartbeat() {
    use mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot};

    let start = Instant::now();
    let mut link = link(LinkConfig::default(), start);
    let beat = |autopilot| {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            autopilot,
            ..HEARTBEAT_DATA::DEFAULT
        })
    };
    // Another onboard component (a camera, say) is not the autopilot.
    link.handle_message(start, (7, 100), &beat(MavAutopilot::MAV_AUTOPILOT_INVALID));
    assert_eq!(link.autopilot_system(), None);
    link.handle_message(start, (2, 1), &beat(MavAutopilot::MAV_AUTOPILOT_PX4));
    assert_eq!(link.autopilot_system(), Some(2));
}
