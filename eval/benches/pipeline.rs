//! Cost of the pure pipeline (tracker, identity, localizer) per frame on the paper's flight.
//!
//! `cargo bench -p towernav-eval --bench pipeline`; throughput is in frames.

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use towernav_core::{LandmarkMap, Pipeline, PipelineConfig};
use towernav_protocol::DetectionFrame;
use towernav_sim::Scenario;

fn paper_flight(c: &mut Criterion) {
    let scenario = Scenario::paper(1);
    let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
    let config = PipelineConfig::new(scenario.camera, scenario.start_in_world());
    let frames: Vec<DetectionFrame> = scenario.frames().map(|(_, f)| f).collect();

    let mut group = c.benchmark_group("pipeline");
    group.throughput(Throughput::Elements(frames.len() as u64));
    group.sample_size(20);
    group.bench_function("seed_flight_2850_frames", |b| {
        b.iter_batched(
            || Pipeline::new(config.clone(), map.clone()),
            |mut pipeline| {
                let mut fixes = 0usize;
                for frame in &frames {
                    fixes +=
                        usize::from(pipeline.process(std::hint::black_box(frame)).fix.is_some());
                }
                fixes
            },
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, paper_flight);
criterion_main!(benches);
