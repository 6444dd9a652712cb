//! The daemon core on virtual time: a clock made of `Instant`s the test moves.

use std::time::{Duration, Instant};

use nalgebra::Point3;
use towernav_geometry::{Attitude, PinholeCamera};
use towernav_protocol::{Detection, Health, IdCorrection, NodeId, PoseMethod};

use super::*;
use crate::fixtures::{map, tower};
use crate::pipeline::{Pipeline, PipelineConfig};

fn core(start: Instant, preview_every: Option<Duration>) -> DaemonCore {
    let towers = map(vec![
        tower("T1", 100.0, 0.0, 40.0),
        tower("T2", 300.0, 0.0, 40.0),
    ]);
    let datum = *towers.datum();
    let pipeline = Pipeline::new(
        PipelineConfig::new(PinholeCamera::default_hd(), Point3::origin()),
        towers,
    );
    DaemonCore::new(
        DaemonConfig {
            uav: NodeId::new("uav1").expect("an id"),
            datum,
            method: PoseMethod::RaysEkf,
            detector: "oracle".into(),
            preview_every,
            session: 41,
        },
        pipeline,
        start,
    )
}

fn frame(seq: u64, at: Instant, start: Instant) -> DetectedFrame {
    DetectedFrame {
        seq,
        time_s: (at - start).as_secs_f64(),
        captured: at,
        attitude: Attitude::default(),
        detections: Vec::new(),
        has_image: true,
        barometric_height_m: None,
    }
}

fn drain(core: &mut DaemonCore) -> Vec<Output> {
    std::iter::from_fn(|| core.poll_output()).collect()
}

/// Drives `core` as the shell does, from `from` to `to`: frames every
/// `frame_every` (none when `None`), and the timer whenever it is due.
fn run(
    core: &mut DaemonCore,
    start: Instant,
    from: Duration,
    to: Duration,
    frame_every: Option<Duration>,
    seq: &mut u64,
) -> Vec<Output> {
    let mut out = Vec::new();
    let mut now = start + from;
    let mut next_frame = frame_every.map(|_| now);
    while now < start + to {
        let timer = core.poll_timeout();
        now = match next_frame {
            Some(f) if f <= timer => f,
            _ => timer,
        };
        if now >= start + to {
            break;
        }
        if next_frame == Some(now) {
            core.handle_frame(now, frame(*seq, now, start));
            *seq += 1;
            next_frame = frame_every.map(|every| now + every);
        }
        core.handle_timeout(now, SourceCounters::default());
        out.extend(drain(core));
    }
    out
}

fn statuses(outputs: &[Output]) -> Vec<&towernav_protocol::StatusHeartbeat> {
    outputs
        .iter()
        .filter_map(|o| match o {
            Output::Status(s) => Some(s),
            _ => None,
        })
        .collect()
}

