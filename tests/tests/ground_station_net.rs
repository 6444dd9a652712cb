//! The ground station's network thread against a real edge node on loopback:
//! poses arrive decoded, the edge's liveliness shows, a payload that does not
//! decode is reported (not dropped), a correction reaches the edge, and the
//! session is recorded to an MCAP file that replays the same events.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use towernav_edge::node::{EdgeNode, open_session};
use towernav_ground_station::events::NetEvent;
use towernav_ground_station::net::{self, NetCommand, NetLink};
use towernav_ground_station::recording;
use towernav_protocol::session::Endpoints;
use towernav_protocol::{
    IdCorrection, Keys, LandmarkRecord, NodeId, PoseEstimate, PoseMethod, TrackReport,
};

fn pose(uav: &NodeId, seq: u64) -> PoseEstimate {
    PoseEstimate {
        uav: uav.clone(),
        time_s: seq as f64 / 30.0,
        seq,
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
        method: PoseMethod::PaperLbl,
        towers_used: vec!["A1".into()],
        coast_s: 0.0,
    }
}

/// The next event `want` accepts, skipping others, within `timeout`.
fn wait_for<T>(
    events: &Receiver<NetEvent>,
    timeout: Duration,
    mut want: impl FnMut(NetEvent) -> Option<T>,
) -> anyhow::Result<T> {
    let end = Instant::now() + timeout;
    loop {
        let left = end.saturating_duration_since(Instant::now());
        match events.recv_timeout(left) {
            Ok(e) => {
                if let Some(t) = want(e) {
                    return Ok(t);
                }
            }
            Err(RecvTimeoutError::Timeout) => anyhow::bail!("timed out"),
            Err(RecvTimeoutError::Disconnected) => anyhow::bail!("the network thread stopped"),
        }
    }
}

fn command(link: &NetLink, command: NetCommand) -> anyhow::Result<()> {
    link.commands
        .send(command)
        .map_err(|_| anyhow::anyhow!("network thread gone"))
}

/// Waits until the ground station sees `uav`'s liveliness token come or go.
fn wait_alive(link: &NetLink, uav: &NodeId, alive: bool) -> anyhow::Result<()> {
    wait_for(&link.events, Duration::from_secs(10), |e| match e {
        NetEvent::Alive { uav: u, alive: a } if u == *uav && a == alive => Some(()),
        _ => None,
    })
}

/// Publishes poses until the ground station's subscription has reached the
/// edge; the first pose that arrives.
async fn first_pose(link: &NetLink, edge: &EdgeNode, uav: &NodeId) -> anyhow::Result<PoseEstimate> {
    for seq in 0..100 {
        edge.publish_pose(&pose(uav, seq)).await?;
        if let Ok(p) = wait_for(&link.events, Duration::from_millis(100), |e| match e {
            NetEvent::Pose(p) => Some(p),
            _ => None,
        }) {
            return Ok(p);
        }
    }
    anyhow::bail!("no pose reached the ground station")
}

/// Puts a payload of an unknown schema on `key` until the ground station
/// rejects it: the tracks subscription's declaration travels apart from the
/// poses' (a single put raced it under load). The rejection's reason.
async fn first_rejection(
    link: &NetLink,
    session: &zenoh::Session,
    key: &str,
) -> anyhow::Result<String> {
    for _ in 0..50 {
        session
            .put(
                key,
                br#"{"schema": 9, "kind": "tracks", "body": {}}"#.to_vec(),
            )
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        if let Ok(e) = wait_for(&link.events, Duration::from_millis(100), |e| match e {
            NetEvent::Rejected { key: k, error } if k == key => Some(error),
            _ => None,
        }) {
            return Ok(e);
        }
    }
    anyhow::bail!("no rejection reached the ground station")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poses_liveliness_rejections_corrections_and_a_recording() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let fleet = NodeId::new("gsnet")?;
    let uav = NodeId::new("uav3")?;
    let session = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
        ..Default::default()
    })
    .await?;
    let dir = tempfile::tempdir()?;
    let mcap = dir.path().join("session.mcap");
    let link = net::spawn(
        Endpoints {
            listen: vec![],
            connect: vec![endpoint],
            ..Default::default()
        },
        fleet.clone(),
        None,
        || {},
    );
    let towers = vec![LandmarkRecord::new(
        "B1",
        towernav_protocol::TowerType::B,
        30.52,
        114.36,
        25.0,
        35.0,
    )];
    command(
        &link,
        NetCommand::StartRecording {
            path: mcap.clone(),
            landmarks: towers.clone(),
        },
    )?;
    wait_for(&link.events, Duration::from_secs(5), |e| match e {
        NetEvent::Recording(Some(path)) if *path == mcap => Some(()),
        _ => None,
    })?;
    // The edge appears once the recording runs, so its arrival is in the file.
    let edge = EdgeNode::new(session.clone(), fleet.clone(), uav.clone()).await?;

    // The edge's liveliness token is seen.
    wait_alive(&link, &uav, true)?;
    let got = first_pose(&link, &edge, &uav).await?;
    assert_eq!(got.uav, uav);
    let key = Keys::new(fleet.clone()).uav_key::<TrackReport>(&uav);
    let error = first_rejection(&link, &session, &key).await?;
    assert!(error.contains("schema version 9"), "{error}");

    // A correction from the ground station reaches the edge.
    let correction = IdCorrection {
        uav: uav.clone(),
        request_id: 42,
        track_id: 7,
        tower_id: Some("B1".into()),
        issued_by: "test".into(),
        release: false,
        session: None,
    };
    command(&link, NetCommand::Correct(correction.clone()))?;
    let received = tokio::time::timeout(Duration::from_secs(5), edge.next_correction()).await?;
    assert_eq!(received, correction);

    // The edge goes away: its token is deleted.
    drop(edge);
    wait_alive(&link, &uav, false)?;

    command(&link, NetCommand::StopRecording)?;
    let notice = wait_for(&link.events, Duration::from_secs(5), |e| match e {
        NetEvent::Notice(n) if n.starts_with("recorded") => Some(n),
        _ => None,
    })?;
    let samples = recording::read(&mcap)?.samples;
    assert_eq!(recording::landmarks(&mcap, &samples)?, Some(towers));
    assert!(
        notice.contains(&format!("recorded {} messages", samples.len())),
        "{notice}"
    );
    let events: Vec<NetEvent> = samples.iter().filter_map(|s| s.event()).collect();
    assert!(matches!(
        events.first(),
        Some(NetEvent::Alive { alive: true, .. })
    ));
    assert!(
        events
            .iter()
            .any(|e| matches!(e, NetEvent::Pose(p) if p.seq == got.seq))
    );
    assert!(
        events
            .iter()
            .any(|e| matches!(e, NetEvent::Rejected { .. }))
    );
    assert!(matches!(
        events.last(),
        Some(NetEvent::Alive { alive: false, .. })
    ));
    // The correction is in the recording too, on its own key.
    let correction_key = Keys::new(fleet).uav_key::<IdCorrection>(&uav);
    assert!(samples.iter().any(|s| s.key == correction_key));
    Ok(())
}
