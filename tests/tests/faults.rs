//! The field's faults, each with what the operator sees and what is kept:
//! a camera that stalls and comes back, a router that restarts under a
//! flight, an edge killed with SIGKILL, a full disk and corrupt files at start.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::MavConnection;
use mavlink::dialects::common::{GpsFixType, MavMessage};
use towernav_edge::daemon::config::{DetectorKind, EdgeConfig, MavlinkMessages, ZenohMode};
use towernav_edge::edge_cmd::run_edge;
use towernav_edge::node::open_session;
use towernav_protocol::session::{Endpoints, router_config};
use towernav_protocol::{
    CorrectionAck, Health, IdCorrection, Keys, NodeId, PoseEstimate, StatusHeartbeat, Topic,
    decode, encode,
};

/// Every sample heard, with when it arrived.
type Heard = Arc<Mutex<Vec<(Instant, Topic, Vec<u8>)>>>;

async fn listen_all(
    session: &zenoh::Session,
    fleet: &str,
) -> anyhow::Result<(Heard, tokio::task::JoinHandle<()>)> {
    let keys = Keys::new(NodeId::new(fleet)?);
    let all = session
        .declare_subscriber(keys.all_uavs_any_topic())
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let heard: Heard = Arc::default();
    let sink = heard.clone();
    let task = tokio::spawn(async move {
        while let Ok(s) = all.recv_async().await {
            if let Ok(k) = Keys::parse_uav(s.key_expr().as_str()) {
                sink.lock().unwrap_or_else(|e| e.into_inner()).push((
                    Instant::now(),
                    k.topic,
                    s.payload().to_bytes().to_vec(),
                ));
            }
        }
    });
    Ok((heard, task))
}

fn of<M: towernav_protocol::Message>(heard: &Heard, topic: Topic) -> Vec<(Instant, M)> {
    heard
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .iter()
        .filter(|(_, t, _)| *t == topic)
        .filter_map(|(at, _, bytes)| decode::<M>(bytes).ok().map(|m| (*at, m)))
        .collect()
}

fn oracle(fleet: &str, frames: u64) -> EdgeConfig {
    let mut c = EdgeConfig {
        fleet: fleet.into(),
        uav: "uav7".into(),
        ..EdgeConfig::default()
    };
    c.source.seed = 11;
    c.source.max_frames = Some(frames);
    c.source.speed = Some(1.0);
    c.detector.kind = DetectorKind::Oracle;
    c
}

/// GPS_INPUT's fix types as an autopilot hears them, with their arrival.
type Fixes = Arc<Mutex<Vec<(Instant, GpsFixType)>>>;

fn autopilot(port: u16) -> anyhow::Result<Fixes> {
    let conn = mavlink::connect::<MavMessage>(&format!("udpin:127.0.0.1:{port}"))?;
    let fixes: Fixes = Arc::default();
    let sink = fixes.clone();
    std::thread::spawn(move || {
        while let Ok((_, m)) = conn.recv() {
            if let MavMessage::GPS_INPUT(g) = m {
                sink.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push((Instant::now(), g.fix_type));
            }
        }
    });
    Ok(fixes)
}

