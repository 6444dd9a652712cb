//! ONNX Runtime loaded at run time and a re-identification model run on crops
//! (the fixture `tests/fixtures/reid-tiny.onnx`, made by `make_reid_model.py`),
//! and each way it can fail: no library, a corrupt model, a model of the wrong shape.

use std::path::PathBuf;

use image::{Rgb, RgbImage};
use towernav_geometry::PixelBox;
use towernav_onnx::runtime::{OnnxError, ReidModel, locate_runtime_from};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

#[test]
fn the_model_embeds_crops_that_look_different_differently() {
    let mut model = ReidModel::load(&fixture("reid-tiny.onnx"), 1).expect("runtime and model load");
    let mut img = RgbImage::from_pixel(200, 120, Rgb([40, 90, 200]));
    for y in 10..60 {
        for x in 120..150 {
            img.put_pixel(x, y, Rgb([220, 210, 30]));
        }
    }
    let sky = PixelBox::new(10.0, 10.0, 40.0, 110.0);
    let half_yellow = PixelBox::new(120.0, 10.0, 150.0, 110.0);
    let e = model.embed(&img, &[sky, half_yellow, sky]).expect("runs");
    assert_eq!(e.len(), 3);
    assert_eq!(e[0].len(), 6);
    let dot = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f32>();
    assert!((dot(&e[0], &e[0]) - 1.0).abs() < 1e-4, "normalised");
    assert!(
        (dot(&e[0], &e[2]) - 1.0).abs() < 1e-5,
        "same crop, same embedding"
    );
    assert!(dot(&e[0], &e[1]) < 0.95, "a different crop differs");
    assert!(model.embed(&img, &[]).expect("no boxes").is_empty());
}

#[test]
fn bad_models_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    let corrupt = dir.path().join("corrupt.onnx");
    std::fs::write(&corrupt, b"this is not a protobuf").expect("write");
    let err = ReidModel::load(&corrupt, 1)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("corrupt.onnx") && err.contains("not a loadable ONNX model"),
        "{err}"
    );
    let missing = ReidModel::load(&dir.path().join("missing.onnx"), 1)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        missing.contains("missing.onnx") && missing.contains("cannot read"),
        "{missing}"
    );
}

#[test]
fn without_a_library_the_error_names_both_ways_to_fix_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let err = locate_runtime_from(Some(dir.path().join("nope.so")), dir.path())
        .expect_err("nothing there");
    assert!(matches!(err, OnnxError::NoLibrary { .. }));
    let text = err.to_string();
    assert!(
        text.contains("cargo xtask setup-ort") && text.contains("ORT_DYLIB_PATH"),
        "{text}"
    );
    assert!(text.contains("nope.so"), "says where it looked: {text}");
}
