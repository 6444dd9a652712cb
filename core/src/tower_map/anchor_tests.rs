use nalgebra::{Matrix2, Point2, Vector2};

use super::*;

#[test]
fn a_surveyed_record_anchors_the_tower_it_fits_and_one_the_flight_contradicts_anchors_nothing() {
    let feet = [Point2::new(0.0, 0.0), Point2::new(200.0, 0.0)];
    // Placed to 0.2 m by their ellipses, which hold the flight's shared
    // GNSS error only roughly: a record 1 m off is still that tower's.
    let covariances = [Matrix2::identity() * 0.04; 2];
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
    let held = pair(&feet, &covariances, &anchors);
    assert_eq!(held, vec![Some(anchors[0]), None]);
}

#[test]
fn the_shift_weighs_each_anchor_by_how_well_both_know_it() {
    let feet = [Point2::new(0.0, 0.0), Point2::new(300.0, 0.0)];
    // The first tower placed to 0.1 m, the second to 1 m along north.
    let covariances = [
        Matrix2::identity() * 0.01,
        Matrix2::new(0.01, 0.0, 0.0, 1.0),
    ];
    let paired = [
        Some(Anchor {
            foot: Point2::new(0.5, 0.5),
            sigma_m: 0.0,
        }),
        Some(Anchor {
            foot: Point2::new(300.5, 2.5),
            sigma_m: 0.0,
        }),
    ];
    // A 2 m prior: weight 1/4 on no shift.
    let s = shift(&feet, &covariances, &paired, 2.0).expect("a shift");
    // North: 0.5 at weight 1/0.0101, 2.5 at 1/1.0001; east: both 0.5 at
    // 1/0.0101.
    let (w1, w2, w0) = (1.0 / 0.0101, 1.0 / 1.0001, 0.25);
    let north = (0.5 * w1 + 2.5 * w2) / (w1 + w2 + w0);
    let east = 0.5 * 2.0 * w1 / (2.0 * w1 + w0);
    assert!(
        (s.by - Vector2::new(east, north)).norm() < 1e-9,
        "{:?}",
        s.by
    );
    assert!((s.covariance[(1, 1)] - 1.0 / (w1 + w2 + w0)).abs() < 1e-12);
    assert_eq!(shift(&feet, &covariances, &[None, None], 2.0), None);
}

#[test]
fn one_anchor_placed_loosely_along_its_rays_moves_the_rest_by_little_along_them() {
    // The tower placed to 3 m east-west, 0.3 m north-south; its record
    // 2.5 m west and 0.5 m north of it.
    let feet = [Point2::new(0.0, 0.0)];
    let covariances = [Matrix2::new(9.0, 0.0, 0.0, 0.09)];
    let paired = [Some(Anchor {
        foot: Point2::new(-2.5, 0.5),
        sigma_m: 0.1,
    })];
    let s = shift(&feet, &covariances, &paired, 1.5).expect("a shift");
    assert!(s.by.x > -0.6 && s.by.x < -0.4, "{:?}", s.by);
    assert!(s.by.y > 0.45, "{:?}", s.by);
}
