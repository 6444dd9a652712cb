//! The landmark editor as an operator drives it, through egui_kittest: what is
//! typed is what is stored, a delete is a deliberate act that can be undone,
//! and the history says who changed what and when.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use towernav_ground_station::app::{GsApp, Tab};
use towernav_ground_station::test_support::app;
use towernav_protocol::LandmarkChangeOp;

fn harness(app: GsApp) -> Harness<'static, GsApp> {
    let mut harness = Harness::builder()
        .with_size([1600.0, 900.0])
        .build_ui_state(|ui, app: &mut GsApp| app.show(ui, 0.0), app);
    harness.run();
    harness.get_by_label("Landmarks").click();
    harness.run();
    assert_eq!(harness.state().tab, Tab::Landmarks);
    harness
}

/// Types `text` into the box labelled `field` one key at a time, a frame
/// after each, as a person types: error lines come and go between keys.
fn type_slowly(harness: &mut Harness<'static, GsApp>, field: &str, text: &str) {
    harness
        .get_by_role_and_label(egui::Role::TextInput, field)
        .click();
    harness.run();
    // Keys go to whatever has the focus, as a keyboard's do: a box that lost
    // it between two keys loses the rest of the number.
    for c in text.chars() {
        harness.event(egui::Event::Text(c.to_string()));
        harness.run();
    }
}

#[test]
fn an_empty_form_flags_nothing_until_a_field_is_left_empty() {
    let (_tx, _commands, app) = app();
    let mut harness = harness(app);
    assert!(
        harness.query_by_label("is required").is_none(),
        "an untouched form is not an error"
    );
    type_slowly(&mut harness, "Height (m)", "4");
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Height (m)")
        .focus();
    harness.key_press(egui::Key::Backspace);
    harness.run();
    harness.get_by_label("is required");
    // Units say what each number means.
    harness.get_by_label("above the WGS84 ellipsoid, not MSL");
}

#[test]
fn typed_keys_are_stored_as_typed_and_a_far_position_is_questioned() {
    let (_tx, _commands, app) = app();
    let mut harness = harness(app);
    // The id is started and erased: the moment every number parses, while
    // the latitude is being typed, an error line appears above it.
    type_slowly(&mut harness, "Id", "E");
    harness.key_press(egui::Key::Backspace);
    harness.run();
    for (field, text) in [
        ("Longitude (deg)", "114.3612"),
        ("Ground elevation (m)", "24.5"),
        ("Height (m)", "41"),
        ("Latitude (deg)", "30.5215"),
    ] {
        type_slowly(&mut harness, field, text);
    }
    harness.get_by_label("is empty");
    type_slowly(&mut harness, "Id", "E7");
    harness.get_by_label("Add").click();
    harness.run();
    let stored = harness
        .state()
        .db()
        .get("E7")
        .expect("db")
        .expect("E7 was stored");
    assert_eq!(
        (
            stored.lat_deg,
            stored.lon_deg,
            stored.ground_elev_m,
            stored.height_m
        ),
        (30.5215, 114.3612, 24.5, 41.0)
    );
    harness.get_by_label_contains("saved E7");
    assert!(harness.query_by_label("that id is taken").is_none());

    // A latitude of 3 is valid, but about 3,000 km from the line: asked, not
    // silently saved.
    harness.get_by_label("New").click();
    harness.run();
    for (field, text) in [
        ("Id", "E8"),
        ("Latitude (deg)", "3"),
        ("Longitude (deg)", "114.3612"),
        ("Ground elevation (m)", "24.5"),
        ("Height (m)", "41"),
    ] {
        type_slowly(&mut harness, field, text);
    }
    harness.get_by_label_contains("km from the nearest tower (");
    assert!(harness.query_by_label("Add").is_none());
    harness.get_by_label("Add anyway");
}

#[test]
fn delete_asks_away_from_the_button_and_can_be_undone_and_the_history_names_who() {
    let (_tx, _commands, app) = app();
    let mut harness = harness(app);
    harness.get_by_label("A1").click();
    harness.run();
    let delete = harness.get_by_label("Delete...");
    let delete_at = delete.rect().center();
    delete.click();
    harness.run();
    // A second click where the first one was (a double click) does not delete.
    harness.get_by_label("Delete tower A1?");
    let confirm = harness.get_by_label("Delete A1");
    assert!(
        confirm.rect().center().distance(delete_at) > 100.0,
        "the confirmation sits away from the first click"
    );
    harness.get_by_label("Keep it").click();
    harness.run();
    assert!(harness.query_by_label("Delete tower A1?").is_none());
    assert!(harness.state().db().get("A1").expect("db").is_some());

    harness.get_by_label("Delete...").click();
    harness.run();
    harness.get_by_label("Delete A1").click();
    harness.run();
    assert!(harness.state().db().get("A1").expect("db").is_none());
    harness.get_by_label_contains("deleted A1");

    harness.get_by_label("Undo delete of A1").click();
    harness.run();
    let back = harness
        .state()
        .db()
        .get("A1")
        .expect("db")
        .expect("A1 is back");
    assert_eq!((back.lat_deg, back.height_m), (30.52, 35.0));
    harness.get_by_label_contains("restored A1");

    let history = harness.state().db().history_since(0).expect("history");
    let removal = history
        .iter()
        .find(|e| matches!(&e.change.change, LandmarkChangeOp::Remove { id } if id == "A1"))
        .expect("the removal is in the log");
    assert_eq!(removal.author.by, "ground-station");
    assert!(
        removal.author.at_unix_s > 1_700_000_000,
        "stamped with the time"
    );
    harness.get_by_label("History").click();
    harness.run();
    harness.get_by_label("removed A1");
}

#[test]
fn an_import_with_a_far_tower_waits_and_then_is_undone_as_a_whole() {
    let (_tx, _commands, app) = app();
    let mut harness = harness(app);
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("survey.csv");
    // One latitude with a wrong digit: 26 degrees north of the line.
    std::fs::write(
        &file,
        "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m\n\
         C1,A,30.5231,114.3612,24.5,33\n\
         C2,A,56.5241,114.3622,24.5,33\n",
    )
    .expect("write");
    harness
        .get_by_role_and_label(egui::Role::TextInput, "File")
        .click();
    harness.run();
    harness.event(egui::Event::Text(file.display().to_string()));
    harness.run();
    harness.get_by_label("Import").click();
    harness.run();
    assert!(
        harness.state().db().get("C1").expect("db").is_none(),
        "held back"
    );
    harness.get_by_label_contains("C2: stands");
    harness.get_by_label("Import anyway").click();
    harness.run();
    assert!(harness.state().db().get("C2").expect("db").is_some());
    harness
        .get_by_label("Undo import of survey.csv (2 towers)")
        .click();
    harness.run();
    for id in ["C1", "C2"] {
        assert!(
            harness.state().db().get(id).expect("db").is_none(),
            "{id} is still there"
        );
    }
    harness.get_by_label_contains("took back the import of survey.csv");
    assert!(harness.state().db().get("A1").expect("db").is_some());
}
