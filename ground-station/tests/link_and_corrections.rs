//! The ground station when a UAV stops talking, driven through egui_kittest:
//! the loss is loud everywhere the UAV is drawn, and a correction sent into
//! the silence ends in "no answer" with resend and cancel, never "pending"
//! forever.

use std::cell::Cell;
use std::rc::Rc;

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use towernav_ground_station::app::GsApp;
use towernav_ground_station::events::NetEvent;
use towernav_ground_station::net::NetCommand;
use towernav_ground_station::test_support::{app, frame_events, pose};
use towernav_protocol::{CorrectionAck, EdgeState, Health, IdCorrection, NodeId, StatusHeartbeat};

fn harness(app: GsApp, now: Rc<Cell<f64>>) -> Harness<'static, GsApp> {
    Harness::builder()
        .with_size([1600.0, 900.0])
        .build_ui_state(move |ui, app: &mut GsApp| app.show(ui, now.get()), app)
}

fn status() -> StatusHeartbeat {
    StatusHeartbeat {
        uav: NodeId::new("uav1").expect("valid"),
        time_s: 1.0,
        state: EdgeState::Localized,
        frames_processed: 30,
        frame_rate_hz: 30.0,
        landmarks_loaded: 2,
        datum_lat_deg: 30.52,
        datum_lon_deg: 114.36,
        datum_alt_m: 25.0,
        health: Health::Ok,
        frames_dropped: 0,
        frames_failed: 0,
        latency_p50_ms: 3.0,
        latency_p99_ms: 9.0,
        detector: "oracle".into(),
    }
}

/// A live UAV with a pose, a status, tracks and a preview.
fn live() -> (
    std::sync::mpsc::Sender<NetEvent>,
    tokio::sync::mpsc::UnboundedReceiver<NetCommand>,
    Harness<'static, GsApp>,
    Rc<Cell<f64>>,
) {
    one_uav(true)
}

/// One UAV heard, with or without its presence token (a replay has none).
fn one_uav(
    token: bool,
) -> (
    std::sync::mpsc::Sender<NetEvent>,
    tokio::sync::mpsc::UnboundedReceiver<NetCommand>,
    Harness<'static, GsApp>,
    Rc<Cell<f64>>,
) {
    let (tx, commands, app) = app();
    if token {
        let uav = NodeId::new("uav1").expect("valid");
        tx.send(NetEvent::Alive { uav, alive: true }).expect("send");
    }
    tx.send(NetEvent::Pose(pose("uav1", 30.5205, 114.3601, 5)))
        .expect("send");
    tx.send(NetEvent::Status(status())).expect("send");
    for e in frame_events("uav1", 5) {
        tx.send(e).expect("send");
    }
    let now = Rc::new(Cell::new(0.0));
    let mut harness = harness(app, now.clone());
    harness.run();
    (tx, commands, harness, now)
}

#[test]
fn a_lost_link_is_loud_in_the_panel_and_the_camera_and_nothing_stays_green() {
    let (tx, _commands, mut harness, now) = live();
    harness.get_by_label("health ok");
    harness.get_by_label("online");
    harness.get_by_label("localized, 30 frames/s");
    assert!(harness.query_by_label_contains("LINK LOST").is_none());

    // Everything stops: late first, then lost.
    now.set(3.0);
    harness.run();
    harness.get_by_label("STALE: nothing heard for 3.0 s");
    harness.get_by_label("STALE nothing heard for 3.0 s");
    assert!(
        harness.query_by_label("health ok").is_none(),
        "no green health on old news"
    );

    now.set(12.0);
    harness.run();
    harness.get_by_label("LINK LOST: uav1 (no data for 12 s)");
    harness.get_by_label("LINK LOST: nothing heard for 12.0 s");
    harness.get_by_label("LINK LOST nothing heard for 12 s");
    harness.get_by_label_contains("last known: health Ok, localized");
    assert!(harness.query_by_label("health ok").is_none());
    assert!(harness.query_by_label("online").is_none());

    // The edge comes back: the banner goes.
    tx.send(NetEvent::Pose(pose("uav1", 30.5205, 114.3601, 6)))
        .expect("send");
    harness.run();
    assert!(harness.query_by_label_contains("LINK LOST").is_none());
    harness.get_by_label("health ok");

    // Its liveliness token goes: lost at once, before any silence.
    tx.send(NetEvent::Alive {
        uav: NodeId::new("uav1").expect("valid"),
        alive: false,
    })
    .expect("send");
    harness.run();
    harness.get_by_label_contains("LINK LOST: uav1");
}

