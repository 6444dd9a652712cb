//! A secured fleet over loopback: mutual TLS with the fleet's CA and Zenoh's
//! access rules from its roster. A ground station, an edge (the daemon's own
//! Zenoh node) and a rogue: first with no certificate, then with another
//! edge's. Every attack below was once accepted; each must now be refused,
//! while the ground station's own traffic still gets through.

use std::path::{Path, PathBuf};
use std::time::Duration;

use towernav_edge::node::{EdgeNode, open_session, wait_for_peer};
use towernav_fleet::{Authority, node};
use towernav_protocol::security::{Credentials, Role};
use towernav_protocol::session::Endpoints;
use towernav_protocol::{
    IdCorrection, Keys, LandmarkChange, LandmarkChangeOp, NodeId, Topic, encode,
};
use zenoh::Session;

const FLEET: &str = "secure";
const QUIET: Duration = Duration::from_millis(1500);

struct Fleet {
    _dir: tempfile::TempDir,
    gs: PathBuf,
    edge: PathBuf,
    other_edge: PathBuf,
    ca_dir: PathBuf,
}

fn issue() -> anyhow::Result<Fleet> {
    let dir = tempfile::tempdir()?;
    let ca_dir = dir.path().join("fleet");
    let mut ca = Authority::init(&ca_dir, FLEET, 30)?;
    let host = ["127.0.0.1".to_owned()];
    let gs = ca.issue(node("gs-1", Role::GroundStation, None, &host)?, 5)?;
    let edge = ca.issue(node("edge-7", Role::Edge, Some("uav-7"), &host)?, 5)?;
    let other_edge = ca.issue(node("edge-8", Role::Edge, Some("uav-8"), &host)?, 5)?;
    Ok(Fleet {
        _dir: dir,
        gs,
        edge,
        other_edge,
        ca_dir,
    })
}

fn tls() -> String {
    format!("tls/127.0.0.1:{}", towernav_tests::loopback_port())
}

async fn open(
    creds: Option<(&Path, &str)>,
    listen: &[String],
    connect: &[String],
) -> anyhow::Result<Session> {
    let security = match creds {
        Some((dir, name)) => Some(Credentials::load(dir, name)?),
        None => None,
    };
    Ok(open_session(&Endpoints {
        listen: listen.to_vec(),
        connect: connect.to_vec(),
        security,
    })
    .await?)
}

async fn peers(session: &Session) -> usize {
    session.info().peers_zid().await.count()
}

