//! Synthetic views of a known tower: exact rays give the tower back; noisy
//! ones stay inside their reported ellipse; bad geometry gives nothing.

use proptest::prelude::*;

use super::*;

/// A view from `camera` of a tower with its foot at `foot` and `height`,
/// the rays turned by `bearing_error` rad about the vertical.
fn view(camera: Point3<f64>, foot: Point3<f64>, height: f64, bearing_error: f64) -> TowerView {
    view_at(0.0, camera, foot, height, bearing_error)
}

fn view_at(
    time_s: f64,
    camera: Point3<f64>,
    foot: Point3<f64>,
    height: f64,
    bearing_error: f64,
) -> TowerView {
    let turn = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), bearing_error);
    let ray = |z: f64| turn * (Point3::new(foot.x, foot.y, foot.z + z) - camera);
    TowerView {
        time_s,
        camera_in_world: camera,
        centre_ray: ray(height / 2.0),
        top_ray: ray(height),
        foot_ray: ray(0.0),
        cut: false,
    }
}

/// Cameras along a pass `offset` metres beside the tower, `n` of them.
fn pass(offset: f64, n: usize) -> Vec<Point3<f64>> {
    (0..n)
        .map(|i| Point3::new(-150.0 + 300.0 * i as f64 / (n - 1) as f64, offset, 60.0))
        .collect()
}

proptest! {
    #[test]
    fn exact_views_give_the_tower_back(
        east in -50.0f64..50.0, north in 100.0f64..200.0, ground in -20.0f64..40.0,
        height in 15.0f64..60.0, n in 5usize..40,
    ) {
        let foot = Point3::new(east, north, ground);
        let views: Vec<_> = pass(0.0, n).into_iter().map(|c| view(c, foot, height, 0.0)).collect();
        let e = triangulate(&views, &TriangulationParams::default()).expect("an estimate");
        prop_assert!((e.foot_in_world - foot).norm() < 1e-6, "{:?}", e.foot_in_world);
        prop_assert!((e.height_m.expect("height") - height).abs() < 1e-6);
        prop_assert_eq!(e.views, n);
        // The far end of the pass (beyond twice the nearest views' range)
        // gives no height.
        prop_assert!(e.height_views >= n / 2 && e.height_views <= n, "{}", e.height_views);
    }

    #[test]
    fn noisy_bearings_stay_inside_the_reported_ellipse(
        errors in prop::collection::vec(-1.0f64..1.0, 30),
    ) {
        let foot = Point3::new(10.0, 120.0, 5.0);
        let p = TriangulationParams { position_sigma_m: 0.0, ..TriangulationParams::default() };
        // One view a second: each bearing error its own.
        let views: Vec<_> = pass(0.0, 30)
            .into_iter()
            .zip(&errors)
            .enumerate()
            // Uniform over +-1.7 sigma: one sigma of spread.
            .map(|(i, (c, e))| view_at(i as f64, c, foot, 30.0, e * p.bearing_sigma_rad * 1.7))
            .collect();
        let e = triangulate(&views, &p).expect("an estimate");
        let d = (e.foot_in_world - foot).xy();
        let m2 = (d.transpose() * e.covariance_en.try_inverse().expect("invertible") * d)[0];
        // Chi-square with 2 degrees of freedom: 99.9 % inside 13.8.
        prop_assert!(m2 < 13.8, "Mahalanobis^2 {m2}, off by {:?}", d);
    }
}

/// A long pass of exact views, 200 s of them: the reading's own error is
/// nil, yet the height keeps what the detector's rows on one tower share.
#[test]
fn however_many_views_agree_a_height_keeps_its_rows_error() {
    let foot = Point3::new(0.0, 120.0, 0.0);
    let views: Vec<_> = pass(0.0, 200)
        .into_iter()
        .enumerate()
        .map(|(i, c)| view_at(i as f64, c, foot, 15.0, 0.0))
        .collect();
    let e = triangulate(&views, &TriangulationParams::default()).expect("an estimate");
    assert!((e.height_m.expect("height") - 15.0).abs() < 1e-6);
    assert!(
        (e.height_sigma_m - TOWER_ROWS_SIGMA_M).abs() < 0.05,
        "{}",
        e.height_sigma_m
    );
}

