//! Recording and replay as an operator meets them, through egui_kittest: a
//! recording shows as running only once its file is open, never overwrites
//! one, and carries its towers; a replay pauses, seeks and keeps the
//! landmarks read-only.

use std::cell::Cell;
use std::rc::Rc;

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use towernav_ground_station::app::GsApp;
use towernav_ground_station::events::NetEvent;
use towernav_ground_station::net::NetCommand;
use towernav_ground_station::recording::{self, Recorder, ReplayPlayer};
use towernav_ground_station::test_support::{app, pose, towers};
use towernav_protocol::{Keys, NodeId, PoseEstimate, encode};

fn harness(app: GsApp, now: Rc<Cell<f64>>) -> Harness<'static, GsApp> {
    Harness::builder()
        .with_size([1600.0, 900.0])
        .build_ui_state(move |ui, app: &mut GsApp| app.show(ui, now.get()), app)
}

#[test]
fn record_runs_only_once_open_shows_a_timer_and_refuses_an_existing_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let taken = dir.path().join("taken.mcap");
    std::fs::write(&taken, b"an earlier flight").expect("write");
    let (tx, mut commands, app) = app();
    let now = Rc::new(Cell::new(0.0));
    let mut harness = harness(app, now.clone());
    harness.run();

    let path_box = harness.get_by_role_and_label(egui::Role::TextInput, "Record to");
    path_box.focus();
    harness.run();
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness.run();
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Record to")
        .type_text(&taken.display().to_string());
    harness.run();
    harness.get_by_label("exists: pick a new name");
    harness.get_by_label("Record").click();
    harness.run();
    assert!(
        commands.try_recv().is_err(),
        "nothing asked for an existing file"
    );

    let fresh = dir.path().join("fresh.mcap");
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Record to")
        .focus();
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness.run();
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Record to")
        .type_text(&fresh.display().to_string());
    harness.run();
    harness.get_by_label("Record").click();
    harness.run();
    match commands.try_recv() {
        Ok(NetCommand::StartRecording { path, landmarks }) => {
            assert_eq!(path, fresh);
            let ids: Vec<&str> = landmarks.iter().map(|l| l.id.as_str()).collect();
            assert_eq!(ids, ["A1", "B1"], "the towers go into the file");
        }
        other => panic!("expected StartRecording, got {other:?}"),
    }
    // Not "recording" until the network side has the file open.
    assert!(harness.query_by_label_contains("REC ").is_none());
    harness.get_by_label("opening...");

    // It failed: the Record button is back, and the notice says why.
    tx.send(NetEvent::Notice("cannot record: disk full".into()))
        .expect("send");
    tx.send(NetEvent::Recording(None)).expect("send");
    harness.run();
    assert!(harness.query_by_label_contains("REC ").is_none());
    harness.get_by_label("cannot record: disk full");
    harness.get_by_label("Record");

    // It runs: a timer from when it opened.
    tx.send(NetEvent::Recording(Some(fresh.clone())))
        .expect("send");
    harness.run();
    now.set(75.0);
    harness.run();
    harness.get_by_label(&format!("REC 01:15 {}", fresh.display()));
    harness.get_by_label("Stop").click();
    harness.run();
    assert!(matches!(commands.try_recv(), Ok(NetCommand::StopRecording)));
}

/// A recording of ten poses a second apart, carrying the test towers.
fn recorded(dir: &std::path::Path) -> std::path::PathBuf {
    let path = dir.join("flight.mcap");
    let keys = Keys::new(NodeId::new("demo").expect("valid"));
    let uav = NodeId::new("uav1").expect("valid");
    let mut rec = Recorder::create(&path).expect("create");
    rec.write_landmarks(&towers(), 1_000_000_000)
        .expect("towers");
    for seq in 0..10u64 {
        let p = pose("uav1", 30.52, 114.36 + 1e-4 * seq as f64, seq);
        rec.write(
            &keys.uav_key::<PoseEstimate>(&uav),
            &encode(&p).expect("encode"),
            1_000_000_000 * (1 + seq),
        )
        .expect("pose");
    }
    rec.finish().expect("finish");
    path
}

#[test]
fn a_replay_pauses_and_seeks_and_its_towers_are_read_only() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = recorded(dir.path());
    let samples = recording::read(&path).expect("read").samples;
    assert_eq!(
        recording::landmarks(&path, &samples).expect("towers"),
        Some(towers())
    );
    let (_tx, _commands, app) = app();
    let app = app.replaying(ReplayPlayer::new(samples, 1.0));
    let now = Rc::new(Cell::new(100.0));
    let mut harness = harness(app, now.clone());
    harness.run();
    now.set(103.5);
    harness.run();
    let seq = |h: &Harness<'static, GsApp>| {
        h.state().fleet().uavs[&NodeId::new("uav1").expect("valid")]
            .last_pose
            .as_ref()
            .map(|p| p.seq)
    };
    assert_eq!(seq(&harness), Some(3));
    harness.get_by_label("00:03 / 00:09");

    harness.get_by_label("Pause").click();
    harness.run();
    now.set(200.0);
    harness.run();
    assert_eq!(seq(&harness), Some(3), "paused");
    // Paused is not a lost link: the replay's clock stopped too.
    assert!(harness.query_by_label_contains("LINK LOST").is_none());

    harness.get_by_label("Play").click();
    harness.run();
    now.set(202.0);
    harness.run();
    assert_eq!(seq(&harness), Some(5));

    // The towers are the recording's, and cannot be edited here: it says so.
    harness.get_by_label("Landmarks").click();
    harness.run();
    harness.get_by_label_contains("REPLAY: these are the recording's towers, read-only");
    harness.get_by_label("A1").click();
    harness.run();
    harness.get_by_label("Delete...").click();
    harness.run();
    harness.get_by_label("Delete A1").click();
    harness.run();
    assert!(
        harness.state().db().get("A1").expect("db").is_some(),
        "a replay edits nothing"
    );
    harness.get_by_label("not saved: a replay's towers are read-only");
}
