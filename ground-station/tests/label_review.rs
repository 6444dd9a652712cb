//! A survey flight's labels reviewed in the Labels tab, through egui_kittest
//! as a reviewer drives it: a wrong box rejected, a loose one dragged to the
//! tower's foot, a missed tower drawn; leaving the frame writes its YOLO file,
//! and a later review starts where this one stopped.

use std::path::Path;

use egui::{Pos2, Rect};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use towernav_dataset::{YoloLabel, parse_labels};
use towernav_ground_station::app::{GsApp, GsOptions, Tab};
use towernav_ground_station::net::NetLink;
use towernav_landmark_db::LandmarkDb;

const W: f64 = 640.0;
const H: f64 = 360.0;

/// Two frames as `towernav-edge label` writes them: data.yaml, images/, labels/.
fn dataset(dir: &Path) {
    std::fs::create_dir_all(dir.join("images")).unwrap();
    std::fs::create_dir_all(dir.join("labels")).unwrap();
    std::fs::write(
        dir.join("data.yaml"),
        format!(
            "path: {}\ntrain: images\nval: images\nnames:\n  0: \"A\"\n  1: \"B\"\n",
            dir.display()
        ),
    )
    .unwrap();
    for name in ["frame_000005", "frame_000010"] {
        image::RgbImage::from_pixel(W as u32, H as u32, image::Rgb([90, 120, 160]))
            .save(dir.join("images").join(format!("{name}.png")))
            .unwrap();
    }
    // Frame 5: a tower at x 100-140, y 90-270, and a box on a tree (B).
    std::fs::write(
        dir.join("labels/frame_000005.txt"),
        "0 0.187500 0.500000 0.062500 0.500000\n1 0.750000 0.500000 0.050000 0.300000\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("labels/frame_000010.txt"),
        "0 0.500000 0.500000 0.050000 0.400000\n",
    )
    .unwrap();
}

fn app(dir: &Path) -> GsApp {
    let db = LandmarkDb::open_in_memory().expect("in-memory database");
    let (_tx, _commands, link) = NetLink::detached();
    let mut app = GsApp::new(
        db,
        link,
        GsOptions {
            labels: Some(dir.to_path_buf()),
            ..GsOptions::default()
        },
    )
    .expect("app");
    app.tab = Tab::Labels;
    app
}

fn harness(app: GsApp) -> Harness<'static, GsApp> {
    let mut harness = Harness::builder()
        .with_size([1600.0, 900.0])
        .build_ui_state(|ui, app: &mut GsApp| app.show(ui, 0.0), app);
    harness.run();
    harness
}

/// Where image pixel `p` is on the screen.
fn screen(frame: Rect, p: [f64; 2]) -> Pos2 {
    let scale = f64::from(frame.width()) / W;
    frame.min + egui::vec2((p[0] * scale) as f32, (p[1] * scale) as f32)
}

/// Presses at `from`, moves in steps, and lets go at `to`, a frame each.
fn drag(harness: &mut Harness<'static, GsApp>, from: Pos2, to: Pos2) {
    harness.hover_at(from);
    harness.run();
    harness.drag_at(from);
    harness.run();
    for k in 1..=4 {
        harness.hover_at(from + (to - from) * (k as f32 / 4.0));
        harness.run();
    }
    harness.drop_at(to);
    harness.run();
}

fn labels(dir: &Path, name: &str) -> Vec<YoloLabel> {
    let path = dir.join("labels").join(format!("{name}.txt"));
    parse_labels(&std::fs::read_to_string(&path).unwrap(), &path, Some(2)).unwrap()
}

fn pixels(l: &YoloLabel) -> [f64; 4] {
    let b = l.pixels(W, H);
    [b.left, b.top, b.right, b.bottom]
}

