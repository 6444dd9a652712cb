//! An edge flies the simulated flight and publishes over Zenoh on loopback; a plain
//! Zenoh subscriber in the same test receives the poses, decodes them and checks them
//! against the simulator's truth.

use std::time::Duration;

use towernav_edge::LandmarkMap;
use towernav_edge::shell::collector::wait_for_peer;
use towernav_edge::shell::node::{EdgeNode, open_session};
use towernav_edge::shell::sim_flight::{SimFlightOptions, fly};
use towernav_protocol::session::Endpoints;
use towernav_protocol::{Keys, NodeId, PoseEstimate, Topic, decode};
use towernav_sim::Scenario;

/// Stated bound for the seed method on the first 30 s of the seed flight.
const MAX_RMS_M: f64 = 5.0;
const MAX_ERROR_M: f64 = 20.0;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poses_arrive_decode_and_match_the_truth() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let fleet = NodeId::new("itest")?;
    let uav = NodeId::new("uav7")?;

    let edge_session = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
    })
    .await?;
    let node = EdgeNode::new(edge_session, fleet.clone(), uav.clone()).await?;

    let listener = open_session(&Endpoints {
        listen: vec![],
        connect: vec![endpoint],
    })
    .await?;
    let subscriber = listener
        .declare_subscriber(Keys::new(fleet).all_uavs(Topic::Pose))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    wait_for_peer(&listener, Duration::from_secs(10)).await?;

    let scenario = Scenario::seed(11);
    let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
    let options = SimFlightOptions {
        max_frames: Some(900),
        ..SimFlightOptions::default()
    };
    let record = fly(&node, &scenario, map, options, None, None, |_| {}).await?;
    assert!(
        record.poses_published > 700,
        "only {} fixes in 900 frames",
        record.poses_published
    );

    let mut errors = Vec::new();
    while errors.len() < record.poses_published as usize {
        let sample = tokio::time::timeout(Duration::from_secs(5), subscriber.recv_async())
            .await
            .map_err(|_| {
                anyhow::anyhow!(
                    "only {} of {} poses arrived",
                    errors.len(),
                    record.poses_published
                )
            })?
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let key = Keys::parse_uav(sample.key_expr().as_str())?;
        assert_eq!(key.uav, uav);
        let pose: PoseEstimate = decode(&sample.payload().to_bytes())?;
        let truth = scenario.truth(pose.seq).pose.position_in_world;
        errors.push(((pose.east_m - truth.x).powi(2) + (pose.north_m - truth.y).powi(2)).sqrt());
        assert!(!pose.towers_used.is_empty());
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let max = errors.iter().copied().fold(0.0, f64::max);
    assert!(rms < MAX_RMS_M, "horizontal RMS {rms:.2} m");
    assert!(max < MAX_ERROR_M, "horizontal max {max:.2} m");
    Ok(())
}