fn correction(uav: &NodeId, request_id: u64, by: &str) -> IdCorrection {
    IdCorrection {
        uav: uav.clone(),
        request_id,
        track_id: 3,
        tower_id: Some("B4".into()),
        issued_by: by.into(),
        release: false,
        session: None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_without_the_fleets_certificate_is_refused_at_connect() -> anyhow::Result<()> {
    let fleet = issue()?;
    let endpoint = tls();
    let gs = open(
        Some((&fleet.gs, "gs-1")),
        std::slice::from_ref(&endpoint),
        &[],
    )
    .await?;
    // No certificate at all: the TLS handshake fails.
    let stranger = zenoh::open(towernav_protocol::session::session_config(&Endpoints {
        listen: vec![],
        connect: vec![endpoint.clone()],
        security: None,
    })?)
    .await
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    // A certificate from another CA, with a name on the roster.
    let impostor_ca = fleet.ca_dir.with_file_name("impostor");
    let mut impostor = Authority::init(&impostor_ca, FLEET, 30)?;
    let forged = impostor.issue(node("gs-1", Role::GroundStation, None, &[])?, 5)?;
    let impostor = open(
        Some((&forged, "gs-1")),
        &[],
        std::slice::from_ref(&endpoint),
    )
    .await?;
    tokio::time::sleep(QUIET).await;
    assert_eq!(peers(&gs).await, 0, "the ground station accepted a link");
    assert_eq!(peers(&stranger).await, 0);
    assert_eq!(peers(&impostor).await, 0);
    // Nor can they read the landmark database, which answers every query.
    let keys = Keys::new(NodeId::new(FLEET)?);
    let queryable = gs
        .declare_queryable(keys.landmark_query())
        .await
        .map_err(anyhow_z)?;
    let answering = tokio::spawn(async move {
        while let Ok(query) = queryable.recv_async().await {
            let _ = query.reply(query.key_expr().clone(), "landmarks").await;
        }
    });
    let ask = |session: &Session| {
        let (session, key) = (session.clone(), keys.landmark_query());
        async move {
            let replies = session
                .get(key)
                .timeout(Duration::from_millis(1000))
                .await
                .map_err(anyhow_z)?;
            anyhow::Ok(replies.recv_async().await.is_ok())
        }
    };
    for rogue in [&stranger, &impostor] {
        assert!(!ask(rogue).await?, "a rogue got a reply");
    }
    // The fleet's own edge does connect: the refusals above are not a broken setup.
    let edge = open(
        Some((&fleet.edge, "edge-7")),
        &[],
        std::slice::from_ref(&endpoint),
    )
    .await?;
    wait_for_peer(&edge, Duration::from_secs(10)).await?;
    assert_eq!(peers(&gs).await, 1);
    assert!(ask(&edge).await?, "the fleet's edge got no landmarks");
    answering.abort();
    Ok(())
}

fn anyhow_z(e: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edges_certificate_cannot_correct_move_towers_or_speak_for_another_uav()
-> anyhow::Result<()> {
    let fleet = issue()?;
    let (gs_at, edge_at) = (tls(), tls());
    let keys = Keys::new(NodeId::new(FLEET)?);
    let uav = NodeId::new("uav-7")?;
    let gs = open(Some((&fleet.gs, "gs-1")), std::slice::from_ref(&gs_at), &[]).await?;
    let edge_session = open(
        Some((&fleet.edge, "edge-7")),
        std::slice::from_ref(&edge_at),
        std::slice::from_ref(&gs_at),
    )
    .await?;
    let edge = EdgeNode::new(edge_session.clone(), NodeId::new(FLEET)?, uav.clone()).await?;
    let changes = edge_session
        .declare_subscriber(keys.landmark_changes())
        .await
        .map_err(anyhow_z)?;
    let poses = gs
        .declare_subscriber(keys.all_uavs(Topic::Pose))
        .await
        .map_err(anyhow_z)?;
    // A rogue holding another edge's certificate, linked to both.
    let rogue = open(
        Some((&fleet.other_edge, "edge-8")),
        &[],
        &[gs_at.clone(), edge_at.clone()],
    )
    .await?;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while peers(&rogue).await < 2 || peers(&edge_session).await < 2 {
        anyhow::ensure!(tokio::time::Instant::now() < deadline, "links not up");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    tokio::time::sleep(Duration::from_millis(500)).await;

    // 1. Corrections: the rogue's pin never reaches the edge; the ground station's does.
    let put = |s: &Session, key: String, bytes: Vec<u8>| {
        let s = s.clone();
        async move { s.put(key, bytes).await.map_err(anyhow_z) }
    };
    let correction_key = keys.uav(&uav, Topic::Correction);
    put(
        &rogue,
        correction_key.clone(),
        encode(&correction(&uav, 1, "rogue"))?,
    )
    .await?;
    let got = tokio::time::timeout(QUIET, edge.next_correction()).await;
    assert!(got.is_err(), "the edge took a rogue's correction: {got:?}");
    put(
        &gs,
        correction_key,
        encode(&correction(&uav, 2, "operator"))?,
    )
    .await?;
    let got = tokio::time::timeout(Duration::from_secs(5), edge.next_correction()).await?;
    assert_eq!((got.request_id, got.issued_by.as_str()), (2, "operator"));

    // 2. Landmark changes: the rogue cannot remove a tower.
    let change = |revision| LandmarkChange {
        revision,
        change: LandmarkChangeOp::Remove { id: "A1".into() },
    };
    put(&rogue, keys.landmark_changes(), encode(&change(11))?).await?;
    let got = tokio::time::timeout(QUIET, changes.recv_async()).await;
    assert!(got.is_err(), "the edge heard a rogue's landmark change");
    put(&gs, keys.landmark_changes(), encode(&change(12))?).await?;
    let sample = tokio::time::timeout(Duration::from_secs(5), changes.recv_async())
        .await?
        .map_err(anyhow_z)?;
    let heard: LandmarkChange = towernav_protocol::decode(&sample.payload().to_bytes())?;
    assert_eq!(heard.revision, 12);

    // 3. Poses: the rogue cannot speak for uav-7, nor for a UAV with no edge.
    put(&rogue, keys.uav(&uav, Topic::Pose), b"fake uav-7".to_vec()).await?;
    put(
        &rogue,
        keys.uav(&NodeId::new("uav-9")?, Topic::Pose),
        b"fake uav-9".to_vec(),
    )
    .await?;
    // Its own keys it may use: the rules are not simply "edges are mute".
    put(
        &rogue,
        keys.uav(&NodeId::new("uav-8")?, Topic::Pose),
        b"own uav-8".to_vec(),
    )
    .await?;
    let mut heard = Vec::new();
    let until = tokio::time::Instant::now() + QUIET;
    while let Ok(Ok(sample)) = tokio::time::timeout_at(until, poses.recv_async()).await {
        heard.push(String::from_utf8_lossy(&sample.payload().to_bytes()).into_owned());
    }
    assert_eq!(heard, vec!["own uav-8".to_owned()]);
    // Nor hold another UAV's liveliness token.
    let _token = rogue
        .liveliness()
        .declare_token(keys.alive(&NodeId::new("uav-9")?))
        .await
        .map_err(anyhow_z)?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let alive = gs
        .liveliness()
        .get(keys.all_alive())
        .timeout(Duration::from_secs(1))
        .await
        .map_err(anyhow_z)?;
    let mut tokens = Vec::new();
    while let Ok(reply) = alive.recv_async().await {
        if let Ok(sample) = reply.result() {
            tokens.push(sample.key_expr().to_string());
        }
    }
    tokens.sort();
    assert_eq!(tokens, vec![keys.alive(&uav)], "{tokens:?}");
    Ok(())
}

/// An independent client, eclipse-zenoh for Python configured as
/// protocol/README.md shows, through a secured router: with an edge's
/// certificate its pose gets through and its correction does not; with a
/// ground station's the correction gets through; without a certificate it
/// gets no link.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_eclipse_zenoh_client_gets_what_its_certificate_allows() -> anyhow::Result<()> {
    let Some(pythonpath) = towernav_tests::python_module("zenoh") else {
        eprintln!("skipped: no eclipse-zenoh (cargo xtask test installs it)");
        return Ok(());
    };
    let dir = tempfile::tempdir()?;
    let ca_dir = dir.path().join("fleet");
    let mut ca = Authority::init(&ca_dir, FLEET, 30)?;
    let host = ["127.0.0.1".to_owned()];
    let router_dir = ca.issue(node("router-1", Role::Router, None, &host)?, 5)?;
    let gs = ca.issue(node("gs-1", Role::GroundStation, None, &[])?, 5)?;
    let edge = ca.issue(node("edge-7", Role::Edge, Some("uav-7"), &[])?, 5)?;
    let endpoint = tls();
    let router = zenoh::open(towernav_protocol::session::router_config(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
        security: Some(Credentials::load(&router_dir, "router-1")?),
    })?)
    .await
    .map_err(anyhow_z)?;
    let keys = Keys::new(NodeId::new(FLEET)?);
    let heard = router
        .declare_subscriber(keys.all_uavs_any_topic())
        .await
        .map_err(anyhow_z)?;
    let uav = NodeId::new("uav-7")?;
    let (pose, correction) = (
        keys.uav(&uav, Topic::Pose),
        keys.uav(&uav, Topic::Correction),
    );
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("python/zenoh_put.py");
    let python = move |credentials: Option<&Path>, puts: Vec<String>| {
        let mut command = std::process::Command::new("python3");
        command
            .arg(&script)
            .arg(&endpoint)
            .env("PYTHONPATH", &pythonpath);
        if let Some(dir) = credentials {
            command.arg("--credentials").arg(dir);
        }
        let out = command.args(puts).output().expect("python3 runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let said = tokio::task::spawn_blocking(move || {
        [
            python(
                Some(&edge),
                vec![
                    format!("{pose}=edge pose"),
                    format!("{correction}=edge correction"),
                ],
            ),
            python(Some(&gs), vec![format!("{correction}=operator correction")]),
            python(None, vec![format!("{pose}=stranger pose")]),
        ]
    })
    .await?;
    assert!(said[0].starts_with("linked"), "{}", said[0]);
    assert!(said[1].starts_with("linked"), "{}", said[1]);
    assert!(said[2].starts_with("no link"), "{}", said[2]);
    let mut got = Vec::new();
    while let Ok(Ok(sample)) = tokio::time::timeout(QUIET, heard.recv_async()).await {
        got.push(String::from_utf8_lossy(&sample.payload().to_bytes()).into_owned());
    }
    got.sort();
    assert_eq!(got, vec!["edge pose", "operator correction"]);
    Ok(())
}