/// The camera stops for 5 s in the middle of a flight: the status says so
/// within a heartbeat, the autopilot is told NO_FIX, status and corrections
/// keep flowing through the stall, and the edge localizes again after it
/// without a restart.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_camera_stall_is_told_at_once_and_the_edge_recovers_by_itself() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let gs = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        ..Default::default()
    })
    .await?;
    let (heard, reader) = listen_all(&gs, "stall").await?;
    let port = towernav_tests::loopback_port();
    let fixes = autopilot(port)?;

    let mut config = oracle("stall", 330);
    config.zenoh.listen = vec![];
    config.zenoh.connect = vec![endpoint];
    config.source.stall = Some([4.0, 5.0]);
    config.mavlink.enabled = true;
    config.mavlink.address = format!("udpout:127.0.0.1:{port}");
    config.mavlink.messages = MavlinkMessages::GpsInput;
    let edge =
        tokio::spawn(
            async move { run_edge(&config, None, Arc::new(AtomicBool::new(false))).await },
        );

    // Wait for the stall: frames stop advancing in the status.
    let uav = NodeId::new("uav7")?;
    let keys = Keys::new(NodeId::new("stall")?);
    let stalled_at = tokio::time::timeout(Duration::from_secs(20), async {
        loop {
            tokio::time::sleep(Duration::from_millis(100)).await;
            let statuses = of::<StatusHeartbeat>(&heard, Topic::Status);
            if let [.., (_, a), (at, b)] = &statuses[..]
                && a.frames_processed > 0
                && a.frames_processed == b.frames_processed
            {
                return *at;
            }
        }
    })
    .await?;
    // A correction sent in the stall is answered in the stall.
    let correction = IdCorrection {
        uav: uav.clone(),
        request_id: 4242,
        track_id: 999_999,
        tower_id: Some("A1".into()),
        issued_by: "faults".into(),
        release: false,
        session: None,
    };
    gs.put(keys.uav_key::<IdCorrection>(&uav), encode(&correction)?)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let summary = edge.await??;
    tokio::time::sleep(Duration::from_millis(300)).await;
    reader.abort();

    let statuses = of::<StatusHeartbeat>(&heard, Topic::Status);
    let stalled: Vec<&(Instant, StatusHeartbeat)> = statuses
        .windows(2)
        .filter(|w| w[0].1.frames_processed == w[1].1.frames_processed)
        .map(|w| &w[1])
        .collect();
    assert!(
        stalled.len() >= 3,
        "statuses keep coming through the stall: {}",
        stalled.len()
    );
    assert!(
        stalled.iter().all(|(_, s)| s.health != Health::Ok),
        "every status in the stall says so"
    );
    assert!(
        stalled.iter().any(|(_, s)| s.health == Health::Failed),
        "a stall past 3 s is a failed source"
    );
    let resumed = statuses.last().map(|(_, s)| s.clone()).expect("statuses");
    assert!(
        resumed.frames_processed > stalled[0].1.frames_processed,
        "frames again after the stall"
    );

    let acks = of::<CorrectionAck>(&heard, Topic::CorrectionAck);
    let (acked_at, _) = acks
        .iter()
        .find(|(_, a)| a.request_id == 4242)
        .expect("the correction is answered");
    let stall_end = statuses
        .iter()
        .find(|(at, s)| *at > stalled_at && s.frames_processed > stalled[0].1.frames_processed)
        .map(|(at, _)| *at)
        .expect("the stall ends");
    assert!(
        *acked_at < stall_end,
        "answered while the camera was still stalled"
    );

    let fixes = fixes.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let kinds: Vec<GpsFixType> = fixes.iter().map(|(_, f)| *f).collect();
    let first_3d = kinds
        .iter()
        .position(|f| *f == GpsFixType::GPS_FIX_TYPE_3D_FIX);
    let lost = fixes
        .iter()
        .position(|(at, f)| *at > stalled_at && *f == GpsFixType::GPS_FIX_TYPE_NO_FIX);
    let (Some(first_3d), Some(lost)) = (first_3d, lost) else {
        panic!("a fix, then NO_FIX in the stall: {kinds:?}");
    };
    assert!(first_3d < lost);
    eprintln!(
        "camera stall: status not ok from the first status without frames; NO_FIX {:.2} s after it",
        fixes[lost]
            .0
            .saturating_duration_since(stalled_at)
            .as_secs_f64()
    );
    assert!(
        kinds[lost..].contains(&GpsFixType::GPS_FIX_TYPE_3D_FIX),
        "a 3-D fix again after the stall: {kinds:?}"
    );
    let poses = of::<PoseEstimate>(&heard, Topic::Pose);
    assert!(
        poses.iter().any(|(_, p)| p.time_s > 9.5),
        "poses after the stall"
    );
    // 330 frames of 11 s, less the 5 s the camera was out (some dropped
    // rather than queued where the machine is loaded).
    let taken = summary.record.frames + summary.dropped;
    assert!((150..=190).contains(&taken), "{taken}");
    Ok(())
}

/// The router a fleet goes through: in this process, or a `zenohd` child.
enum Router {
    InProcess(zenoh::Session),
    Zenohd(towernav_tests::fleet::Zenohd),
}

async fn start_router(
    endpoint: &str,
    zenohd: Option<&std::path::Path>,
    dir: &std::path::Path,
) -> anyhow::Result<Router> {
    Ok(match zenohd {
        Some(bin) => {
            Router::Zenohd(towernav_tests::fleet::start_plain_zenohd(bin, endpoint, dir).await?)
        }
        None => Router::InProcess(
            zenoh::open(router_config(&Endpoints {
                listen: vec![endpoint.into()],
                ..Default::default()
            })?)
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?,
        ),
    })
}

impl Router {
    async fn stop(self) {
        match self {
            Router::InProcess(s) => {
                let _ = s.close().await;
            }
            Router::Zenohd(z) => drop(z),
        }
    }
}

/// What the ground station's network thread delivered, fed to its fleet
/// model as the app does, with the link state it showed every 100 ms.
struct GroundStation {
    poses: Vec<(Instant, u64)>,
    links: Vec<(Instant, towernav_ground_station::fleet::Link)>,
}