#[test]
fn a_ten_second_camera_stall_still_beats_acks_and_takes_landmarks() {
    let start = Instant::now();
    let mut core = core(start, None);
    let mut seq = 0;
    let flying = run(
        &mut core,
        start,
        Duration::ZERO,
        Duration::from_millis(2050),
        Some(Duration::from_millis(100)),
        &mut seq,
    );
    assert_eq!(statuses(&flying).len(), 2);
    assert!(statuses(&flying).iter().all(|s| s.health == Health::Ok));
    let frames = core.frames();

    // The camera stops; the operator corrects twice and the landmarks change.
    let stalled_at = start + Duration::from_millis(2050);
    core.handle_command(
        stalled_at + Duration::from_secs(3),
        Command::Correct(IdCorrection {
            uav: NodeId::new("uav1").expect("an id"),
            request_id: 7,
            track_id: 99,
            tower_id: Some("T1".into()),
            issued_by: "operator".into(),
            release: false,
            session: None,
        }),
    );
    let acks: Vec<_> = drain(&mut core)
        .into_iter()
        .filter_map(|o| match o {
            Output::Ack(a) => Some(a),
            _ => None,
        })
        .collect();
    assert_eq!(acks.len(), 1, "the ack goes out at once, with no frame");
    assert_eq!(acks[0].request_id, 7);
    assert!(!acks[0].accepted, "no track 99 exists: {:?}", acks[0]);
    // A correction picked in another run of the edge is refused, saying why.
    core.handle_command(
        stalled_at + Duration::from_secs(3),
        Command::Correct(IdCorrection {
            uav: NodeId::new("uav1").expect("an id"),
            request_id: 8,
            track_id: 1,
            tower_id: Some("T1".into()),
            issued_by: "operator".into(),
            release: false,
            session: Some(40),
        }),
    );
    let refused: Vec<_> = drain(&mut core)
        .into_iter()
        .filter_map(|o| match o {
            Output::Ack(a) => Some(a),
            _ => None,
        })
        .collect();
    assert!(!refused[0].accepted);
    let reason = refused[0].reason.as_deref().unwrap_or_default();
    assert!(reason.contains("earlier run"), "{reason}");
    core.handle_command(
        stalled_at + Duration::from_secs(4),
        Command::ReplaceMap(map(vec![tower("T3", 200.0, 50.0, 35.0)])),
    );
    assert_eq!(core.pipeline().map().towers.len(), 1);

    let stall = run(
        &mut core,
        start,
        Duration::from_millis(2050),
        Duration::from_millis(12_050),
        None,
        &mut seq,
    );
    let beats = statuses(&stall);
    assert_eq!(beats.len(), 10, "one status a second through the stall");
    assert_eq!(core.frames(), frames);
    assert!(beats.iter().all(|s| s.frames_processed == frames));
    assert!(beats.iter().all(|s| s.health != Health::Ok), "{beats:?}");
    assert_eq!(beats.last().map(|s| s.health), Some(Health::Failed));
    assert_eq!(beats.last().map(|s| s.landmarks_loaded), Some(1));
}

#[test]
fn every_frame_sends_tracks_and_detections_and_previews_are_paced() {
    let start = Instant::now();
    let mut core = core(start, Some(Duration::from_millis(500)));
    let mut seq = 0;
    let out = run(
        &mut core,
        start,
        Duration::ZERO,
        Duration::from_millis(1990),
        Some(Duration::from_millis(100)),
        &mut seq,
    );
    let count = |f: fn(&Output) -> bool| out.iter().filter(|o| f(o)).count();
    assert_eq!(count(|o| matches!(o, Output::Tracks(_))), 20);
    assert_eq!(count(|o| matches!(o, Output::Detections(_))), 20);
    assert_eq!(count(|o| matches!(o, Output::Preview { .. })), 4);
    assert_eq!(core.latency_count(), 20);
}

#[test]
fn a_late_timer_sends_one_status_not_a_burst() {
    let start = Instant::now();
    let mut core = core(start, None);
    core.handle_timeout(start + Duration::from_secs(5), SourceCounters::default());
    assert_eq!(statuses(&drain(&mut core)).len(), 1);
    assert!(core.poll_timeout() > start + Duration::from_secs(5));
}

#[test]
fn drops_since_the_last_status_degrade_health() {
    let start = Instant::now();
    let mut core = core(start, None);
    let mut seq = 0;
    run(
        &mut core,
        start,
        Duration::ZERO,
        Duration::from_millis(1050),
        Some(Duration::from_millis(100)),
        &mut seq,
    );
    let now = start + Duration::from_millis(1100);
    core.handle_frame(now, frame(seq, now, start));
    let at = core.poll_timeout();
    core.handle_timeout(
        at,
        SourceCounters {
            dropped: 3,
            failed: 0,
        },
    );
    let out = drain(&mut core);
    let beats = statuses(&out);
    assert_eq!(beats.len(), 1);
    assert_eq!(beats[0].health, Health::Degraded);
    assert_eq!(beats[0].frames_dropped, 3);
}

#[test]
fn percentiles_of_nothing_are_zero() {
    assert_eq!(percentiles(&mut []), (0.0, 0.0));
    let mut v = [3.0, 1.0, 2.0];
    assert_eq!(percentiles(&mut v), (2.0, 3.0));
}

#[test]
fn whole_run_latency_percentiles_hold_in_fixed_memory() {
    let start = Instant::now();
    let mut core = core(start, None);
    assert_eq!(core.latency_percentiles(), (0.0, 0.0));
    // Frames handled 1, 2, ... 100 ms after their capture.
    for k in 1..=100u64 {
        let captured = start + Duration::from_secs(k);
        core.handle_frame(
            captured + Duration::from_millis(k),
            frame(k, captured, start),
        );
    }
    let (p50, p99) = core.latency_percentiles();
    assert!((p50 - 50.0).abs() <= 0.5, "{p50}");
    assert!((p99 - 99.0).abs() <= 1.0, "{p99}");
    assert_eq!(core.latency_count(), 100);
}