fn near(a: [f64; 4], b: [f64; 4], tol: f64) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn a_reviewer_rejects_drags_and_draws_and_the_label_files_follow() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("labels-survey");
    dataset(&dir);
    let mut harness = harness(app(&dir));
    harness.get_by_label_contains("Frame 1 of 2: frame_000005");
    let frame = harness.get_by_label("Frame").rect();
    // Screen pixels are image pixels scaled by the frame's fit.
    assert!((f64::from(frame.height()) / f64::from(frame.width()) - H / W).abs() < 0.01);

    harness.get_by_label("Reject box 2").click();
    harness.run();
    // The tower's box ends 30 px above its foot: its bottom edge is dragged down.
    drag(
        &mut harness,
        screen(frame, [120.0, 270.0]),
        screen(frame, [120.0, 300.0]),
    );
    // A tower the labeller missed, drawn on open image.
    drag(
        &mut harness,
        screen(frame, [250.0, 50.0]),
        screen(frame, [300.0, 150.0]),
    );
    harness.get_by_label_contains("changed, written on leaving");
    // Nothing is written until the frame is left.
    assert_eq!(labels(&dir, "frame_000005").len(), 2);

    harness.get_by_label("Next").click();
    harness.run();
    harness.get_by_label_contains("Frame 2 of 2: frame_000010");
    let written = labels(&dir, "frame_000005");
    assert_eq!(written.len(), 2, "{written:?}");
    let px = 1.5 * W / f64::from(frame.width());
    assert_eq!(written[0].class, 0);
    assert!(
        near(pixels(&written[0]), [100.0, 90.0, 140.0, 300.0], px),
        "dragged: {:?}",
        pixels(&written[0])
    );
    assert_eq!(written[1].class, 0, "a drawn box takes the chosen class");
    assert!(
        near(pixels(&written[1]), [250.0, 50.0, 300.0, 150.0], px),
        "drawn: {:?}",
        pixels(&written[1])
    );

    // Frame 10 is right as it is: Enter accepts it as labelled.
    harness.key_press(egui::Key::Enter);
    harness.run();
    assert_eq!(
        std::fs::read_to_string(dir.join("labels/frame_000010.txt")).unwrap(),
        "0 0.500000 0.500000 0.050000 0.400000\n"
    );
    let log = std::fs::read_to_string(dir.join("review.csv")).unwrap();
    assert_eq!(
        log,
        "frame,kept,rejected,edited\nframe_000005,2,1,2\nframe_000010,1,0,0\n"
    );

    // A later review knows both frames were done.
    let again = harness_again(&dir);
    again.get_by_label_contains("2 reviewed before");
    again.get_by_label_contains("2 of 2 reviewed");
}

fn harness_again(dir: &Path) -> Harness<'static, GsApp> {
    harness(app(dir))
}

#[test]
fn a_changed_frame_is_written_before_another_folder_opens() {
    let tmp = tempfile::tempdir().unwrap();
    let (one, two) = (tmp.path().join("one"), tmp.path().join("two"));
    dataset(&one);
    dataset(&two);
    let mut harness = harness(app(&one));
    harness.get_by_label("Reject box 1").click();
    harness.run();
    harness
        .get_by_role_and_label(egui::Role::TextInput, "Dataset folder")
        .focus();
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness.run();
    harness.event(egui::Event::Text(two.display().to_string()));
    harness.run();
    harness.get_by_label("Open").click();
    harness.run();
    harness.get_by_label_contains(&format!("{}: 2 frames", two.display()));
    assert_eq!(labels(&one, "frame_000005").len(), 1);
    assert_eq!(labels(&two, "frame_000005").len(), 2);
}

#[test]
fn a_folder_that_is_no_dataset_is_named_and_nothing_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let harness = harness(app(tmp.path()));
    harness.get_by_label_contains("not opened");
    harness.get_by_label_contains("no data.yaml and no images/ folder");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
}

#[test]
fn a_bad_label_line_is_named_with_its_file_and_line() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("set");
    dataset(&dir);
    std::fs::write(dir.join("labels/frame_000010.txt"), "0 0.5 0.5 0.05\n").unwrap();
    let harness = harness(app(&dir));
    harness.get_by_label_contains("frame_000010.txt, line 1");
}