fn ground_station(
    endpoint: &str,
    fleet: &str,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<GroundStation> {
    ground_station_at(
        Endpoints {
            connect: vec![endpoint.into()],
            ..Default::default()
        },
        fleet,
        stop,
    )
}

fn ground_station_at(
    endpoints: Endpoints,
    fleet: &str,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<GroundStation> {
    use towernav_ground_station::events::NetEvent;
    let link = towernav_ground_station::net::spawn(
        endpoints,
        NodeId::new(fleet).expect("an id"),
        None,
        || {},
    );
    std::thread::spawn(move || {
        // The whole link: its command sender dropped would stop the network thread.
        let link = link;
        let start = Instant::now();
        let datum = towernav_sim::Scenario::paper(11).world.datum;
        let mut model = towernav_ground_station::fleet::Fleet::new(datum);
        let uav = NodeId::new("uav7").expect("an id");
        let mut gs = GroundStation {
            poses: Vec::new(),
            links: Vec::new(),
        };
        let mut next_look = Instant::now();
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            if let Ok(event) = link.events.recv_timeout(Duration::from_millis(20)) {
                if let NetEvent::Pose(p) = &event {
                    gs.poses.push((Instant::now(), p.seq));
                }
                model.apply(event, start.elapsed().as_secs_f64());
            }
            if Instant::now() >= next_look {
                next_look += Duration::from_millis(100);
                gs.links.push((
                    Instant::now(),
                    model.link(&uav, start.elapsed().as_secs_f64()),
                ));
            }
        }
        gs
    })
}

/// The router restarts mid-flight (2 s down): the edge and the ground
/// station reconnect by themselves, poses resume within 5 s of its return,
/// none duplicated or out of order, and the ground station shows the gap.
async fn router_restart(zenohd: Option<&std::path::Path>) -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let endpoint = towernav_tests::loopback_endpoint();
    let router = start_router(&endpoint, zenohd, dir.path()).await?;
    let stop = Arc::new(AtomicBool::new(false));
    let gs = ground_station(&endpoint, "restart", stop.clone());

    let mut config = oracle("restart", 540);
    config.zenoh.mode = ZenohMode::Client;
    config.zenoh.listen = vec![];
    config.zenoh.connect = vec![endpoint.clone()];
    let edge =
        tokio::spawn(
            async move { run_edge(&config, None, Arc::new(AtomicBool::new(false))).await },
        );
    tokio::time::sleep(Duration::from_secs(6)).await;
    router.stop().await;
    let down = Instant::now();
    tokio::time::sleep(Duration::from_secs(2)).await;
    let router = start_router(&endpoint, zenohd, dir.path()).await?;
    let up = Instant::now();
    let summary = edge.await??;
    tokio::time::sleep(Duration::from_millis(500)).await;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let gs = gs
        .join()
        .map_err(|_| anyhow::anyhow!("the ground station thread panicked"))?;
    router.stop().await;

    // Every frame processed or, on a loaded machine, dropped as the queue does.
    assert_eq!(summary.record.frames + summary.dropped, 540);
    let seqs: Vec<u64> = gs.poses.iter().map(|(_, s)| *s).collect();
    assert!(
        seqs.windows(2).all(|w| w[0] < w[1]),
        "no pose twice or out of order: {seqs:?}"
    );
    let before = gs.poses.iter().filter(|(at, _)| *at < down).count();
    let after = gs.poses.iter().find(|(at, _)| *at > up).map(|(at, _)| *at);
    assert!(
        before > 50,
        "{before} poses before the restart, {} in all; links {:?}",
        gs.poses.len(),
        gs.links.iter().map(|(_, l)| *l).collect::<Vec<_>>()
    );
    let resumed = after.expect("poses after the router came back");
    eprintln!(
        "router restart ({}): poses resumed {:.2} s after the router came back",
        if zenohd.is_some() {
            "zenohd"
        } else {
            "in-process"
        },
        resumed.duration_since(up).as_secs_f64()
    );
    assert!(
        resumed.duration_since(up) < Duration::from_secs(5),
        "poses resumed {:?} after the router",
        resumed.duration_since(up)
    );
    use towernav_ground_station::fleet::Link;
    let shown: Vec<&Link> = gs.links.iter().map(|(_, l)| l).collect();
    let live_before = shown
        .iter()
        .position(|l| l.is_live())
        .expect("live at first");
    let gap = shown[live_before..]
        .iter()
        .position(|l| matches!(l, Link::Stale(_) | Link::Lost(_)))
        .map(|i| i + live_before)
        .expect("the ground station shows the gap");
    assert!(
        shown[gap..].iter().any(|l| l.is_live()),
        "and live again after it"
    );
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_in_process_router_restart_is_ridden_out() -> anyhow::Result<()> {
    router_restart(None).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_zenohd_restart_is_ridden_out() -> anyhow::Result<()> {
    let Some(bin) = std::env::var_os("TOWERNAV_ZENOHD").map(std::path::PathBuf::from) else {
        eprintln!("skipped: no zenohd (TOWERNAV_ZENOHD; `cargo xtask test` builds it)");
        return Ok(());
    };
    router_restart(Some(&bin)).await
}

/// The ground station's database in `dir`, holding the paper's field.
fn paper_field_database(dir: &std::path::Path) -> anyhow::Result<std::path::PathBuf> {
    use towernav_landmark_db::{Author, LandmarkDb};
    let path = dir.join("gs.sqlite");
    let crew = Author {
        by: "crew".into(),
        at_unix_s: 0,
    };
    LandmarkDb::open(&path)?.upsert_all(&towernav_sim::World::paper_field().landmarks(), &crew)?;
    Ok(path)
}

/// `towernav-edge run` as a process, its log kept.
fn spawn_edge(args: &[&str], log: &std::path::Path) -> anyhow::Result<std::process::Child> {
    Ok(
        std::process::Command::new(towernav_tests::programs::sibling_binary("towernav-edge"))
            .arg("run")
            .args(args)
            .stdout(std::fs::File::create(log.with_extension("out"))?)
            .stderr(std::fs::File::create(log)?)
            .spawn()?,
    )
}

async fn wait_poses(heard: &Heard, after: Instant, n: usize) -> anyhow::Result<Vec<PoseEstimate>> {
    tokio::time::timeout(Duration::from_secs(30), async {
        loop {
            let poses: Vec<PoseEstimate> = of::<PoseEstimate>(heard, Topic::Pose)
                .into_iter()
                .filter(|(at, _)| *at > after)
                .map(|(_, p)| p)
                .collect();
            if poses.len() >= n {
                return poses;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    })
    .await
    .map_err(|_| anyhow::anyhow!("no {n} poses within 30 s"))
}

/// SIGKILL mid-flight: the replica the edge kept is whole (it is replaced
/// atomically), and the edge started again localizes from its first fix; a
/// replica found corrupt at start is set aside with a clear log line and
/// fetched again from the ground station.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edge_killed_mid_flight_starts_again_from_a_whole_or_refetched_replica()
-> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let db_path = paper_field_database(dir.path())?;
    let fleet = "killed";
    let endpoint = towernav_tests::loopback_endpoint();
    let gs = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        ..Default::default()
    })
    .await?;
    let service = tokio::spawn(towernav_ground_station::landmark_service::serve(
        gs.clone(),
        NodeId::new(fleet)?,
        db_path.clone(),
    ));
    let (heard, reader) = listen_all(&gs, fleet).await?;
    let replica = dir.path().join("replica.json");
    let replica_arg = replica.display().to_string();
    let edge_listen = towernav_tests::loopback_endpoint();
    let args = [
        "--fleet",
        fleet,
        "--uav",
        "uav7",
        "--connect",
        &endpoint,
        "--listen",
        &edge_listen,
        "--detector",
        "oracle",
        "--replica",
        &replica_arg,
        "--speed",
        "1",
        "--max-frames",
        "9000",
    ];

    let mut first = spawn_edge(&args, &dir.path().join("first.log"))?;
    wait_poses(&heard, Instant::now(), 30).await?;
    first.kill()?; // SIGKILL
    first.wait()?;
    let (kept, set_aside) = towernav_edge::landmark_sync::load_or_set_aside(&replica)?;
    assert_eq!(
        (kept.len(), set_aside),
        (18, None),
        "the replica is whole after SIGKILL"
    );

    // Started again: it localizes from its first fix.
    let restarted = Instant::now();
    let mut second = spawn_edge(&args, &dir.path().join("second.log"))?;
    let poses = wait_poses(&heard, restarted, 10).await?;
    assert!(
        poses[0].seq < 300,
        "a new run from the first frames: seq {}",
        poses[0].seq
    );
    second.kill()?;
    second.wait()?;

    // A replica cut short (a disk that failed under it): set aside, fetched again.
    let text = std::fs::read(&replica)?;
    std::fs::write(&replica, &text[..text.len() / 2])?;
    let again = Instant::now();
    let log = dir.path().join("third.log");
    let mut third = spawn_edge(&args, &log)?;
    wait_poses(&heard, again, 10).await?;
    third.kill()?;
    third.wait()?;
    let said = std::fs::read_to_string(&log)?;
    assert!(
        said.contains("corrupt"),
        "the log names the corrupt replica:\n{said}"
    );
    assert!(
        dir.path().join("replica.json.corrupt").exists(),
        "kept aside for a look"
    );
    let (refetched, _) = towernav_edge::landmark_sync::load_or_set_aside(&replica)?;
    assert_eq!(refetched.len(), 18, "fetched again from the ground station");
    reader.abort();
    service.abort();
    Ok(())
}

/// A full disk under the pose log: a clear error naming the file, and the
/// flight goes on (poses still published, the run ends well); a corrupt
/// landmark database at start: refused by name before anything starts.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_and_a_corrupt_database_are_told_by_name() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let endpoint = towernav_tests::loopback_endpoint();
    let gs = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        ..Default::default()
    })
    .await?;
    let (heard, reader) = listen_all(&gs, "disk").await?;
    let edge_listen = towernav_tests::loopback_endpoint();
    let common = [
        "--fleet",
        "disk",
        "--uav",
        "uav7",
        "--connect",
        &endpoint,
        "--listen",
        &edge_listen,
        "--detector",
        "oracle",
        "--speed",
        "1",
        "--max-frames",
        "150",
    ];
    // /dev/full: every write fails with ENOSPC, as on a full card.
    let log = dir.path().join("full.log");
    let mut args = common.to_vec();
    args.extend(["--jsonl", "/dev/full"]);
    let status = spawn_edge(&args, &log)?.wait()?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    reader.abort();
    let said = std::fs::read_to_string(&log)?;
    assert!(status.success(), "the flight goes on:\n{said}");
    assert!(
        said.contains("/dev/full") && said.contains("pose log could not be written"),
        "the error names the file:\n{said}"
    );
    assert_eq!(
        said.matches("could not be written").count(),
        1,
        "told once, not per pose"
    );
    assert!(
        of::<PoseEstimate>(&heard, Topic::Pose).len() > 50,
        "poses still reach the ground station"
    );

    let db = dir.path().join("towers.sqlite");
    std::fs::write(&db, b"SQLite format 3\0 but not really a database")?;
    let db_arg = db.display().to_string();
    let mut args = common.to_vec();
    args.extend(["--landmarks", &db_arg]);
    let log = dir.path().join("corrupt.log");
    let status = spawn_edge(&args, &log)?.wait()?;
    let said = std::fs::read_to_string(&log)?;
    assert!(!status.success(), "a corrupt database is refused:\n{said}");
    assert!(said.contains("towers.sqlite"), "naming the file:\n{said}");
    assert!(!said.contains("panicked"), "{said}");
    Ok(())
}

