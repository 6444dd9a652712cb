//! Estimator plus filter for one frame: ours (robust rays) and the EKF step,
//! on the paper's-field frame with the most towers in view; the paper's method alongside.

use criterion::{Criterion, criterion_group, criterion_main};
use towernav_core::LandmarkMap;
use towernav_core::filter::{FilterParams, PoseFilter};
use towernav_core::localizer::{Height, LocalizerParams, Observation, paper_lbl, robust_lbl};
use towernav_sim::{Scenario, World};

fn localizer(c: &mut Criterion) {
    let scenario = Scenario::preset(World::paper_field(), "paper-path-1", 1).expect("preset");
    let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
    // The busiest of the first 30 s: oracle detections bound to their true towers.
    let (truth, frame) = scenario
        .frames()
        .take(900)
        .max_by_key(|(_, f)| f.detections.len())
        .expect("frames");
    let observations: Vec<Observation> = frame
        .detections
        .iter()
        .filter_map(|d| {
            let b = truth
                .boxes
                .iter()
                .max_by(|a, b| a.bbox.iou(&d.bbox).total_cmp(&b.bbox.iou(&d.bbox)))?;
            Some(Observation::new(
                &map.towers[map.index_of(&b.tower_id)?],
                d.bbox,
                d.score,
            ))
        })
        .collect();
    let params = LocalizerParams::default();
    let name = format!("rays_plus_ekf_{}_towers", observations.len());
    let mut filter = PoseFilter::new(FilterParams::default());
    let mut t = 0.0;
    c.bench_function(&name, |b| {
        b.iter(|| {
            let fix = robust_lbl(
                &observations,
                &scenario.camera,
                &frame.imu_attitude,
                None,
                &params,
            )
            .map(|r| r.fix);
            t += 1.0 / 30.0;
            filter.step(t, fix.as_ref(), frame.imu_attitude.yaw, 1e-5)
        })
    });
    c.bench_function(&format!("paper_{}_towers", observations.len()), |b| {
        b.iter(|| {
            paper_lbl(
                &observations,
                &scenario.camera.intrinsics,
                frame.imu_attitude.yaw,
                Height::unknown(30.0),
                &params,
            )
        })
    });
}

criterion_group!(benches, localizer);
criterion_main!(benches);