/// The test core with a MAVLink link on the default settings.
fn core_with_autopilot(start: Instant) -> DaemonCore {
    use crate::autopilot_link::{AutopilotLink, LinkConfig};

    let core = core(start, None);
    let datum = core.config.datum;
    core.with_autopilot(AutopilotLink::new(
        LinkConfig::default(),
        datum,
        start,
        1_795_305_600_000_000,
    ))
}

#[test]
fn the_autopilot_s_barometric_height_reaches_the_pipeline_altitude_first() {
    use mavlink::dialects::common::{ALTITUDE_DATA, GLOBAL_POSITION_INT_DATA, MavMessage};

    let start = Instant::now();
    let mut core = core_with_autopilot(start);
    let position = |relative_mm| Command::FromAutopilot {
        from: (1, 1),
        message: MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            relative_alt: relative_mm,
            ..GLOBAL_POSITION_INT_DATA::DEFAULT
        }),
    };
    core.handle_command(start, position(31_500));
    assert_eq!(core.pipeline().barometer().map(|b| b.1), Some(31.5));
    core.handle_command(
        start,
        Command::FromAutopilot {
            from: (1, 1),
            message: MavMessage::ALTITUDE(ALTITUDE_DATA {
                altitude_relative: 29.0,
                ..ALTITUDE_DATA::DEFAULT
            }),
        },
    );
    assert_eq!(core.pipeline().barometer().map(|b| b.1), Some(29.0));
    // Once ALTITUDE comes, GLOBAL_POSITION_INT's fused height is not taken.
    core.handle_command(start, position(50_000));
    assert_eq!(core.pipeline().barometer().map(|b| b.1), Some(29.0));
}

#[test]
fn the_autopilot_s_gnss_position_starts_the_pipeline_where_the_uav_is() {
    use mavlink::dialects::common::{GLOBAL_POSITION_INT_DATA, MavMessage};

    let start = Instant::now();
    let mut core = core_with_autopilot(start);
    let datum = core.config.datum;
    assert!(
        core.pipeline().predicted_position(0.0).is_none(),
        "nothing known yet"
    );
    // 200 m east of the datum, 40 m above it (MSL from the geoid).
    let place = datum.to_geodetic(&Point3::new(200.0, 0.0, 40.0));
    let msl = place.height_m - towernav_geometry::geoid_height_m(place.lat_deg, place.lon_deg);
    core.handle_command(
        start,
        Command::FromAutopilot {
            from: (1, 1),
            message: MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
                lat: (place.lat_deg * 1e7).round() as i32,
                lon: (place.lon_deg * 1e7).round() as i32,
                alt: (msl * 1e3).round() as i32,
                hdg: u16::MAX,
                ..GLOBAL_POSITION_INT_DATA::DEFAULT
            }),
        },
    );
    let p = core.pipeline().predicted_position(0.0).expect("hinted");
    assert!((p - Point3::new(200.0, 0.0, 40.0)).norm() < 0.05, "{p}");
    // And it goes out for the survey record.
    let recorded = drain(&mut core).into_iter().find_map(|o| match o {
        Output::AutopilotPosition(p) => Some(p),
        _ => None,
    });
    let recorded = recorded.expect("recorded");
    assert!((recorded.height_m - place.height_m).abs() < 0.01);
    assert_eq!(recorded.frame_seq, None, "no frame yet");
}

#[test]
fn with_an_autopilot_link_the_core_beats_mavlink_through_a_camera_stall() {
    let start = Instant::now();
    let mut core = core_with_autopilot(start);
    let mut seq = 0;
    let outputs = run(
        &mut core,
        start,
        Duration::ZERO,
        Duration::from_secs(10),
        None,
        &mut seq,
    );
    let mavlink: Vec<&str> = outputs
        .iter()
        .filter_map(|o| match o {
            Output::Mavlink(m) => Some(mavlink::Message::message_name(m)),
            _ => None,
        })
        .collect();
    let count = |name: &str| mavlink.iter().filter(|n| **n == name).count();
    assert_eq!(count("HEARTBEAT"), 10);
    assert_eq!(count("GPS_INPUT"), 50);
}