/// The ground station restarts mid-flight: its database is whole; the
/// restarted one gets the poses it missed from the edge's cache (history),
/// sees the correction it had sent as the edge's pin (resolved); and the same
/// correction sent again after an undo is answered as before, not applied twice.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ground_station_restart_keeps_its_database_and_never_applies_a_correction_twice()
-> anyhow::Result<()> {
    use towernav_ground_station::events::NetEvent;
    use towernav_ground_station::net::{self, NetCommand, NetLink};
    let dir = tempfile::tempdir()?;
    let db_path = paper_field_database(dir.path())?;
    let fleet = NodeId::new("gsrestart")?;
    let edge_endpoint = towernav_tests::loopback_endpoint();
    let mut config = oracle("gsrestart", 600);
    config.zenoh.listen = vec![edge_endpoint.clone()];
    config.zenoh.connect = vec![];
    let edge =
        tokio::spawn(
            async move { run_edge(&config, None, Arc::new(AtomicBool::new(false))).await },
        );
    let start_gs = || {
        net::spawn(
            Endpoints {
                connect: vec![edge_endpoint.clone()],
                ..Default::default()
            },
            fleet.clone(),
            Some(db_path.clone()),
            || {},
        )
    };
    // Events until `until` says stop, or 15 s.
    fn collect(
        link: &NetLink,
        mut until: impl FnMut(&NetEvent) -> bool,
    ) -> Vec<(Instant, NetEvent)> {
        let end = Instant::now() + Duration::from_secs(15);
        let mut got = Vec::new();
        while Instant::now() < end {
            if let Ok(e) = link.events.recv_timeout(Duration::from_millis(50)) {
                let stop = until(&e);
                got.push((Instant::now(), e));
                if stop {
                    break;
                }
            }
        }
        got
    }
    let first = start_gs();
    // A bound track, then the operator pins it to its tower.
    // Three seconds of flight heard, then a bound track.
    let mut heard_s = 0.0;
    let seen = collect(&first, |e| match e {
        NetEvent::Pose(p) => {
            heard_s = p.time_s;
            false
        }
        NetEvent::Tracks(t) => heard_s >= 3.0 && t.tracks.iter().any(|t| t.tower_id.is_some()),
        _ => false,
    });
    let (track, tower) = seen
        .iter()
        .rev()
        .find_map(|(_, e)| match e {
            NetEvent::Tracks(t) => t
                .tracks
                .iter()
                .find_map(|t| Some((t.track_id, t.tower_id.clone()?))),
            _ => None,
        })
        .expect("a bound track");
    let uav = NodeId::new("uav7")?;
    let pin = IdCorrection {
        uav: uav.clone(),
        request_id: 1_000_001,
        track_id: track,
        tower_id: Some(tower.clone()),
        issued_by: "operator".into(),
        release: false,
        session: None,
    };
    first.commands.send(NetCommand::Correct(pin.clone()))?;
    let answered = collect(
        &first,
        |e| matches!(e, NetEvent::Ack(a) if a.request_id == pin.request_id),
    );
    assert!(
        answered
            .iter()
            .any(|(_, e)| matches!(e, NetEvent::Ack(a) if a.accepted)),
        "the pin is accepted"
    );
    let before_restart_s = seen
        .iter()
        .chain(&answered)
        .filter_map(|(_, e)| match e {
            NetEvent::Pose(p) => Some(p.time_s),
            _ => None,
        })
        .fold(0.0, f64::max);
    drop(first); // the ground station goes away
    tokio::time::sleep(Duration::from_secs(1)).await;
    let db = towernav_landmark_db::LandmarkDb::open(&db_path)?;
    assert_eq!(db.list()?.len(), 18, "the database is whole");

    let second = start_gs();
    // Until the pin shows, a pose from before the restart has come (the
    // history, whose reply may trail the live poses on a loaded machine) and
    // the live poses run 2 s past what the first one heard; 15 s at most.
    let (mut pinned_seen, mut live_s, mut oldest_s) = (false, 0.0, f64::INFINITY);
    let seen = collect(&second, |e| {
        match e {
            NetEvent::Pose(p) => {
                live_s = f64::max(live_s, p.time_s);
                oldest_s = f64::min(oldest_s, p.time_s);
            }
            NetEvent::Tracks(t) => {
                pinned_seen |= t.tracks.iter().any(|t| t.track_id == track && t.pinned)
            }
            _ => {}
        }
        pinned_seen && oldest_s <= before_restart_s && live_s > before_restart_s + 2.0
    });
    let poses: Vec<&PoseEstimate> = seen
        .iter()
        .filter_map(|(_, e)| match e {
            NetEvent::Pose(p) => Some(p),
            _ => None,
        })
        .collect();
    let earliest = poses.iter().map(|p| p.time_s).fold(f64::INFINITY, f64::min);
    assert!(
        earliest <= before_restart_s,
        "history: a pose from before it joined ({earliest:.1} s; the first had seen {before_restart_s:.1} s)"
    );
    assert!(
        seen.iter().any(|(_, e)| matches!(e, NetEvent::Tracks(t) if t.tracks.iter().any(|t| t.track_id == track && t.pinned))),
        "the restarted ground station sees the pin: resolved"
    );
    // The operator undoes it, then the old correction arrives again.
    let release = IdCorrection {
        request_id: 1_000_002,
        release: true,
        ..pin.clone()
    };
    second.commands.send(NetCommand::Correct(release.clone()))?;
    collect(
        &second,
        |e| matches!(e, NetEvent::Ack(a) if a.request_id == release.request_id),
    );
    second.commands.send(NetCommand::Correct(pin.clone()))?;
    let after = collect(
        &second,
        |e| matches!(e, NetEvent::Ack(a) if a.request_id == pin.request_id),
    );
    assert!(after.iter().any(
        |(_, e)| matches!(e, NetEvent::Ack(a) if a.request_id == pin.request_id && a.accepted)
    ));
    let later = collect(
        &second,
        |e| matches!(e, NetEvent::Tracks(t) if t.tracks.iter().any(|t| t.track_id == track)),
    );
    let still_pinned = later.iter().rev().find_map(|(_, e)| match e {
        NetEvent::Tracks(t) => t
            .tracks
            .iter()
            .find(|t| t.track_id == track)
            .map(|t| t.pinned),
        _ => None,
    });
    assert_eq!(
        still_pinned,
        Some(false),
        "the repeat is not applied: the undo stands"
    );
    drop(second);
    edge.abort();
    Ok(())
}

