//! A survey's measured towers reviewed as an operator does it, through
//! egui_kittest: the proposals listed with their verdicts, one accepted, one
//! rejected, one taken into the form; only the accepted one is written, in
//! one import under the operator's name, and Undo takes it back.

use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};
use towernav_ground_station::app::{GsApp, Tab};
use towernav_ground_station::test_support::app;

/// What `towernav-edge map-towers` writes: A1 confirmed 10 m from its
/// record, two new towers, a missed one.
const SURVEY: &str = r#"{"type":"FeatureCollection","features":[
  {"type":"Feature","id":"A1","geometry":{"type":"Point","coordinates":[114.36008,30.52007,25.0]},
   "properties":{"id":"A1","tower_type":"A","ground_elev_m":25.0,"height_m":34.4,"status":"confirmed",
    "known_id":"A1","offset_east_m":-6.0,"offset_north_m":8.0,"height_difference_m":-0.6,
    "sigma_major_m":1.2,"sigma_minor_m":0.5,"ellipse_bearing_deg":90.0,"views":812,
    "sigma_horizontal_m":1.2,"survey_source":"towernav-edge map-towers"}},
  {"type":"Feature","id":"NEW-1","geometry":{"type":"Point","coordinates":[114.3620,30.5205,25.0]},
   "properties":{"id":"NEW-1","tower_type":"A","ground_elev_m":25.0,"height_m":32.2,"status":"new",
    "sigma_major_m":0.9,"sigma_minor_m":0.6,"ellipse_bearing_deg":0.0,"views":640}},
  {"type":"Feature","id":"NEW-2","geometry":{"type":"Point","coordinates":[114.3640,30.5215,25.0]},
   "properties":{"id":"NEW-2","tower_type":"B","ground_elev_m":25.0,"height_m":38.0,"status":"new",
    "sigma_major_m":2.9,"sigma_minor_m":0.7,"ellipse_bearing_deg":45.0,"views":90}},
  {"type":"Feature","id":"B1","geometry":{"type":"Point","coordinates":[114.36,30.521,25.0]},
   "properties":{"id":"B1","tower_type":"B","ground_elev_m":25.0,"height_m":35.0,"status":"missed",
    "frames_in_view":44}}
]}"#;

fn harness(app: GsApp) -> Harness<'static, GsApp> {
    let mut harness = Harness::builder()
        .with_size([1600.0, 900.0])
        .build_ui_state(|ui, app: &mut GsApp| app.show(ui, 0.0), app);
    harness.run();
    harness.get_by_label("Survey review").click();
    harness.run();
    assert_eq!(harness.state().tab, Tab::Survey);
    harness
}

/// The app on the Survey review tab with `text` opened from a file named `name`.
fn opened(text: &str, name: &str) -> (tempfile::TempDir, Harness<'static, GsApp>) {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join(name);
    std::fs::write(&file, text).expect("write");
    let (_tx, _commands, app) = app();
    let mut harness = harness(app);
    open(&mut harness, &file);
    (dir, harness)
}

fn open(harness: &mut Harness<'static, GsApp>, path: &std::path::Path) {
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Survey file")
        .click();
    harness.run();
    harness.event(egui::Event::Text(path.display().to_string()));
    harness.run();
    harness.get_by_label("Open survey").click();
    harness.run();
}

#[test]
fn only_the_accepted_tower_is_written_as_one_import_that_undo_takes_back() {
    let (_dir, mut harness) = opened(SURVEY, "towers-mapped.geojson");
    harness.get_by_label("confirms A1: 10.0 m off, height -0.6 m");
    harness.get_by_label("B1: missed ");
    // Nothing is written until something is accepted.
    assert!(
        harness
            .get_by_label("Write 0 accepted towers")
            .accesskit_node()
            .is_disabled()
    );

    harness.get_by_label("Accept NEW-1").click();
    harness.run();
    harness.get_by_label("Reject NEW-2").click();
    harness.run();
    harness.get_by_label("Write 1 accepted towers").click();
    harness.run();

    let db = harness.state().db();
    let written = db.get("NEW-1").expect("reads").expect("NEW-1 written");
    assert_eq!(written.updated_by, "ground-station", "the operator's name");
    assert!((written.height_m - 32.2).abs() < 1e-9);
    assert!(db.get("NEW-2").expect("reads").is_none(), "rejected");
    let a1 = db.get("A1").expect("reads").expect("A1");
    assert_eq!(a1.height_m, 35.0, "A1 was neither accepted nor edited");
    harness.get_by_label_contains("imported 1 towers from survey");

    // The import is one step back.
    harness.get_by_label("Landmarks").click();
    harness.run();
    harness.get_by_label_contains("Undo import of").click();
    harness.run();
    assert!(harness.state().db().get("NEW-1").expect("reads").is_none());
}

#[test]
fn edit_takes_a_confirmed_tower_into_the_form_as_the_stored_one() {
    let (_dir, mut harness) = opened(SURVEY, "towers-mapped.geojson");
    harness.get_by_label("Edit A1").click();
    harness.run();
    assert_eq!(harness.state().tab, Tab::Landmarks);
    // The form holds the measured height, and edits A1 rather than adding it.
    let height = harness.get_by_role_and_label(egui::Role::TextInput, "Height (m)");
    assert_eq!(height.accesskit_node().value().as_deref(), Some("34.4"));
    assert_eq!(harness.state().editing(), Some("A1"));
}

#[test]
fn a_file_that_is_not_a_survey_is_refused_by_name() {
    let (_dir, harness) = opened(
        r#"{"type":"FeatureCollection","features":[{"properties":{}}]}"#,
        "towers.geojson",
    );
    harness.get_by_label_contains("feature 1: no status");
}
