//! The four attacks an outside client once got through on a secured fleet,
//! replayed over loopback with real certificates from `towernav-fleet`:
//! an edge posing as another UAV (and answering its corrections), a revoked
//! or superseded certificate coming back, a plain link learnt by gossip, and
//! an edge reading another UAV. Each runs peer to peer, and the first and
//! last also through a fleet router, as a deployed fleet runs.

use std::path::{Path, PathBuf};
use std::time::Duration;

use towernav_edge::node::{EdgeNode, open_session};
use towernav_fleet::{Authority, node};
use towernav_ground_station::corrections::{Before, CorrectionState, Corrections};
use towernav_ground_station::events::{NetEvent, decode_sample};
use towernav_ground_station::test_support::pose;
use towernav_protocol::security::{Credentials, Role};
use towernav_protocol::session::{Endpoints, client_config, router_config};
use towernav_protocol::{
    CorrectionAck, IdCorrection, Keys, LandmarkChange, LandmarkChangeOp, NodeId, Topic, encode,
};
use zenoh::Session;

const FLEET: &str = "secure";
const QUIET: Duration = Duration::from_millis(1500);

fn tls() -> String {
    format!("tls/127.0.0.1:{}", towernav_tests::loopback_port())
}

fn z(e: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

fn keys() -> Keys {
    Keys::new(NodeId::new(FLEET).expect("valid"))
}

fn id(s: &str) -> NodeId {
    NodeId::new(s).expect("valid")
}

struct Fleet {
    dir: tempfile::TempDir,
    ca: Authority,
}

impl Fleet {
    fn new() -> anyhow::Result<Self> {
        let dir = tempfile::tempdir()?;
        let mut ca = Authority::init(&dir.path().join("fleet"), FLEET, 30)?;
        let host = ["127.0.0.1".to_owned()];
        ca.issue(node("gs-1", Role::GroundStation, None, &host)?, 5)?;
        ca.issue(node("router-1", Role::Router, None, &host)?, 5)?;
        for (name, uav) in [("edge-7", "uav-7"), ("edge-8", "uav-8")] {
            ca.issue(node(name, Role::Edge, Some(uav), &host)?, 5)?;
        }
        Ok(Self { dir, ca })
    }

    fn folder(&self, name: &str) -> PathBuf {
        self.ca.node_dir(name)
    }

    /// A copy of `name`'s folder as it is now: what a thief takes.
    fn steal(&self, name: &str) -> anyhow::Result<PathBuf> {
        let to = self.dir.path().join(format!("stolen-{name}"));
        std::fs::create_dir_all(&to)?;
        for entry in std::fs::read_dir(self.folder(name))? {
            let entry = entry?;
            std::fs::copy(entry.path(), to.join(entry.file_name()))?;
        }
        Ok(to)
    }
}

/// How the nodes of a test reach each other.
#[derive(Clone, Copy, Debug)]
enum Topology {
    /// Every node a peer, linked straight to the ground station.
    Peers,
    /// Every node a client of one fleet router.
    Router,
}

struct Net {
    _router: Option<Session>,
    at: String,
    topology: Topology,
}

impl Net {
    /// The ground station, listening (peers) or behind the router.
    async fn start(fleet: &Fleet, topology: Topology) -> anyhow::Result<(Self, Session)> {
        let at = tls();
        let (router, gs) = match topology {
            Topology::Peers => {
                let gs = node_session(
                    &fleet.folder("gs-1"),
                    "gs-1",
                    std::slice::from_ref(&at),
                    &[],
                    topology,
                )
                .await?;
                (None, gs)
            }
            Topology::Router => {
                let router = zenoh::open(router_config(&Endpoints {
                    listen: vec![at.clone()],
                    connect: vec![],
                    security: Some(Credentials::load(&fleet.folder("router-1"), "router-1")?),
                })?)
                .await
                .map_err(z)?;
                let gs = node_session(
                    &fleet.folder("gs-1"),
                    "gs-1",
                    &[],
                    std::slice::from_ref(&at),
                    topology,
                )
                .await?;
                (Some(router), gs)
            }
        };
        Ok((
            Self {
                _router: router,
                at,
                topology,
            },
            gs,
        ))
    }

    async fn join(&self, dir: &Path, name: &str) -> anyhow::Result<Session> {
        node_session(
            dir,
            name,
            &[],
            std::slice::from_ref(&self.at),
            self.topology,
        )
        .await
    }
}

async fn node_session(
    dir: &Path,
    name: &str,
    listen: &[String],
    connect: &[String],
    topology: Topology,
) -> anyhow::Result<Session> {
    let endpoints = Endpoints {
        listen: listen.to_vec(),
        connect: connect.to_vec(),
        security: Some(Credentials::load(dir, name)?),
    };
    Ok(match topology {
        Topology::Peers => open_session(&endpoints).await?,
        Topology::Router => zenoh::open(client_config(&endpoints)?).await.map_err(z)?,
    })
}

/// Waits until `session` has a link (a peer or a router).
async fn linked(session: &Session) -> anyhow::Result<()> {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    loop {
        let info = session.info();
        if info.peers_zid().await.count() + info.routers_zid().await.count() > 0 {
            return Ok(());
        }
        anyhow::ensure!(tokio::time::Instant::now() < deadline, "no link came up");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Sends with `send` until `sub` hears something, then everything it hears
/// until it falls quiet. A subscription takes a moment to reach a publisher
/// (seconds through a router on a loaded machine), and a sample put before
/// it arrives is gone: a pose stream or a change the ground station repeats
/// survives that, a single put in a test does not.
async fn until_heard(
    sub: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    mut send: impl AsyncFnMut() -> anyhow::Result<()>,
) -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    loop {
        send().await?;
        let got = heard(sub, Duration::from_millis(300)).await;
        if !got.is_empty() {
            let mut all = got;
            all.extend(heard(sub, QUIET).await);
            return Ok(all);
        }
        anyhow::ensure!(
            tokio::time::Instant::now() < deadline,
            "nothing was heard in 20 s"
        );
    }
}

/// Everything `sub` hears within `within`, as (key, bytes).
async fn heard(
    sub: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    within: Duration,
) -> Vec<(String, Vec<u8>)> {
    let until = tokio::time::Instant::now() + within;
    let mut out = Vec::new();
    while let Ok(Ok(sample)) = tokio::time::timeout_at(until, sub.recv_async()).await {
        out.push((
            sample.key_expr().to_string(),
            sample.payload().to_bytes().to_vec(),
        ));
    }
    out
}

async fn posing_as_another_uav(topology: Topology) -> anyhow::Result<()> {
    let fleet = Fleet::new()?;
    let (net, gs) = Net::start(&fleet, topology).await?;
    let rogue = net.join(&fleet.folder("edge-8"), "edge-8").await?;
    linked(&rogue).await?;
    let everything = gs
        .declare_subscriber(keys().all_uavs_any_topic())
        .await
        .map_err(z)?;
    // Its own honest pose, until the ground station hears it: the route is up.
    let own_pose = keys().uav(&id("uav-8"), Topic::Pose);
    let honest = encode(&pose("uav-8", 60.0, 10.0, 1))?;
    until_heard(&everything, async || {
        rogue.put(&own_pose, honest.clone()).await.map_err(z)
    })
    .await?;

    // 1. A pose on its own key that names uav-7, 500 m off.
    let fake = pose("uav-7", 60.0045, 10.0, 1);
    rogue.put(&own_pose, encode(&fake)?).await.map_err(z)?;
    // 2. A refusal of a correction the ground station sent uav-7, on its own
    //    key, once naming uav-7 and once itself.
    let mut corrections = Corrections::starting_at(41);
    let sent = corrections.issue(
        &id("uav-7"),
        3,
        None,
        Some("B4".into()),
        Before::default(),
        "operator",
        0.0,
    );
    let own_ack = keys().uav(&id("uav-8"), Topic::CorrectionAck);
    for uav in ["uav-7", "uav-8"] {
        let forged = CorrectionAck {
            uav: id(uav),
            request_id: sent.request_id,
            accepted: false,
            reason: Some("forged".into()),
        };
        rogue.put(&own_ack, encode(&forged)?).await.map_err(z)?;
    }
    let samples = heard(&everything, QUIET).await;
    assert_eq!(samples.len(), 3, "the samples did not arrive: {samples:?}");
    let mut filed = Vec::new();
    for (key, bytes) in &samples {
        match decode_sample(key, bytes) {
            Some(NetEvent::Rejected { error, .. }) => {
                assert!(
                    error.contains("uav-7") && error.contains("uav-8"),
                    "{error}"
                );
            }
            Some(NetEvent::Ack(ack)) => {
                assert_eq!(ack.uav.as_str(), "uav-8");
                corrections.acknowledged(&ack);
                filed.push("ack");
            }
            other => panic!("{topology:?}: {key} was taken as {other:?}"),
        }
    }
    assert_eq!(filed, vec!["ack"], "{topology:?}");
    assert_eq!(
        corrections.sent[0].state,
        CorrectionState::Pending,
        "{topology:?}: another UAV's answer counted"
    );
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edge_cannot_pose_as_another_uav_or_answer_its_corrections() -> anyhow::Result<()> {
    posing_as_another_uav(Topology::Peers).await?;
    posing_as_another_uav(Topology::Router).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_revoked_or_superseded_certificate_never_comes_back() -> anyhow::Result<()> {
    let mut fleet = Fleet::new()?;
    let host = ["127.0.0.1".to_owned()];
    // edge-8's vehicle is stolen, revoked, and a replacement gets the name.
    let stolen = fleet.steal("edge-8")?;
    fleet.ca.revoke("edge-8")?;
    fleet
        .ca
        .issue(node("edge-8", Role::Edge, Some("uav-8"), &host)?, 5)?;
    // edge-7 is simply issued again; its old folder is kept somewhere.
    let superseded = fleet.steal("edge-7")?;
    fleet
        .ca
        .issue(node("edge-7", Role::Edge, Some("uav-7"), &host)?, 5)?;
    let (net, gs) = Net::start(&fleet, Topology::Peers).await?;
    let poses = gs
        .declare_subscriber(keys().all_uavs(Topic::Pose))
        .await
        .map_err(z)?;
    let mut nodes = Vec::new();
    for (dir, name, uav) in [
        (stolen, "edge-8", "uav-8"),
        (superseded, "edge-7", "uav-7"),
        (fleet.folder("edge-8"), "edge-8", "uav-8"),
    ] {
        let session = net.join(&dir, name).await?;
        linked(&session).await?;
        let what = format!("{} {uav}", dir.display());
        nodes.push((session, keys().uav(&id(uav), Topic::Pose), what));
    }
    // All three put until the ground station hears one, so the old ones'
    // silence means refusal, not a route still on its way.
    let got = until_heard(&poses, async || {
        for (session, key, what) in &nodes {
            session.put(key, what.clone()).await.map_err(z)?;
        }
        Ok(())
    })
    .await?;
    let replacement = &nodes[2].2;
    let strays: Vec<String> = got
        .into_iter()
        .map(|(_, b)| String::from_utf8_lossy(&b).into_owned())
        .filter(|g| g != replacement)
        .collect();
    assert!(
        strays.is_empty(),
        "only the replacement is heard: {strays:?}"
    );
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gossip_does_not_open_a_plain_link() -> anyhow::Result<()> {
    let fleet = Fleet::new()?;
    let (net, gs) = Net::start(&fleet, Topology::Peers).await?;
    // A node with edge-8's certificate that links to the ground station over
    // TLS and offers only a plain TCP listener for others to dial.
    let plain = towernav_tests::loopback_endpoint();
    let dir = fleet.folder("edge-8");
    let mut config = zenoh::Config::default();
    let path = |f: &str| format!("{:?}", dir.join(f).display().to_string());
    for (key, value) in [
        ("mode", "\"peer\"".to_owned()),
        ("scouting/multicast/enabled", "false".to_owned()),
        ("listen/endpoints", format!("[{plain:?}]")),
        ("connect/endpoints", format!("[{:?}]", net.at)),
        ("transport/link/tls/root_ca_certificate", path("ca.pem")),
        ("transport/link/tls/connect_certificate", path("node.pem")),
        ("transport/link/tls/connect_private_key", path("node.key")),
        ("transport/link/tls/enable_mtls", "true".to_owned()),
    ] {
        config
            .insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("{key}: {e}"))?;
    }
    let rogue = zenoh::open(config).await.map_err(z)?;
    linked(&rogue).await?;
    // The fleet's own edge, linked to the ground station only.
    let edge = net.join(&fleet.folder("edge-7"), "edge-7").await?;
    linked(&edge).await?;
    tokio::time::sleep(Duration::from_secs(3)).await;
    let rogue_zid = rogue.info().zid().await;
    let edge_peers: Vec<_> = edge.info().peers_zid().await.collect();
    assert!(
        !edge_peers.contains(&rogue_zid),
        "the edge dialled a gossiped plain TCP link: {edge_peers:?}"
    );
    assert!(edge_peers.contains(&gs.info().zid().await));
    Ok(())
}

async fn reading_another_uav(topology: Topology) -> anyhow::Result<()> {
    let fleet = Fleet::new()?;
    let (net, gs) = Net::start(&fleet, topology).await?;
    let edge_session = net.join(&fleet.folder("edge-7"), "edge-7").await?;
    linked(&edge_session).await?;
    let edge = EdgeNode::new(edge_session.clone(), NodeId::new(FLEET)?, id("uav-7")).await?;
    let rogue = net.join(&fleet.folder("edge-8"), "edge-8").await?;
    linked(&rogue).await?;
    let spy = rogue
        .declare_subscriber(format!("towernav/{FLEET}/uav/uav-7/**"))
        .await
        .map_err(z)?;
    let landmarks = rogue
        .declare_subscriber(keys().landmark_changes())
        .await
        .map_err(z)?;
    let poses = gs
        .declare_subscriber(keys().all_uavs(Topic::Pose))
        .await
        .map_err(z)?;
    // Declarations travel both ways before anything is sent: the ground
    // station sees the edge's token (on a loaded machine it takes seconds),
    // then a moment for its own subscriptions to reach the edge.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(15);
    loop {
        let alive = gs
            .liveliness()
            .get(keys().all_alive())
            .timeout(Duration::from_secs(1))
            .await
            .map_err(z)?;
        let mut seen = false;
        while let Ok(reply) = alive.recv_async().await {
            seen |= reply
                .result()
                .is_ok_and(|s| s.key_expr().as_str().ends_with("uav-7"));
        }
        if seen || tokio::time::Instant::now() > deadline {
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    tokio::time::sleep(Duration::from_millis(800)).await;

    let correction = IdCorrection {
        uav: id("uav-7"),
        request_id: 5,
        track_id: 3,
        tower_id: Some("B4".into()),
        issued_by: "operator".into(),
        release: false,
        session: None,
    };
    gs.put(
        keys().uav(&id("uav-7"), Topic::Correction),
        encode(&correction)?,
    )
    .await
    .map_err(z)?;
    let change = LandmarkChange {
        revision: 3,
        change: LandmarkChangeOp::Remove { id: "A1".into() },
    };

    // The legitimate paths work...
    let got = tokio::time::timeout(Duration::from_secs(5), edge.next_correction()).await?;
    assert_eq!(got.request_id, 5, "{topology:?}");
    let sent = pose("uav-7", 60.0, 10.0, 1);
    let got = until_heard(&poses, async || Ok(edge.publish_pose(&sent).await?)).await?;
    assert!(
        got.iter().all(|(key, _)| key.contains("uav-7")),
        "{topology:?}: {got:?}"
    );
    let change = encode(&change)?;
    let got = until_heard(&landmarks, async || {
        gs.put(keys().landmark_changes(), change.clone())
            .await
            .map_err(z)
    })
    .await?;
    assert!(
        got.iter().all(|(_, bytes)| *bytes == change),
        "{topology:?}: the landmark change came back altered"
    );
    // ...and the other edge hears nothing of uav-7.
    let spied = heard(&spy, QUIET).await;
    assert!(spied.is_empty(), "{topology:?}: edge-8 read {spied:?}");
    let alive = rogue
        .liveliness()
        .get(keys().all_alive())
        .timeout(Duration::from_secs(1))
        .await
        .map_err(z)?;
    let mut tokens = Vec::new();
    while let Ok(reply) = alive.recv_async().await {
        if let Ok(sample) = reply.result() {
            tokens.push(sample.key_expr().to_string());
        }
    }
    assert!(
        !tokens.iter().any(|t| t.ends_with("uav-7")),
        "{topology:?}: edge-8 sees uav-7 alive: {tokens:?}"
    );
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edge_reads_nothing_of_another_uav() -> anyhow::Result<()> {
    reading_another_uav(Topology::Peers).await?;
    reading_another_uav(Topology::Router).await
}