/// A TCP proxy between edge and ground station that delays every chunk by
/// `delay` and holds one in five for a further `stall` (a lost segment's
/// retransmission, as TCP's user sees 20 % loss), order kept.
async fn lossy_proxy(listen: u16, to: u16, delay: Duration, stall: Duration) -> anyhow::Result<()> {
    let listener = tokio::net::TcpListener::bind(("127.0.0.1", listen)).await?;
    tokio::spawn(async move {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        while let Ok((inbound, _)) = listener.accept().await {
            let Ok(outbound) = tokio::net::TcpStream::connect(("127.0.0.1", to)).await else {
                continue;
            };
            let (ri, wi) = inbound.into_split();
            let (ro, wo) = outbound.into_split();
            for (mut from, mut into) in [
                (
                    Box::new(ri) as Box<dyn tokio::io::AsyncRead + Send + Unpin>,
                    Box::new(wo) as Box<dyn tokio::io::AsyncWrite + Send + Unpin>,
                ),
                (Box::new(ro), Box::new(wi)),
            ] {
                seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                let mut rng = seed;
                let (tx, mut rx) =
                    tokio::sync::mpsc::unbounded_channel::<(tokio::time::Instant, Vec<u8>)>();
                tokio::spawn(async move {
                    use tokio::io::AsyncReadExt;
                    let mut buf = vec![0u8; 64 * 1024];
                    let mut release = tokio::time::Instant::now();
                    while let Ok(n) = from.read(&mut buf).await {
                        if n == 0 {
                            break;
                        }
                        rng ^= rng << 13;
                        rng ^= rng >> 7;
                        rng ^= rng << 17;
                        let lost = rng.is_multiple_of(5);
                        let due = tokio::time::Instant::now()
                            + delay
                            + if lost { stall } else { Duration::ZERO };
                        release = release.max(due);
                        if tx.send((release, buf[..n].to_vec())).is_err() {
                            break;
                        }
                    }
                });
                tokio::spawn(async move {
                    use tokio::io::AsyncWriteExt;
                    while let Some((at, bytes)) = rx.recv().await {
                        tokio::time::sleep_until(at).await;
                        if into.write_all(&bytes).await.is_err() {
                            break;
                        }
                    }
                });
            }
        }
    });
    Ok(())
}