#[test]
fn a_lost_fix_is_not_a_lost_link() {
    let (tx, _commands, mut harness, now) = live();
    harness.get_by_label_contains("FIX: ");
    // Out of sight of towers: no more poses, but status, tracks and camera
    // frames keep coming every second, the status saying there is no fix.
    for t in 1..=40 {
        now.set(f64::from(t));
        tx.send(NetEvent::Status(StatusHeartbeat {
            time_s: f64::from(t),
            state: EdgeState::NoFix,
            ..status()
        }))
        .expect("send");
        for e in frame_events("uav1", 5 + u64::from(t as u32)) {
            tx.send(e).expect("send");
        }
        harness.run();
    }
    assert!(
        harness.query_by_label_contains("LINK LOST").is_none(),
        "heard every second: the link is up"
    );
    assert!(harness.query_by_label_contains("STALE").is_none());
    harness.get_by_label("NO FIX (link up): last pose 40 s ago");
    harness.get_by_label("online");
    harness.get_by_label_contains("last known: 30.520500");
    // Coasting is its own state.
    tx.send(NetEvent::Status(StatusHeartbeat {
        time_s: 41.0,
        state: EdgeState::Coasting,
        ..status()
    }))
    .expect("send");
    harness.run();
    harness.get_by_label("COASTING: no tower in sight, last pose 40 s ago");
    // Then the edge goes quiet too: now the link is lost.
    now.set(52.0);
    harness.run();
    harness.get_by_label("LINK LOST: nothing heard for 12.0 s");
}

#[test]
fn a_predicted_pose_reads_as_coasting_and_current_not_as_a_fix() {
    let (tx, _commands, mut harness, now) = live();
    harness.get_by_label_contains("FIX: ");
    harness.get_by_label("fix from 2 towers: A1 B1");
    // Out of sight of towers, the filter keeps publishing its prediction.
    for i in 1..=30u32 {
        let t = f64::from(i) / 10.0;
        now.set(t);
        let mut p = pose(
            "uav1",
            30.5205,
            114.3601 + 1e-6 * f64::from(i),
            5 + u64::from(i),
        );
        p.towers_used.clear();
        p.coast_s = t;
        tx.send(NetEvent::Pose(p)).expect("send");
        harness.run();
    }
    harness.get_by_label_contains("COASTING: no tower fix for 3.0 s");
    assert!(harness.query_by_label_contains("FIX: ").is_none());
    assert!(harness.query_by_label_contains("fix from").is_none());
    // The prediction is where the UAV is now, not a last known place.
    harness.get_by_label_contains("30.520500, 114.360130");
    assert!(harness.query_by_label_contains("last known").is_none());
    // A tower fix again.
    now.set(3.1);
    tx.send(NetEvent::Pose(pose("uav1", 30.5205, 114.3602, 40)))
        .expect("send");
    harness.run();
    harness.get_by_label_contains("FIX: ");
    assert!(harness.query_by_label_contains("COASTING").is_none());
}

/// Clicks track 7's box, picks B1 and sends it; returns what was published.
fn send_b1(
    harness: &mut Harness<'static, GsApp>,
    commands: &mut tokio::sync::mpsc::UnboundedReceiver<NetCommand>,
) -> IdCorrection {
    harness.get_by_label("T7 A1").click();
    harness.run();
    harness.get_by_label("B1 (B)").click();
    harness.run();
    harness.get_by_label("Send B1").click();
    harness.run();
    match commands.try_recv() {
        Ok(NetCommand::Correct(c)) => c,
        other => panic!("expected a correction, got {other:?}"),
    }
}

#[test]
fn a_correction_to_a_silent_uav_times_out_and_can_be_resent_or_cancelled() {
    let (tx, mut commands, mut harness, now) = live();
    let first = send_b1(&mut harness, &mut commands);
    harness.get_by_label("#1 T7 -> B1");
    harness.get_by_label("pending 0 s");

    now.set(6.0);
    harness.run();
    harness.get_by_label("no answer after 5 s");
    assert!(harness.query_by_label_contains("pending").is_none());

    harness.get_by_label("Resend").click();
    harness.run();
    let again = match commands.try_recv() {
        Ok(NetCommand::Correct(c)) => c,
        other => panic!("expected the resend, got {other:?}"),
    };
    assert_eq!(
        (again.track_id, again.tower_id.as_deref()),
        (first.track_id, first.tower_id.as_deref())
    );
    assert_ne!(again.request_id, first.request_id);
    harness.get_by_label("#2 T7 -> B1");
    harness.get_by_label("cancelled");
    harness.get_by_label("pending 0 s");

    // The edge is back and answers the resend.
    tx.send(NetEvent::Ack(CorrectionAck {
        uav: again.uav.clone(),
        request_id: again.request_id,
        accepted: true,
        reason: None,
    }))
    .expect("send");
    harness.run();
    harness.get_by_label("accepted");

    // A third one is given up by the operator.
    send_b1(&mut harness, &mut commands);
    harness.get_by_label("Cancel").click();
    harness.run();
    assert!(harness.query_by_label_contains("pending").is_none());
    assert_eq!(
        harness
            .state()
            .fleet()
            .corrections
            .sent
            .iter()
            .filter(|c| c.state == towernav_ground_station::corrections::CorrectionState::Cancelled)
            .count(),
        2
    );
}

