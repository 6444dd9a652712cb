//! The mapper on synthetic tracks: pieces of one tower become one tower
//! with all their views, and a few short tracks that happen to cross make
//! no tower.

use nalgebra::{Point2, Point3};

use super::*;

fn view(time_s: f64, camera: Point3<f64>, foot: Point3<f64>) -> TowerView {
    let ray = |z: f64| Point3::new(foot.x, foot.y, foot.z + z) - camera;
    TowerView {
        time_s,
        camera_in_world: camera,
        centre_ray: ray(15.0),
        top_ray: ray(30.0),
        foot_ray: ray(0.0),
        cut: false,
    }
}

/// A pass east along `north`, from east -150 to 150, 10 frames a second.
fn pass(start_s: f64, north: f64, foot: Point3<f64>) -> Vec<TowerView> {
    (0..300)
        .map(|i| {
            let camera = Point3::new(-150.0 + i as f64, north, 60.0);
            view(start_s + i as f64 / 10.0, camera, foot)
        })
        .collect()
}

fn cluster(views: Vec<TowerView>, id: u64) -> Cluster {
    Cluster {
        at: Point2::origin(),
        gate: 0.0,
        ids: vec![id],
        views,
    }
}

#[test]
fn two_clusters_of_one_tower_become_one_with_all_its_views() {
    let foot = Point3::new(0.0, 150.0, 0.0);
    let p = TriangulationParams::default();
    // The second pass logged 4 m east of where it flew.
    let moved: Vec<TowerView> = pass(100.0, -50.0, foot)
        .into_iter()
        .map(|v| TowerView {
            camera_in_world: v.camera_in_world + nalgebra::Vector3::new(4.0, 0.0, 0.0),
            ..v
        })
        .collect();
    let groups = merge_duplicates(
        vec![cluster(pass(0.0, 0.0, foot), 1), cluster(moved, 2)],
        &p,
    );
    assert_eq!(groups.len(), 1);
    assert_eq!(groups[0].2.len(), 600);
    assert_eq!(groups[0].1, vec![1, 2]);
    // Far apart, two towers stay two.
    let other = Point3::new(0.0, 400.0, 0.0);
    let groups = merge_duplicates(
        vec![
            cluster(pass(0.0, 0.0, foot), 1),
            cluster(pass(100.0, 250.0, other), 2),
        ],
        &p,
    );
    assert_eq!(groups.len(), 2);
}

#[test]
fn a_few_short_tracks_that_cross_make_no_tower() {
    let foot = Point3::new(0.0, 150.0, 0.0);
    let ghost = Point3::new(60.0, 260.0, 0.0);
    let mut mapper = TowerMapper::default();
    for v in pass(0.0, 0.0, foot) {
        mapper.add(1, TowerType::A, v);
    }
    // Four tracks of half a second each, from four places, minutes apart.
    for (k, (east, north)) in [
        (-100.0, 0.0),
        (200.0, 100.0),
        (-50.0, 400.0),
        (250.0, 350.0),
    ]
    .into_iter()
    .enumerate()
    {
        for i in 0..5 {
            let camera = Point3::new(east + i as f64, north, 60.0);
            mapper.add(
                10 + k as u64,
                TowerType::A,
                view(60.0 * (k + 1) as f64 + i as f64 / 10.0, camera, ghost),
            );
        }
    }
    let towers = mapper.finish(&TriangulationParams::default(), Some(0.0), &[]);
    let solid: Vec<_> = towers.iter().filter(|t| t.is_solid(3.0)).collect();
    assert_eq!(solid.len(), 1, "{towers:#?}");
    let stray = towers
        .iter()
        .find(|t| !t.is_solid(3.0))
        .expect("the stray cluster");
    let doubt = stray.doubt(3.0).expect("a reason");
    assert!(doubt.starts_with("seen for 0.4 s at most"), "{doubt}");
    assert!((solid[0].estimate.foot_in_world - foot).norm() < 0.5);
    assert_eq!(solid[0].estimate.views, 300);
    assert!(solid[0].followed_s >= 29.0);
}

#[test]
fn a_flight_logged_off_by_one_offset_is_moved_onto_its_surveyed_tower() {
    // Two towers, each passed on both sides, every pose logged 1.2 m east
    // and 0.9 m north of where it was: the views agree with each other, so
    // the towers land off by the same. One tower surveyed to 5 cm brings
    // the other back.
    let (a, b) = (Point3::new(0.0, 150.0, 0.0), Point3::new(40.0, 450.0, 0.0));
    let off = nalgebra::Vector3::new(1.2, 0.9, 0.0);
    let mut mapper = TowerMapper::default();
    for (id, foot, start_s, north) in [
        (1, a, 0.0, 0.0),
        (2, a, 40.0, 300.0),
        (3, b, 80.0, 300.0),
        (4, b, 120.0, 600.0),
    ] {
        for v in pass(start_s, north, foot) {
            mapper.add(
                id,
                TowerType::A,
                TowerView {
                    camera_in_world: v.camera_in_world + off,
                    ..v
                },
            );
        }
    }
    let p = TriangulationParams::default();
    let free = mapper.finish(&p, Some(0.0), &[]);
    let near = |towers: &[MappedTower], foot: Point3<f64>| {
        towers
            .iter()
            .find(|t| (t.estimate.foot_in_world - foot).norm() < 5.0)
            .cloned()
            .expect("found")
    };
    assert!((near(&free, b).estimate.foot_in_world - (b + off)).norm() < 0.2);
    let surveyed = Anchor {
        foot: a.xy(),
        sigma_m: 0.05,
    };
    let held = mapper.finish(&p, Some(0.0), &[surveyed]);
    let (ta, tb) = (near(&held, a), near(&held, b));
    assert!(ta.anchored && !tb.anchored);
    // Most of the way: the shift's prior (the GNSS sigma, 1.5 m) keeps a
    // share of an offset as large as itself.
    let left = (tb.estimate.foot_in_world - b).norm();
    assert!(
        left < 0.4 * off.norm(),
        "{left:.2} m left of {:.2}",
        off.norm()
    );
}
