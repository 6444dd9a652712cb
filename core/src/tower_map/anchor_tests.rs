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
    let s = shift(&feet, &covariances, &paired).expect("a shift");
    // East: both say 0.5 alike. North: 0.5 at weight 1/0.0101, 2.5 at
    // weight 1/1.0001.
    let (w1, w2) = (1.0 / 0.0101, 1.0 / 1.0001);
    let north = (0.5 * w1 + 2.5 * w2) / (w1 + w2);
    assert!(
        (s.by - Vector2::new(0.5, north)).norm() < 1e-9,
        "{:?}",
        s.by
    );
    assert!((s.covariance[(1, 1)] - 1.0 / (w1 + w2)).abs() < 1e-12);
    assert_eq!(shift(&feet, &covariances, &[None, None]), None);
}
