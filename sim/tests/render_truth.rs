//! The truth boxes agree with the rendered pixels: render a tower, render the
//! same view without it, and compare the changed pixels' extent with the box
//! projected from the 3-D model.

use nalgebra::{Point3, Vector3};
use towernav_geometry::{Attitude, PinholeCamera, Pose};
use towernav_protocol::TowerType;
use towernav_sim::truth::truth_box;
use towernav_sim::{Conditions, Renderer, SimTower, World};

fn world_with(towers: Vec<SimTower>) -> World {
    World {
        datum: World::paper_field().datum,
        towers,
        lines: Vec::new(),
        distractors: Vec::new(),
    }
}

/// Extent (left, top, right, bottom) of the pixels that differ between two renders.
fn changed_extent(a: &image::RgbImage, b: &image::RgbImage) -> Option<(f64, f64, f64, f64)> {
    let mut ext: Option<(u32, u32, u32, u32)> = None;
    for (x, y, p) in a.enumerate_pixels() {
        let q = b.get_pixel(x, y);
        let diff = (0..3)
            .map(|c| (i16::from(p[c]) - i16::from(q[c])).abs())
            .max()
            .unwrap_or(0);
        if diff > 4 {
            ext = Some(match ext {
                None => (x, y, x, y),
                Some((l, t, r, btm)) => (l.min(x), t.min(y), r.max(x), btm.max(y)),
            });
        }
    }
    ext.map(|(l, t, r, b)| {
        (
            f64::from(l),
            f64::from(t),
            f64::from(r + 1),
            f64::from(b + 1),
        )
    })
}

fn check(tower_type: TowerType, distance: f64, line_yaw: f64, attitude: Attitude) {
    let tower = SimTower {
        id: "T1".into(),
        tower_type,
        foot_in_world: Point3::new(distance, 12.0, 0.0),
        height_m: 40.0,
        base_width_m: 7.0,
        line_yaw,
    };
    let camera = PinholeCamera::default_hd();
    let pose = Pose {
        position_in_world: Point3::new(0.0, 0.0, 30.0),
        attitude,
    };
    let conditions = Conditions::plain();
    let with = Renderer::new(&world_with(vec![tower.clone()]), camera, 1).render(
        &pose,
        &conditions,
        (0.0, 0.0, 0.0),
        0,
    );
    let without = Renderer::new(&world_with(Vec::new()), camera, 1).render(
        &pose,
        &conditions,
        (0.0, 0.0, 0.0),
        0,
    );
    let (l, t, r, b) = changed_extent(&with, &without).expect("the tower changes pixels");
    let truth = truth_box(&camera, &pose, &tower).expect("in view").bbox;
    let what = format!(
        "{tower_type} at {distance} m, yaw {line_yaw}: pixels ({l},{t},{r},{b}) truth {truth:?}"
    );
    // Members have width and antialiasing: allow two pixels either side.
    assert!((l - truth.left).abs() <= 2.5, "left: {what}");
    assert!((r - truth.right).abs() <= 2.5, "right: {what}");
    assert!((t - truth.top).abs() <= 2.5, "top: {what}");
    // The box bottom is the foot on the axis (the labeling convention); the
    // near legs stand in front of it and reach lower in the image.
    let camera_from_world = camera.world_from_camera(&pose).inverse();
    let lowest_leg = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
        .iter()
        .filter_map(|(sx, sy)| {
            let corner = tower.foot_in_world + Vector3::new(sx * 3.5, sy * 3.5, 0.0);
            camera.project(&(camera_from_world * corner))
        })
        .map(|p| p.y)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        b >= truth.bottom - 1.0 && b <= lowest_leg + 2.5,
        "bottom {b} not between the axis foot {} and the lowest leg {lowest_leg}: {what}",
        truth.bottom
    );
}

#[test]
fn rendered_towers_fill_their_truth_boxes_for_every_type() {
    for t in TowerType::ALL {
        check(t, 150.0, 0.0, Attitude::level(0.0));
    }
}

#[test]
fn truth_holds_far_away_rotated_and_from_a_tilted_camera() {
    check(TowerType::B, 400.0, 0.7, Attitude::level(0.0));
    check(
        TowerType::C,
        120.0,
        -0.4,
        Attitude {
            roll: 0.12,
            pitch: -0.1,
            yaw: 0.05,
        },
    );
}