#[test]
fn a_correction_is_bound_to_the_edge_run_it_was_picked_in() {
    let (tx, mut commands, mut harness, now) = live();
    let sent = send_b1(&mut harness, &mut commands);
    assert_eq!(
        sent.session,
        Some(1),
        "the run of the tracks the operator saw"
    );
    now.set(6.0);
    harness.run();
    harness.get_by_label("no answer after 5 s");
    // The edge restarts: its tracks come from run 2, where T7 is another tower.
    for e in towernav_ground_station::test_support::frame_events("uav1", 1) {
        let e = match e {
            NetEvent::Tracks(mut t) => {
                t.session = 2;
                NetEvent::Tracks(t)
            }
            other => other,
        };
        tx.send(e).expect("send");
    }
    harness.run();
    harness.get_by_label_contains("the edge restarted and its track numbers started again");
    assert!(
        harness.query_by_label("Resend").is_none(),
        "a correction of another run is not resent"
    );
    assert!(commands.try_recv().is_err(), "nothing was sent");
}

#[test]
fn picking_a_tower_bound_to_another_track_says_so_before_sending() {
    use towernav_geometry::PixelBox;
    use towernav_protocol::{TowerType, Track, TrackReport};
    let (tx, mut commands, mut harness, _now) = live();
    let uav = NodeId::new("uav1").expect("valid");
    let track = |id: u64, left: f64, tower: &str| Track {
        track_id: id,
        bbox: PixelBox::new(left, 200.0, left + 60.0, 400.0),
        tower_type: TowerType::B,
        tower_id: Some(tower.into()),
        pinned: false,
        confidence: Some(0.9),
    };
    tx.send(NetEvent::Tracks(TrackReport {
        uav,
        time_s: 5.0 / 30.0,
        seq: 5,
        tracks: vec![track(7, 600.0, "A1"), track(9, 900.0, "B1")],
        session: 0,
    }))
    .expect("send");
    harness.run();
    harness.get_by_label("T7 A1").click();
    harness.run();
    harness.get_by_label("B1 (B)").click();
    harness.run();
    harness.run();
    harness.get_by_label("B1 is bound to track 9: sending unbinds it there");
    harness.get_by_label("Send B1 (unbinds T9)").click();
    harness.run();
    assert!(matches!(commands.try_recv(), Ok(NetCommand::Correct(c)) if c.track_id == 7));
}

#[test]
fn an_endpoint_that_brings_nothing_is_called_out() {
    let (_tx, _commands, app) = app();
    let now = Rc::new(Cell::new(1.0));
    let mut harness = harness(app, now.clone());
    harness.run();
    harness.get_by_label_contains("No UAV yet. Listening via");
    now.set(12.0);
    harness.run();
    harness.get_by_label_contains("Nothing heard from any edge for 12 s via");
}

#[test]
fn a_heard_uav_without_a_presence_token_is_heard_and_a_stale_frame_warns_the_picker() {
    // As in a replay: data, no liveliness token.
    let (_tx, _commands, mut harness, now) = one_uav(false);
    harness.get_by_label("heard");
    assert!(harness.query_by_label("presence unknown").is_none());
    // The link goes: the frame is old, and the picker says so.
    now.set(12.0);
    harness.run();
    harness.get_by_label("T7 A1").click();
    harness.run();
    harness.get_by_label_contains("this frame is old");
    // Enter in the search box picks the only tower that matches.
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Tower id")
        .click();
    harness.run();
    harness.event(egui::Event::Text("b1".into()));
    harness.run();
    harness.key_press(egui::Key::Enter);
    harness.run();
    harness.get_by_label("Send B1");
}

#[test]
fn a_recording_that_starts_takes_the_old_cannot_record_away() {
    let (tx, _commands, mut harness, _now) = live();
    tx.send(NetEvent::Notice(
        "cannot record: /full/disk.mcap: no space".into(),
    ))
    .expect("send");
    harness.run();
    harness.get_by_label_contains("cannot record");
    tx.send(NetEvent::Recording(Some("session.mcap".into())))
        .expect("send");
    harness.run();
    assert!(
        harness.query_by_label_contains("cannot record").is_none(),
        "a stale 'cannot record' beside a running recording"
    );
    harness.get_by_label_contains("REC");
}