/// netem's 20 % loss and 200 ms delay on a veth into a network namespace,
/// where the kernel allows it (the host's end of the veth); `None`, saying
/// why, where it does not.
fn netem_namespace(name: &str) -> Option<String> {
    let run = |args: &[&str]| {
        std::process::Command::new(args[0])
            .args(&args[1..])
            .output()
            .map_err(|e| e.to_string())
            .and_then(|o| {
                o.status
                    .success()
                    .then_some(())
                    .ok_or_else(|| String::from_utf8_lossy(&o.stderr).trim().to_owned())
            })
    };
    let host = format!("{name}h");
    let inside = format!("{name}n");
    let steps: Vec<Vec<String>> = vec![
        vec!["ip".into(), "netns".into(), "add".into(), name.into()],
        vec![
            "ip".into(),
            "link".into(),
            "add".into(),
            host.clone(),
            "type".into(),
            "veth".into(),
            "peer".into(),
            "name".into(),
            inside.clone(),
        ],
        vec![
            "ip".into(),
            "link".into(),
            "set".into(),
            inside.clone(),
            "netns".into(),
            name.into(),
        ],
        vec![
            "ip".into(),
            "addr".into(),
            "add".into(),
            "10.213.0.1/24".into(),
            "dev".into(),
            host.clone(),
        ],
        vec![
            "ip".into(),
            "link".into(),
            "set".into(),
            host.clone(),
            "up".into(),
        ],
        vec![
            "ip".into(),
            "netns".into(),
            "exec".into(),
            name.into(),
            "ip".into(),
            "addr".into(),
            "add".into(),
            "10.213.0.2/24".into(),
            "dev".into(),
            inside.clone(),
        ],
        vec![
            "ip".into(),
            "netns".into(),
            "exec".into(),
            name.into(),
            "ip".into(),
            "link".into(),
            "set".into(),
            inside.clone(),
            "up".into(),
        ],
        vec![
            "ip".into(),
            "netns".into(),
            "exec".into(),
            name.into(),
            "ip".into(),
            "link".into(),
            "set".into(),
            "lo".into(),
            "up".into(),
        ],
        vec![
            "tc".into(),
            "qdisc".into(),
            "add".into(),
            "dev".into(),
            host.clone(),
            "root".into(),
            "netem".into(),
            "loss".into(),
            "20%".into(),
            "delay".into(),
            "200ms".into(),
        ],
    ];
    for step in &steps {
        let args: Vec<&str> = step.iter().map(String::as_str).collect();
        if let Err(why) = run(&args) {
            let _ = run(&["ip", "link", "del", &host]);
            let _ = run(&["ip", "netns", "del", name]);
            eprintln!(
                "netem skipped (the proxy still runs): `{}` refused: {why}",
                step.join(" ")
            );
            return None;
        }
    }
    Some(host)
}