#[test]
fn one_wild_view_does_not_move_the_foot() {
    let foot = Point3::new(0.0, 150.0, 0.0);
    let mut views: Vec<_> = pass(0.0, 20)
        .into_iter()
        .map(|c| view(c, foot, 30.0, 0.0))
        .collect();
    views[7] = view(views[7].camera_in_world, foot, 30.0, 0.3);
    let e = triangulate(&views, &TriangulationParams::default()).expect("an estimate");
    assert!(
        (e.foot_in_world - foot).xy().norm() < 0.5,
        "{:?}",
        e.foot_in_world
    );
}

#[test]
fn views_from_one_direction_give_nothing() {
    // Flying straight at the tower: every bearing the same.
    let foot = Point3::new(0.0, 500.0, 0.0);
    let views: Vec<_> = (0..20)
        .map(|i| view(Point3::new(0.0, f64::from(i) * 10.0, 60.0), foot, 30.0, 0.0))
        .collect();
    assert!(triangulate(&views, &TriangulationParams::default()).is_none());
    let few: Vec<_> = pass(0.0, 4)
        .into_iter()
        .map(|c| view(c, Point3::new(0.0, 150.0, 0.0), 30.0, 0.0))
        .collect();
    assert!(triangulate(&few, &TriangulationParams::default()).is_none());
}

#[test]
fn cut_views_place_the_foot_but_give_no_height() {
    let foot = Point3::new(0.0, 150.0, 3.0);
    let views: Vec<_> = pass(0.0, 10)
        .into_iter()
        .map(|c| TowerView {
            cut: true,
            ..view(c, foot, 30.0, 0.0)
        })
        .collect();
    let e = triangulate(&views, &TriangulationParams::default()).expect("an estimate");
    assert_eq!(e.height_m, None);
    assert!((e.foot_in_world.z - 3.0).abs() < 1e-6);
}

#[test]
fn frames_of_one_second_do_not_shrink_the_ellipse_as_independent_views_would() {
    let foot = Point3::new(0.0, 150.0, 0.0);
    let p = TriangulationParams::default();
    let cameras = pass(0.0, 300);
    // 300 frames in 10 s against 300 frames over 300 s.
    let burst: Vec<_> = cameras
        .iter()
        .enumerate()
        .map(|(i, c)| view_at(i as f64 / 30.0, *c, foot, 30.0, 0.0))
        .collect();
    let slow: Vec<_> = cameras
        .iter()
        .enumerate()
        .map(|(i, c)| view_at(i as f64, *c, foot, 30.0, 0.0))
        .collect();
    let burst = triangulate(&burst, &p).expect("an estimate");
    let slow = triangulate(&slow, &p).expect("an estimate");
    // The GNSS error of one 10 s stretch stays whole.
    assert!(burst.sigma_horizontal_m() >= p.position_sigma_m * 0.99);
    assert!(slow.sigma_horizontal_m() < 0.5 * burst.sigma_horizontal_m());
}

#[test]
fn near_views_set_the_height_where_far_ones_are_many() {
    // 10 views from 100-150 m, exact; 40 from 400-500 m whose top rows sit
    // low (a far tower's thin top lost by the detector).
    let foot = Point3::new(0.0, 0.0, 0.0);
    let at = |i: usize, range: f64, top_error: f64| {
        // Round the tower, 40 degrees of arc.
        let angle = ((i % 10) as f64 / 9.0 - 0.5) * 40_f64.to_radians();
        let camera = Point3::new(-range * angle.cos(), range * angle.sin(), 60.0);
        let mut v = view_at(i as f64, camera, foot, 40.0, 0.0);
        v.top_ray = Point3::new(foot.x, foot.y, 40.0 - top_error) - camera;
        v
    };
    let mut views: Vec<_> = (0..10)
        .map(|i| at(i, 100.0 + 5.0 * i as f64, 0.0))
        .collect();
    views.extend((0..40).map(|i| at(10 + i, 400.0 + 2.5 * i as f64, 4.0)));
    let e = triangulate(&views, &TriangulationParams::default()).expect("an estimate");
    let height = e.height_m.expect("a height");
    assert!((height - 40.0).abs() < 0.2, "height {height}");
}
