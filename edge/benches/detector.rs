//! The shipped tower detector on one 1280x720 rendered frame, pre- and
//! post-processing included, on ONNX Runtime's CPU provider with 2 threads
//! (this project's target machine): the detector alone, and with the
//! tower-type classifier on each box (what the edge runs). Needs the ONNX
//! Runtime library (`cargo xtask setup-ort`) and `models/towers.onnx`
//! (`models/tower-types.onnx` for the second); says so and skips the model
//! runs when one is missing.

use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use towernav_edge::detector::{CropBatch, Preprocessor};
use towernav_edge::shell::yolo::{DetectorOptions, YoloDetector};
use towernav_sim::{Scenario, World};

fn detector(c: &mut Criterion) {
    let scenario = match Scenario::preset(World::seed_field(), "seed-path-1", 1) {
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
        .map(|b| towernav_edge::detector::type_stage::crop_square(&b.bbox))
        .collect();
    let mut crops = CropBatch::new(64, 64);
    c.bench_function(&format!("type_crops_{}boxes", regions.len()), |b| {
        b.iter(|| crops.cut(&frame, &regions).map(|batch| batch.len()))
    });

    let model = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models/towers.onnx");
    let threads = std::env::var("TOWERNAV_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(2);
    let options = DetectorOptions {
        threads,
        ..DetectorOptions::default()
    };
    let types = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../models/tower-types.onnx");
    for (suffix, type_model) in [("", None), ("_with_types", Some(types.as_path()))] {
        match YoloDetector::load_with_types(&model, type_model, &options) {
            Ok(mut detector) => {
                let boxes = detector.detect(&frame, 0).map_or(0, |d| d.len());
                let input = format!(
                    "detect_1280x720_{}x{}_{}threads{suffix}_{boxes}boxes",
                    detector.info().input_width,
                    detector.info().input_height,
                    threads
                );
                c.bench_function(&input, |b| {
                    b.iter(|| detector.detect(&frame, 0).map(|d| d.len()))
                });
            }
            Err(e) => eprintln!("skipping the model benchmark{suffix}: {e}"),
        }
    }
}

criterion_group!(benches, detector);
criterion_main!(benches);
