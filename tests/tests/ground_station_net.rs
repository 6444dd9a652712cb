//! The ground station's network thread against a real edge node on loopback:
//! poses arrive decoded, the edge's liveliness shows, a payload that does not
//! decode is reported (not dropped), a correction reaches the edge, and the
//! session is recorded to an MCAP file that replays the same events.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use towernav_edge::node::{EdgeNode, open_session};
use towernav_ground_station::events::NetEvent;
use towernav_ground_station::net::{self, NetCommand};
use towernav_ground_station::recording;
use towernav_protocol::session::Endpoints;
use towernav_protocol::{IdCorrection, Keys, NodeId, PoseEstimate, PoseMethod, TrackReport};

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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poses_liveliness_rejections_corrections_and_a_recording() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let fleet = NodeId::new("gsnet")?;
    let uav = NodeId::new("uav3")?;
    let session = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
    })
    .await?;
    let dir = tempfile::tempdir()?;
    let mcap = dir.path().join("session.mcap");
    let link = net::spawn(
        Endpoints {
            listen: vec![],
            connect: vec![endpoint],
        },
        fleet.clone(),
        None,
        || {},
    );
    link.commands
        .send(NetCommand::StartRecording(mcap.clone()))
        .map_err(|_| anyhow::anyhow!("network thread gone"))?;
    wait_for(&link.events, Duration::from_secs(5), |e| match e {
        NetEvent::Notice(n) if n.starts_with("recording to") => Some(()),
        _ => None,
    })?;
    // The edge appears once the recording runs, so its arrival is in the file.
    let edge = EdgeNode::new(session.clone(), fleet.clone(), uav.clone()).await?;

    // The edge's liveliness token is seen.
    wait_for(&link.events, Duration::from_secs(10), |e| match e {
        NetEvent::Alive {
            uav: u,
            alive: true,
        } if u == uav => Some(()),
        _ => None,
    })?;

    // Publish until the ground station's subscription has reached us.
    let mut got = None;
    for seq in 0..100 {
        edge.publish_pose(&pose(&uav, seq)).await?;
        if let Ok(p) = wait_for(&link.events, Duration::from_millis(100), |e| match e {
            NetEvent::Pose(p) => Some(p),
            _ => None,
        }) {
            got = Some(p);
            break;
        }
    }
    let got = got.ok_or_else(|| anyhow::anyhow!("no pose reached the ground station"))?;
    assert_eq!(got.uav, uav);

    let key = Keys::new(fleet.clone()).uav_key::<TrackReport>(&uav);
    // Put until the tracks subscription has reached us too: its declaration
    // travels apart from the poses' (a single put raced it under load).
    let mut error = None;
    for _ in 0..50 {
        session
            .put(
                key.clone(),
                br#"{"schema": 9, "kind": "tracks", "body": {}}"#.to_vec(),
            )
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        if let Ok(e) = wait_for(&link.events, Duration::from_millis(100), |e| match e {
            NetEvent::Rejected { key: k, error } if k == key => Some(error),
            _ => None,
        }) {
            error = Some(e);
            break;
        }
    }
    let error = error.ok_or_else(|| anyhow::anyhow!("no rejection reached the ground station"))?;
    assert!(error.contains("schema version 9"), "{error}");

    // A correction from the ground station reaches the edge.
    let correction = IdCorrection {
        uav: uav.clone(),
        request_id: 42,
        track_id: 7,
        tower_id: Some("B1".into()),
        issued_by: "test".into(),
    };
    link.commands
        .send(NetCommand::Correct(correction.clone()))
        .map_err(|_| anyhow::anyhow!("network thread gone"))?;
    let received = tokio::time::timeout(Duration::from_secs(5), edge.next_correction()).await?;
    assert_eq!(received, correction);

    // The edge goes away: its token is deleted.
    drop(edge);
    wait_for(&link.events, Duration::from_secs(10), |e| match e {
        NetEvent::Alive {
            uav: u,
            alive: false,
        } if u == uav => Some(()),
        _ => None,
    })?;

    link.commands
        .send(NetCommand::StopRecording)
        .map_err(|_| anyhow::anyhow!("network thread gone"))?;
    let notice = wait_for(&link.events, Duration::from_secs(5), |e| match e {
        NetEvent::Notice(n) if n.starts_with("recorded") => Some(n),
        _ => None,
    })?;
    let samples = recording::read(&mcap)?;
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