/// The fixture's towers as an ideal detector boxes them from `pose`.
fn boxes_seen_from(core: &DaemonCore, pose: &towernav_geometry::Pose) -> Vec<Detection> {
    let pipeline = core.pipeline();
    let camera = pipeline.config().camera;
    let camera_from_world = camera.world_from_camera(pose).inverse();
    pipeline
        .map()
        .towers
        .iter()
        .filter_map(|t| {
            let foot = camera.project(&(camera_from_world * t.foot_in_world))?;
            let top = camera.project(&(camera_from_world * t.top_in_world()))?;
            let half_width = 0.1 * (foot.y - top.y);
            Some(Detection {
                bbox: towernav_geometry::PixelBox::new(
                    foot.x - half_width,
                    top.y,
                    foot.x + half_width,
                    foot.y,
                ),
                tower_type: t.tower_type,
                score: 0.9,
            })
        })
        .collect()
}

/// Hovers 20 m up with both towers in view for two seconds, then loses them
/// for one, while a flow sensor 10 m above the ground (when `flow_mps` is
/// given) reports that speed forward (east) 30 times a second; returns the
/// estimate's east velocity at the end.
fn east_velocity_after_a_gap(flow_mps: Option<f64>) -> f64 {
    use mavlink::dialects::common::{MavMessage, OPTICAL_FLOW_RAD_DATA};

    let start = Instant::now();
    let mut core = core_with_autopilot(start);
    let pose = towernav_geometry::Pose {
        position_in_world: Point3::new(0.0, 0.0, 20.0),
        attitude: Attitude::level(0.0),
    };
    let seen = boxes_seen_from(&core, &pose);
    assert_eq!(seen.len(), 2, "both towers in view");
    let dt = 1.0 / 30.0;
    for seq in 0..90u64 {
        let at = start + Duration::from_secs_f64(seq as f64 * dt);
        let mut f = frame(seq, at, start);
        if seq < 60 {
            f.detections = seen.clone();
        }
        core.handle_frame(at, f);
        if let (Some(v), true) = (flow_mps, seq >= 60) {
            // Forward motion is flow about the sensor's Y axis.
            let message = MavMessage::OPTICAL_FLOW_RAD(OPTICAL_FLOW_RAD_DATA {
                integration_time_us: (dt * 1e6) as u32,
                integrated_y: (v * dt / 10.0) as f32,
                distance: 10.0,
                quality: 255,
                ..OPTICAL_FLOW_RAD_DATA::DEFAULT
            });
            core.handle_command(
                at,
                Command::FromAutopilot {
                    from: (1, 158),
                    message,
                },
            );
        }
        drain(&mut core);
    }
    let estimate = core
        .last_output()
        .and_then(|o| o.estimate.as_ref())
        .expect("still coasting");
    assert!(!estimate.updated, "no tower in the last second");
    estimate.velocity_in_world.x
}

#[test]
fn an_optical_flow_sensor_s_velocity_carries_the_coast() {
    let still = east_velocity_after_a_gap(None);
    let moving = east_velocity_after_a_gap(Some(2.0));
    assert!(still.abs() < 0.3, "hovering: {still}");
    assert!((moving - 2.0).abs() < 0.3, "the flow's 2 m/s: {moving}");
}

