//! The COCO start of the detector (`training/coco_init.py`): the COCO-trained
//! YOLOv5n's backbone and neck, mapped onto Ultralytics' YOLOv5n, ahead of
//! the checkpoint's own anchor head for seven COCO classes
//! (`tests/fixtures/coco-check.onnx`, made by `coco_init.py check-onnx`), run
//! by the project's own ONNX runtime on the photo that ships with those
//! weights. A wrong mapping of any layer loses the people and the bus.

use std::path::PathBuf;

use towernav_onnx::yolo::{DetectorOptions, YoloDetector};
use towernav_protocol::TowerType;

fn coco_photo(name: &str) -> Option<PathBuf> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/weights/coco")
        .join(name);
    path.is_file().then_some(path)
}

#[test]
fn the_converted_backbone_still_finds_the_people_and_the_bus() {
    let Some(photo) = coco_photo("bus.jpg") else {
        eprintln!("skipped: ../shared/weights/coco/bus.jpg is not beside the project");
        return;
    };
    let model = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/coco-check.onnx");
    let mut detector = YoloDetector::load(&model, &DetectorOptions::default()).expect("loads");
    assert_eq!(
        (detector.info().input_width, detector.info().input_height),
        (640, 640)
    );
    let frame = image::open(&photo).expect("bus.jpg decodes").to_rgb8();
    let (w, h) = frame.dimensions();
    let boxes = detector.detect(&frame, 0).expect("runs");
    let of = |name: &str| {
        let t = TowerType::new(name).expect("a class name");
        boxes
            .iter()
            .filter(|d| d.tower_type == t && d.score >= 0.4)
            .collect::<Vec<_>>()
    };
    let people = of("person");
    let buses = of("bus");
    assert!(people.len() >= 3, "people: {people:?} of {boxes:?}");
    assert_eq!(buses.len(), 1, "buses: {buses:?} of {boxes:?}");
    // The bus fills most of the photo's width; the people stand on the ground below its roof.
    let bus = buses[0].bbox;
    assert!(bus.width() > 0.7 * w as f64, "{bus:?}");
    for person in &people {
        assert!(person.bbox.height() > 0.25 * h as f64, "{person:?}");
        assert!(person.bbox.bottom > bus.top, "{person:?} below {bus:?}");
    }
}
