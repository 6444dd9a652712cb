//! A fleet through one router: `n` simulated edges (oracle detector) connect
//! to a router, in-process (a router-mode Zenoh session, the subscriber in it)
//! or a `zenohd` process (the subscriber a client of it, as a ground station
//! is); the subscriber counts every pose by UAV and sequence number and
//! measures its age from the sender's timestamp. With `secure`, the fleet's
//! CA issues every node a certificate and all links are mutual TLS under the
//! access rules. Shared by the fleet test and `cargo bench -p towernav-tests --bench fleet`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use towernav_edge::daemon::config::{DetectorKind, EdgeConfig, ZenohMode};
use towernav_edge::edge_cmd::run_edge;
use towernav_edge::node::wait_for_peer;
use towernav_fleet::{Authority, node, router};
use towernav_ground_station::recording::Recorder;
use towernav_protocol::security::{Credentials, Role};
use towernav_protocol::session::{Endpoints, client_config, router_config};
use towernav_protocol::{Keys, NodeId, PoseEstimate, decode_on_key};

/// Pose sequence numbers per UAV, and pose ages in ms, as the subscriber saw them.
type Seen = (BTreeMap<String, BTreeSet<u64>>, Vec<f64>);

pub struct FleetOptions {
    pub edges: usize,
    pub frames: u64,
    /// Simulator speed (1 = real time, 30 Hz per edge; 0 = as fast as possible).
    pub speed: f64,
    /// JPEG previews per second per edge (0: none).
    pub preview_hz: f64,
    /// Record every topic the subscriber sees into this MCAP file.
    pub record: Option<PathBuf>,
    /// Route through this `zenohd` (`cargo xtask zenohd`) instead of an in-process router.
    pub zenohd: Option<PathBuf>,
    /// Mutual TLS with certificates from a fresh fleet CA, and its access rules.
    pub secure: bool,
}

#[derive(Debug, Default)]
pub struct FleetReport {
    /// Poses each edge says it published.
    pub published: BTreeMap<String, u64>,
    /// Distinct pose sequence numbers the subscriber got, per UAV.
    pub received: BTreeMap<String, u64>,
    /// Age of each pose at the subscriber (sender's timestamp to arrival), ms.
    pub latency_ms: Vec<f64>,
    pub wall_s: f64,
}

impl FleetReport {
    /// UAVs whose received poses fall short of what they published: (uav, published, received).
    pub fn lost(&self) -> Vec<(String, u64, u64)> {
        self.published
            .iter()
            .filter_map(|(uav, &p)| {
                let r = self.received.get(uav).copied().unwrap_or(0);
                (r < p).then(|| (uav.clone(), p, r))
            })
            .collect()
    }

    /// (p50, p99, max) of the latency, ms.
    pub fn latency(&self) -> (f64, f64, f64) {
        let mut v = self.latency_ms.clone();
        if v.is_empty() {
            return (0.0, 0.0, 0.0);
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        (at(0.5), at(0.99), v[v.len() - 1])
    }
}

fn uav_id(i: usize) -> String {
    format!("uav{i:02}")
}

fn edge_config(
    fleet: &str,
    uav: usize,
    router: &str,
    credentials: Option<PathBuf>,
    options: &FleetOptions,
) -> EdgeConfig {
    let mut c = EdgeConfig {
        fleet: fleet.into(),
        uav: uav_id(uav),
        ..EdgeConfig::default()
    };
    c.zenoh.credentials = credentials;
    c.zenoh.listen = vec![];
    c.zenoh.connect = vec![router.into()];
    c.zenoh.mode = ZenohMode::Client;
    c.source.seed = 100 + uav as u64;
    c.source.max_frames = Some(options.frames);
    c.source.speed = Some(options.speed);
    c.detector.kind = DetectorKind::Oracle;
    c.output.preview_hz = options.preview_hz;
    c
}

/// The fleet's certificates: a CA folder with a router, a ground station
/// (the subscriber) and one edge per UAV.
struct Certificates {
    _dir: tempfile::TempDir,
    ca: PathBuf,
}

impl Certificates {
    fn issue(fleet: &str, edges: usize) -> anyhow::Result<Self> {
        let dir = tempfile::tempdir()?;
        let ca = dir.path().join("fleet");
        let mut authority = Authority::init(&ca, fleet, 2)?;
        let host = ["127.0.0.1".to_owned()];
        authority.issue(node("router", Role::Router, None, &host)?, 1)?;
        authority.issue(node("bench-gs", Role::GroundStation, None, &host)?, 1)?;
        for i in 0..edges {
            let uav = uav_id(i);
            authority.issue(
                node(&format!("edge-{uav}"), Role::Edge, Some(&uav), &host)?,
                1,
            )?;
        }
        Ok(Self { _dir: dir, ca })
    }

