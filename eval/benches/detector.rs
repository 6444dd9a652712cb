//! The shipped tower detector on one 1280x720 rendered frame, pre- and
//! post-processing included, on ONNX Runtime's CPU provider with 2 threads
//! (this project's target machine): the float export alone, the INT8 one
//! alone, and the INT8 one with the INT8 tower-type classifier on each box
//! (what the daemon runs). Needs the ONNX Runtime library (`cargo xtask
//! setup-ort`) and the models in `models/`; says so and skips a run whose
//! model is missing.

use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use towernav_core::detector::{CropBatch, Preprocessor};
use towernav_onnx::yolo::{DetectorOptions, YoloDetector};
use towernav_sim::{Scenario, World};

fn detector(c: &mut Criterion) {
    let scenario = match Scenario::preset(World::paper_field(), "paper-path-1", 1) {
        Ok(s) => s,
        Err(e) => panic!("preset: {e}"),
    };
    let renderer = scenario.renderer();
    let mut buffers = renderer.buffers();
    let truth = scenario.truth(24 * 30);
    scenario.render_into(&renderer, &mut buffers, &truth, &Default::default());
    let frame = buffers.image;

    let mut pre = Preprocessor::new(512, 320);
    c.bench_function("letterbox_1280x720_to_512x320", |b| {
        b.iter(|| pre.run(&frame, 0).map(|(lb, _)| lb.scale))
    });

    let regions: Vec<_> = truth
        .boxes
        .iter()
        .map(|b| towernav_core::detector::type_stage::crop_square(&b.bbox))
        .collect();
    let mut crops = CropBatch::new(64, 64);
    c.bench_function(&format!("type_crops_{}boxes", regions.len()), |b| {
        b.iter(|| crops.cut(&frame, &regions).map(|batch| batch.len()))
    });

    let models = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models");
    let threads = std::env::var("TOWERNAV_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(2);
    let options = DetectorOptions {
        threads,
        ..DetectorOptions::default()
    };
    let types = models.join("tower-types-int8.onnx");
    let runs = [
        ("float", "towers.onnx", None),
        ("int8", "towers-int8.onnx", None),
        // What the daemon runs by default.
        ("int8_with_types", "towers-int8.onnx", Some(types.as_path())),
    ];
    for (name, model, type_model) in runs {
        match YoloDetector::load_with_types(&models.join(model), type_model, &options) {
            Ok(mut detector) => {
                let boxes = detector.detect(&frame, 0).map_or(0, |d| d.len());
                let id = format!(
                    "detect_1280x720_{}x{}_{threads}threads_{name}_{boxes}boxes",
                    detector.info().input_width,
                    detector.info().input_height,
                );
                c.bench_function(&id, |b| {
                    b.iter(|| detector.detect(&frame, 0).map(|d| d.len()))
                });
            }
            Err(e) => eprintln!("skipping the {name} model benchmark: {e}"),
        }
    }
}

criterion_group!(benches, detector);
criterion_main!(benches);
