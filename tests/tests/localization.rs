//! Localization targets on the paper's field with the realistic oracle and
//! quadrotor attitude: ours + EKF at most 2 m RMS horizontally, and at
//! most 4 m with a fifth of the observations made false or bound to the wrong
//! tower. The paper's method runs on the same frames for comparison.

use towernav_eval::cmd::loc_eval::evaluate;
use towernav_sim::{Scenario, World};

#[test]
fn ours_meets_the_targets_where_the_paper_does_not() {
    let scenario = Scenario::preset(World::paper_field(), "paper-path-1", 1).expect("preset");
    let clean = evaluate(&scenario, 0.0, 1).summary();
    assert!(
        clean.filtered.count > 4000,
        "{} estimates",
        clean.filtered.count
    );
    assert!(
        clean.filtered.rms <= 2.0,
        "ours + EKF RMS {:.2} m",
        clean.filtered.rms
    );
    assert!(
        clean.paper.rms > 2.0 * clean.filtered.rms,
        "seed {:.2} m",
        clean.paper.rms
    );
    // Consistent covariance: mean 2-dof NEES near 2.
    assert!(
        (0.5..=4.0).contains(&clean.filtered_mean_nees_h),
        "NEES {:.2}",
        clean.filtered_mean_nees_h
    );

    let dirty = evaluate(&scenario, 0.2, 1);
    assert!(
        dirty.corrupted as f64 > 0.15 * dirty.observations as f64,
        "{} of {} corrupted",
        dirty.corrupted,
        dirty.observations
    );
    let dirty = dirty.summary();
    assert!(
        dirty.filtered.rms <= 4.0,
        "with outliers {:.2} m",
        dirty.filtered.rms
    );
}
