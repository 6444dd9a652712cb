//! Tracker plus identity per frame with 20 towers in view: SORT with
//! camera-motion compensation and map-based identity against a trusted pose.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Point3;
use towernav_core::identity::{Identity, IdentityParams, View};
use towernav_core::landmarks::{LandmarkMap, MapTower};
use towernav_core::tracker::{CameraMotion, SortParams, SortTracker, Tracker, TrackerInput};
use towernav_geometry::{Attitude, Datum, Geodetic, PinholeCamera, PixelBox, Pose};
use towernav_protocol::{Detection, TowerType};

fn tracking(c: &mut Criterion) {
    let camera = PinholeCamera::default_hd();
    // 20 towers ahead in two rows, all in view.
    let towers: Vec<MapTower> = (0..20)
        .map(|i| MapTower {
            id: format!("T{i}"),
            tower_type: TowerType::ALL[i % 4],
            foot_in_world: Point3::new(
                150.0 + 40.0 * (i / 2) as f64,
                if i % 2 == 0 { 60.0 } else { -60.0 },
                0.0,
            ),
            height_m: 40.0,
            sigma_horizontal_m: 0.5,
            sigma_vertical_m: 0.5,
        })
        .collect();
    let datum = Datum::new(Geodetic {
        lat_deg: 30.5,
        lon_deg: 114.3,
        height_m: 0.0,
    });
    let map = LandmarkMap::new(towers, datum);
    let frames: Vec<(f64, Pose, Vec<Detection>)> = (0..60)
        .map(|k| {
            let t = f64::from(k) / 30.0;
            let pose = Pose {
                position_in_world: Point3::new(10.0 * t, 0.0, 30.0),
                attitude: Attitude {
                    roll: 0.0,
                    pitch: -0.08,
                    yaw: 0.002 * f64::from(k),
                },
            };
            let cfw = camera.world_from_camera(&pose).inverse();
            let dets = map
                .towers
                .iter()
                .filter_map(|tw| {
                    let f = camera.project(&(cfw * tw.foot_in_world))?;
                    let top = camera.project(&(cfw * tw.top_in_world()))?;
                    let w = (f.y - top.y) / 4.0;
                    Some(Detection {
                        bbox: PixelBox::new(f.x - w / 2.0, top.y, f.x + w / 2.0, f.y),
                        tower_type: tw.tower_type,
                        score: 0.9,
                    })
                })
                .collect();
            (t, pose, dets)
        })
        .collect();
    assert_eq!(frames[0].2.len(), 20, "all 20 towers in view");
    let all: Vec<usize> = (0..map.towers.len()).collect();
    c.bench_function("sort_cmc_plus_identity_20_towers", |b| {
        b.iter_batched(
            || {
                (
                    SortTracker::new(SortParams::default()),
                    Identity::new(IdentityParams::default()),
                )
            },
            |(mut tracker, mut identity)| {
                let mut prev: Option<Attitude> = None;
                for (t, pose, dets) in &frames {
                    let motion = prev.map(|p| CameraMotion::between(&camera, &p, &pose.attitude));
                    prev = Some(pose.attitude);
                    let out = tracker.step(&TrackerInput {
                        time_s: *t,
                        detections: dets,
                        motion: motion.as_ref(),
                        features: None,
                    });
                    let live = Tracker::live_ids(&tracker);
                    let view = View {
                        guess: pose,
                        trusted: true,
                        camera: &camera,
                        map: &map,
                    };
                    std::hint::black_box(identity.update(&out, &live, view, || all.clone()));
                }
            },
            criterion::BatchSize::SmallInput,
        )
    });
}

criterion_group!(benches, tracking);
criterion_main!(benches);