/// 20 % loss and 200 ms delay between edge and ground station: poses come
/// late but in order and none lost, and the ground station shows the link
/// live with a fix, not lost. Through the kernel's netem in a network
/// namespace where it allows; always through a delaying proxy.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lossy_link_brings_poses_late_but_in_order() -> anyhow::Result<()> {
    if let Some(host) = netem_namespace("tnfault") {
        // The kernel allows it: the edge runs inside, the ground station outside.
        let outcome = lossy_through(
            "tcp/10.213.0.1",
            Some(vec![
                "ip".into(),
                "netns".into(),
                "exec".into(),
                "tnfault".into(),
            ]),
        )
        .await;
        let _ = std::process::Command::new("ip")
            .args(["link", "del", &host])
            .status();
        let _ = std::process::Command::new("ip")
            .args(["netns", "del", "tnfault"])
            .status();
        outcome?;
    }
    lossy_through("proxy", None).await
}

async fn lossy_through(how: &str, wrap: Option<Vec<String>>) -> anyhow::Result<()> {
    let stop = Arc::new(AtomicBool::new(false));
    let gs_port = towernav_tests::loopback_port();
    let (gs_endpoint, edge_connect) = match wrap {
        None => {
            let proxy = towernav_tests::loopback_port();
            lossy_proxy(
                proxy,
                gs_port,
                Duration::from_millis(200),
                Duration::from_millis(300),
            )
            .await?;
            (
                format!("tcp/127.0.0.1:{gs_port}"),
                format!("tcp/127.0.0.1:{proxy}"),
            )
        }
        Some(_) => (format!("{how}:{gs_port}"), format!("{how}:{gs_port}")),
    };
    // The ground station listens; the edge, listening nowhere (so nothing
    // goes around the bad link), connects to it through it.
    let gs = ground_station_at(
        Endpoints {
            listen: vec![gs_endpoint],
            ..Default::default()
        },
        "lossy",
        stop.clone(),
    );
    let dir = tempfile::tempdir()?;
    let log = dir.path().join("edge.log");
    let pose_log = dir.path().join("poses.jsonl");
    let config = dir.path().join("edge.toml");
    std::fs::write(
        &config,
        format!(
            "fleet = \"lossy\"\nuav = \"uav7\"\n[zenoh]\nlisten = []\nconnect = [\"{edge_connect}\"]\n\
             [source]\nmax_frames = 300\nspeed = 1.0\n[detector]\nkind = \"oracle\"\n\
             [output]\njsonl = \"{}\"\n",
            pose_log.display()
        ),
    )?;
    let edge_bin = towernav_tests::programs::sibling_binary("towernav-edge");
    let mut cmd = match &wrap {
        Some(prefix) => {
            let mut c = std::process::Command::new(&prefix[0]);
            c.args(&prefix[1..]).arg(&edge_bin);
            c
        }
        None => std::process::Command::new(&edge_bin),
    };
    let status = cmd
        .arg("run")
        .arg("--config")
        .arg(&config)
        .stdout(std::fs::File::create(log.with_extension("out"))?)
        .stderr(std::fs::File::create(&log)?)
        .status()?;
    anyhow::ensure!(
        status.success(),
        "the edge failed: {}",
        std::fs::read_to_string(&log)?
    );
    tokio::time::sleep(Duration::from_secs(3)).await;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let gs = gs
        .join()
        .map_err(|_| anyhow::anyhow!("the ground station thread panicked"))?;

    let logged = std::fs::read_to_string(&pose_log)?.lines().count();
    let seqs: Vec<u64> = gs.poses.iter().map(|(_, s)| *s).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{how}: in order");
    assert_eq!(
        seqs.len(),
        logged,
        "{how}: every pose the edge logged arrived"
    );
    use towernav_ground_station::fleet::Link;
    let first_live = gs
        .links
        .iter()
        .position(|(_, l)| l.is_live())
        .expect("live");
    let last_pose = gs.poses.last().map(|(at, _)| *at).expect("poses");
    let during: Vec<&Link> = gs.links[first_live..]
        .iter()
        .filter(|(at, _)| *at < last_pose)
        .map(|(_, l)| l)
        .collect();
    assert!(
        during.iter().all(|l| !l.is_lost()),
        "{how}: late is not lost: {during:?}"
    );
    Ok(())
}