    fn node(&self, name: &str) -> PathBuf {
        self.ca.join(towernav_fleet::NODES_DIR).join(name)
    }

    fn credentials(&self, name: &str) -> anyhow::Result<Credentials> {
        Ok(Credentials::load(&self.node(name), name)?)
    }
}

/// A `zenohd` child process, killed when dropped.
pub struct Zenohd(std::process::Child);

impl Drop for Zenohd {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A plain (no TLS) `zenohd` on `endpoint`, once its port accepts.
pub async fn start_plain_zenohd(
    bin: &std::path::Path,
    endpoint: &str,
    dir: &std::path::Path,
) -> anyhow::Result<Zenohd> {
    start_zenohd(bin, endpoint, None, dir).await
}

/// Starts `zenohd` listening on `endpoint` and waits until its port accepts.
async fn start_zenohd(
    bin: &std::path::Path,
    endpoint: &str,
    certificates: Option<&Certificates>,
    dir: &std::path::Path,
) -> anyhow::Result<Zenohd> {
    let listen = [endpoint.to_owned()];
    let config = match certificates {
        Some(c) => router::router_config(&c.credentials("router")?, &listen),
        None => serde_json::json!({
            "mode": "router",
            "listen": { "endpoints": listen },
            "scouting": { "multicast": { "enabled": false } },
            "timestamping": { "enabled": { "router": true, "peer": true, "client": true } },
        }),
    };
    let path = dir.join("zenohd.json5");
    std::fs::write(&path, serde_json::to_string_pretty(&config)?)?;
    let child = std::process::Command::new(bin)
        .arg("-c")
        .arg(&path)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .map_err(|e| anyhow::anyhow!("starting {}: {e}", bin.display()))?;
    let router = Zenohd(child);
    let port = endpoint.rsplit(':').next().unwrap_or_default();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    // A refused loopback connect returns at once: no need for an async one.
    while std::net::TcpStream::connect(format!("127.0.0.1:{port}")).is_err() {
        anyhow::ensure!(
            tokio::time::Instant::now() < deadline,
            "{} did not listen on {endpoint} within 20 s",
            bin.display()
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    Ok(router)
}

pub async fn run_fleet(options: &FleetOptions) -> anyhow::Result<FleetReport> {
    let fleet = "fleet";
    let port = crate::loopback_port();
    let endpoint = if options.secure {
        format!("tls/127.0.0.1:{port}")
    } else {
        format!("tcp/127.0.0.1:{port}")
    };
    let err = |e: zenoh::Error| anyhow::anyhow!("{e}");
    let certificates = match options.secure {
        true => Some(Certificates::issue(fleet, options.edges)?),
        false => None,
    };
    let scratch = tempfile::tempdir()?;
    let (_zenohd, router) = match &options.zenohd {
        Some(bin) => {
            let process =
                start_zenohd(bin, &endpoint, certificates.as_ref(), scratch.path()).await?;
            let security = match &certificates {
                Some(c) => Some(c.credentials("bench-gs")?),
                None => None,
            };
            let session = zenoh::open(client_config(&Endpoints {
                listen: vec![],
                connect: vec![endpoint.clone()],
                security,
            })?)
            .await
            .map_err(err)?;
            wait_for_peer(&session, Duration::from_secs(10)).await?;
            (Some(process), session)
        }
        None => {
            let security = match &certificates {
                Some(c) => Some(c.credentials("router")?),
                None => None,
            };
            let session = zenoh::open(router_config(&Endpoints {
                listen: vec![endpoint.clone()],
                connect: vec![],
                security,
            })?)
            .await
            .map_err(err)?;
            (None, session)
        }
    };
    // The subscriber lives in the router itself, or is linked to it already:
    // it is in place before any edge connects.
    let keys = Keys::new(NodeId::new(fleet)?);
    let all = router
        .declare_subscriber(keys.all_uavs_any_topic())
        .await
        .map_err(err)?;
    let seen: Arc<Mutex<Seen>> = Arc::default();
    let mut recorder = match &options.record {
        Some(path) => Some(Recorder::create(path)?),
        None => None,
    };
    let (poses_tx, mut poses_rx) = tokio::sync::watch::channel(0u64);
    let reader = tokio::spawn({
        let seen = seen.clone();
        async move {
            while let Ok(sample) = all.recv_async().await {
                record(&mut recorder, &sample);
                if count_pose(&sample, &seen) {
                    poses_tx.send_modify(|n| *n += 1);
                }
            }
            if let Some(rec) = recorder {
                rec.finish().map(|_| ())
            } else {
                Ok(())
            }
        }
    });
    let start = std::time::Instant::now();
    let mut tasks = Vec::new();
    for i in 0..options.edges {
        let credentials = certificates
            .as_ref()
            .map(|c| c.node(&format!("edge-{}", uav_id(i))));
        let config = edge_config(fleet, i, &endpoint, credentials, options);
        tasks.push(tokio::spawn(async move {
            let summary = run_edge(&config, None, Arc::new(AtomicBool::new(false))).await?;
            anyhow::Ok((config.uav, summary.record.poses_published))
        }));
    }
    let mut report = FleetReport::default();
    for t in tasks {
        let (uav, published) = t.await??;
        report.published.insert(uav, published);
    }
    report.wall_s = start.elapsed().as_secs_f64();
    // Wait until every published pose has arrived, or a generous grace period;
    // the report counts what did not.
    let expected: u64 = report.published.values().sum();
    let _ = tokio::time::timeout(
        Duration::from_secs(5),
        poses_rx.wait_for(|n| *n >= expected),
    )
    .await;
    drop(router);
    let recorded = tokio::time::timeout(Duration::from_secs(5), reader).await;
    if let Ok(Ok(Err(e))) = recorded {
        anyhow::bail!("recording: {e}");
    }
    let seen = seen.lock().unwrap_or_else(|e| e.into_inner());
    report.received = seen
        .0
        .iter()
        .map(|(uav, seqs)| (uav.clone(), seqs.len() as u64))
        .collect();
    report.latency_ms = seen.1.clone();
    Ok(report)
}

/// Writes `sample` to the recording; a failed write stops the recording.
fn record(recorder: &mut Option<Recorder>, sample: &zenoh::sample::Sample) {
    let Some(rec) = recorder.as_mut() else {
        return;
    };
    let now_ns = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let payload = sample.payload().to_bytes();
    if let Err(e) = rec.write(sample.key_expr().as_str(), &payload, now_ns) {
        eprintln!("recording stopped: {e}");
        *recorder = None;
    }
}

/// Counts `sample` if it is a pose: its seq under its UAV, and its age.
fn count_pose(sample: &zenoh::sample::Sample, seen: &Mutex<Seen>) -> bool {
    // Counted under the UAV of its key; a pose naming another UAV is not counted.
    let Ok(pose) =
        decode_on_key::<PoseEstimate>(sample.key_expr().as_str(), &sample.payload().to_bytes())
    else {
        return false;
    };
    let age_ms = sample
        .timestamp()
        .and_then(|t| {
            SystemTime::now()
                .duration_since(t.get_time().to_system_time())
                .ok()
        })
        .map(|d| d.as_secs_f64() * 1e3);
    let mut seen = seen.lock().unwrap_or_else(|e| e.into_inner());
    seen.0
        .entry(pose.uav.as_str().to_owned())
        .or_default()
        .insert(pose.seq);
    if let Some(age) = age_ms {
        seen.1.push(age);
    }
    true
}
