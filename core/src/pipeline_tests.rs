//! The pipeline's answers to operator corrections: what it refuses, and why.

use nalgebra::Point3;
use towernav_geometry::{Attitude, PinholeCamera};
use towernav_protocol::{DetectionFrame, TowerType};

use crate::fixtures::{det, map, tower};
use crate::landmarks::MapTower;
use crate::pipeline::{ECHO_MAX_CHARS, Pipeline, PipelineConfig};

/// A pipeline over an A tower and a B tower that has tracked one type-A box
/// for ten frames; returns it and the track's id.
fn tracking_an_a_box() -> (Pipeline, u64) {
    let typed = |id: &str, x: f64, t: TowerType| MapTower {
        tower_type: t,
        ..tower(id, x, 0.0, 40.0)
    };
    let mut pipeline = Pipeline::new(
        PipelineConfig::new(PinholeCamera::default_hd(), Point3::new(0.0, 0.0, 30.0)),
        map(vec![
            typed("A1", 100.0, TowerType::A),
            typed("B1", 300.0, TowerType::B),
        ]),
    );
    let mut track = None;
    for seq in 0..10 {
        let out = pipeline.process(&DetectionFrame {
            seq,
            time_s: seq as f64 / 30.0,
            imu_attitude: Attitude::default(),
            detections: vec![det(600.0, TowerType::A, 0.9)],
        });
        track = out.tracks.first().map(|t| t.track_id).or(track);
    }
    (pipeline, track.expect("a confirmed track"))
}

#[test]
fn a_correction_to_a_tower_of_another_type_is_refused_with_the_reason() {
    let (mut pipeline, track) = tracking_an_a_box();
    let refused = pipeline
        .pin(track, Some("B1"))
        .expect_err("an A track, a B tower");
    assert!(
        refused.contains("type A") && refused.contains("type B"),
        "{refused}"
    );
    pipeline.pin(track, Some("A1")).expect("same type");
    pipeline
        .pin(track, None)
        .expect("unbinding is always allowed");
}

#[test]
fn a_refusal_does_not_echo_a_huge_id() {
    let (mut pipeline, track) = tracking_an_a_box();
    let huge = "X".repeat(64 * 1024);
    let refused = pipeline.pin(track, Some(&huge)).expect_err("unknown");
    assert!(
        refused.len() < ECHO_MAX_CHARS + 100,
        "{} chars",
        refused.len()
    );
    assert!(refused.contains("65536 bytes"), "{refused}");
}