#[test]
fn a_repeated_correction_is_answered_again_and_not_applied_twice() {
    use crate::fixtures::det;
    let start = Instant::now();
    let mut core = core(start, None);
    // One tower box, frame after frame: a live track.
    let seen = |core: &mut DaemonCore, seq: u64| -> Vec<Output> {
        let at = start + Duration::from_millis(33 * seq);
        let mut f = frame(seq, at, start);
        f.detections = vec![det(600.0, towernav_protocol::TowerType::B, 0.9)];
        core.handle_frame(at, f);
        drain(core)
    };
    let mut outputs = Vec::new();
    for seq in 0..5 {
        outputs = seen(&mut core, seq);
    }
    let track = outputs
        .iter()
        .find_map(|o| match o {
            Output::Tracks(t) => t.tracks.first().map(|t| t.track_id),
            _ => None,
        })
        .expect("a live track");
    let correction = |request_id: u64, release: bool| {
        Command::Correct(IdCorrection {
            uav: NodeId::new("uav1").expect("an id"),
            request_id,
            track_id: track,
            tower_id: Some("T1".into()),
            issued_by: "operator".into(),
            release,
            session: None,
        })
    };
    let acks = |outputs: Vec<Output>| -> Vec<CorrectionAck> {
        outputs
            .into_iter()
            .filter_map(|o| match o {
                Output::Ack(a) => Some(a),
                _ => None,
            })
            .collect()
    };
    let pinned = |outputs: &[Output]| {
        outputs.iter().find_map(|o| match o {
            Output::Tracks(t) => t
                .tracks
                .iter()
                .find(|t| t.track_id == track)
                .map(|t| t.pinned),
            _ => None,
        })
    };
    core.handle_command(start, correction(11, false));
    let first = acks(drain(&mut core));
    assert!(first[0].accepted, "{first:?}");
    assert_eq!(pinned(&seen(&mut core, 5)), Some(true));
    core.handle_command(start, correction(12, true));
    assert!(acks(drain(&mut core))[0].accepted);
    assert_eq!(pinned(&seen(&mut core, 6)), Some(false), "released");
    // 11 again, after 12: the same answer, and the release stands.
    core.handle_command(start, correction(11, false));
    assert_eq!(acks(drain(&mut core)), first, "answered as before");
    assert_eq!(pinned(&seen(&mut core, 7)), Some(false), "not pinned again");
    // A new request id is a new correction.
    core.handle_command(start, correction(13, false));
    assert!(acks(drain(&mut core))[0].accepted);
    assert_eq!(pinned(&seen(&mut core, 8)), Some(true));
}

#[test]
fn through_a_gap_predicted_poses_go_out_at_the_frame_rate_marked_as_coasting() {
    let start = Instant::now();
    let mut core = core(start, None);
    let pose = towernav_geometry::Pose {
        position_in_world: Point3::new(0.0, 0.0, 20.0),
        attitude: Attitude::level(0.0),
    };
    let seen = boxes_seen_from(&core, &pose);
    assert_eq!(seen.len(), 2, "both towers in view");
    let mut poses = Vec::new();
    // Two seconds with both towers, then none for a minute, at 30 frames/s.
    for seq in 0..(62 * 30u64) {
        let at = start + Duration::from_secs_f64(seq as f64 / 30.0);
        let mut f = frame(seq, at, start);
        if seq < 60 {
            f.detections = seen.clone();
        }
        core.handle_frame(at, f);
        poses.extend(drain(&mut core).into_iter().filter_map(|o| match o {
            Output::Pose { pose, state, .. } => Some((pose, state)),
            _ => None,
        }));
    }
    let (fixed, coasting): (Vec<_>, Vec<_>) = poses.iter().partition(|(p, _)| p.seq < 60);
    assert!(fixed.len() >= 50, "{} fixes", fixed.len());
    assert!(
        fixed.iter().all(|(p, s)| p.coast_s == 0.0
            && p.towers_used.len() == 2
            && *s == EdgeState::Localized)
    );
    // Every frame of the gap has its pose until the covariance passes the
    // bound, each a prediction that says so, its covariance growing.
    assert!(coasting.len() > 30, "{} predicted poses", coasting.len());
    assert!(
        coasting
            .windows(2)
            .all(|w| w[1].0.seq == w[0].0.seq + 1 && w[1].0.coast_s > w[0].0.coast_s),
        "one per frame, the coast growing"
    );
    assert!(
        coasting
            .iter()
            .all(|(p, s)| p.is_coasting() && p.towers_used.is_empty() && *s == EdgeState::Coasting)
    );
    let variance = |p: &PoseEstimate| p.covariance[0][0] + p.covariance[1][1];
    let (first, last) = (&coasting[0].0, &coasting[coasting.len() - 1].0);
    assert!(
        (first.coast_s - 1.0 / 30.0).abs() < 1e-6,
        "{}",
        first.coast_s
    );
    assert!(variance(last) > 4.0 * variance(first));
    assert!(
        last.seq < 61 * 30,
        "published until the bound, not for ever"
    );
}
