use super::*;

/// A flight east at 10 m/s and north at 2 m/s, fixes at 10 Hz, the logged
/// position off by `error(t)`; `velocity` gives each fix's velocity.
fn fixes(
    times: impl Iterator<Item = f64>,
    error: impl Fn(f64) -> Vector2<f64>,
    velocity: impl Fn(f64) -> Vector2<f64>,
) -> Vec<DriftFix> {
    times
        .map(|t| DriftFix {
            time_s: t,
            position: Point2::new(10.0 * t, 2.0 * t) + error(t),
            velocity: velocity(t),
        })
        .collect()
}

fn wander(t: f64) -> Vector2<f64> {
    Vector2::new(1.5 * (t / 7.0).sin(), -0.8 * (t / 4.0).cos())
}

fn true_velocity(_: f64) -> Vector2<f64> {
    Vector2::new(10.0, 2.0)
}

#[test]
fn the_change_between_two_times_is_the_gnss_errors() {
    let drift = GnssDrift::new(&fixes(
        (0..600).map(|i| f64::from(i) * 0.1),
        wander,
        true_velocity,
    ));
    for (a, b) in [(1.0, 2.0), (3.05, 41.7), (50.0, 12.5)] {
        let change = drift.change(a, b).expect("inside the flight");
        let truth = wander(b) - wander(a);
        // Linear between fixes 0.1 s apart: a sine's curvature, millimetres.
        assert!(
            (change - truth).norm() < 5e-3,
            "{a}-{b}: {change:?} against {truth:?}"
        );
    }
    assert_eq!(drift.change(-1.0, 2.0), None);
    assert_eq!(drift.change(2.0, 60.0), None);
}

#[test]
fn a_gap_in_the_fixes_breaks_the_track() {
    let times = (0..100).chain(130..200).map(|i| f64::from(i) * 0.1);
    let drift = GnssDrift::new(&fixes(times, wander, true_velocity));
    assert!(drift.change(1.0, 9.0).is_some());
    assert!(drift.change(14.0, 19.0).is_some());
    assert_eq!(drift.change(5.0, 15.0), None, "across 3 s without a fix");
    assert!(GnssDrift::new(&[]).is_empty());
}

#[test]
fn velocities_read_wrong_miss_the_positions_by_far_more_than_the_gnss_wanders() {
    let times = || (0..3000).map(|i| f64::from(i) * 0.1);
    let expected = expected_window_miss(1.5, 10.0);
    let right = GnssDrift::new(&fixes(times(), wander, true_velocity))
        .window_miss()
        .expect("windows");
    assert!(right < expected, "{right:.2} m against {expected:.2} m");
    // North and east swapped, as a reader mixing up NED and ENU would.
    let swapped = GnssDrift::new(&fixes(times(), wander, |_| Vector2::new(2.0, 10.0)))
        .window_miss()
        .expect("windows");
    assert!(
        swapped > 5.0 * expected,
        "{swapped:.2} m against {expected:.2} m"
    );
}
