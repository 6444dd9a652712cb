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
fn a_surveyed_record_anchors_the_tower_it_fits_and_one_the_flight_contradicts_anchors_nothing() {
    let feet = [Point2::new(0.0, 0.0), Point2::new(200.0, 0.0)];
    // Placed to 0.5 m, the flight's shared error included.
    let covariances = [nalgebra::Matrix2::identity() * 0.25; 2];
    let anchors = [
        Anchor {
            foot: Point2::new(0.8, -0.6),
            sigma_m: 0.1,
        },
        // 6 m off while claiming 10 cm: a record moved by a typing slip.
        Anchor {
            foot: Point2::new(206.0, 0.0),
            sigma_m: 0.1,
        },
        // A second record on the first tower, further off: the nearer wins.
        Anchor {
            foot: Point2::new(1.2, 0.5),
            sigma_m: 0.1,
        },
    ];
    let held = anchored(&feet, &covariances, &anchors);
    assert_eq!(held, vec![Some(anchors[0]), None]);
}
