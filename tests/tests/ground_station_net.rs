//! The ground station's network thread against a real Zenoh publisher on loopback:
//! poses arrive decoded, and a payload that does not decode is reported, not dropped.

use std::sync::mpsc::RecvTimeoutError;
use std::time::Duration;

use towernav_edge::shell::node::open_session;
use towernav_ground_station::fleet::NetEvent;
use towernav_ground_station::net;
use towernav_protocol::session::Endpoints;
use towernav_protocol::{Keys, NodeId, PoseEstimate, PoseMethod, Topic, encode};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poses_and_rejections_reach_the_ui_channel() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let fleet = NodeId::new("gsnet")?;
    let uav = NodeId::new("uav3")?;
    let edge = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
    })
    .await?;
    let events = net::spawn(
        Endpoints {
            listen: vec![],
            connect: vec![endpoint],
        },
        fleet.clone(),
        None,
        || {},
    );

    let key = Keys::new(fleet).uav(&uav, Topic::Pose);
    let pose = PoseEstimate {
        uav: uav.clone(),
        time_s: 1.0,
        seq: 30,
        east_m: 10.0,
        north_m: 20.0,
        up_m: 30.0,
        lat_deg: 30.5,
        lon_deg: 114.3,
        alt_m: 55.0,
        yaw_rad: 0.0,
        covariance: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
        ],
        method: PoseMethod::SeedLbl,
        towers_used: vec!["A1".into()],
    };
    // Publish until the ground station's subscription has reached us (it connects asynchronously).
    let mut got_pose = None;
    for _ in 0..100 {
        edge.put(key.clone(), encode(&pose)?)
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        match events.recv_timeout(Duration::from_millis(100)) {
            Ok(NetEvent::Pose(p)) => {
                got_pose = Some(p);
                break;
            }
            Ok(other) => anyhow::bail!("unexpected event {other:?}"),
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => anyhow::bail!("the network thread stopped"),
        }
    }
    assert_eq!(got_pose.as_ref(), Some(&pose));

    edge.put(
        key.clone(),
        br#"{"schema": 9, "kind": "pose", "body": {}}"#.to_vec(),
    )
    .await
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    loop {
        match events.recv_timeout(Duration::from_secs(5))? {
            NetEvent::Pose(_) => continue, // stragglers from the loop above
            NetEvent::Rejected { key: k, error } => {
                assert_eq!(k, key);
                assert!(error.contains("schema version 9"), "{error}");
                break;
            }
            other => anyhow::bail!("unexpected event {other:?}"),
        }
    }
    Ok(())
}
