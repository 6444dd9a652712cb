//! The edge daemon end to end on loopback: a plain Zenoh subscriber sees its
//! poses (checked against the simulator's truth), tracks, detections, status
//! and liveliness; an operator's correction round trip; the daemon localizing
//! with nobody listening; and a corrupt frame survived.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use towernav_edge::daemon::config::{AttitudeKind, DetectorKind, EdgeConfig, SourceKind};
use towernav_edge::edge_cmd::run_edge;
use towernav_edge::node::open_session;
use towernav_edge::node::wait_for_peer;
use towernav_protocol::session::Endpoints;
use towernav_protocol::{
    CorrectionAck, Health, IdCorrection, Keys, NodeId, PoseEstimate, StatusHeartbeat, Topic,
    TrackReport, decode, encode,
};
use towernav_sim::Scenario;
use zenoh::sample::SampleKind;

/// Stated bound for ours on the first 20 s of the skeleton's flight (the demo reaches 1.6 m).
const MAX_RMS_M: f64 = 3.0;

fn oracle_config(fleet: &str, connect: &str, frames: u64) -> EdgeConfig {
    let mut c = EdgeConfig {
        fleet: fleet.into(),
        uav: "uav7".into(),
        ..EdgeConfig::default()
    };
    c.zenoh.listen = vec![];
    c.zenoh.connect = vec![connect.into()];
    c.source.seed = 11;
    c.source.max_frames = Some(frames);
    c.source.speed = Some(0.0);
    c.detector.kind = DetectorKind::Oracle;
    c
}

/// Samples a subscriber receives, kept as (key, payload) while it runs; the
/// watch counts poses.
type Collected = (
    Arc<std::sync::Mutex<Vec<(String, Vec<u8>)>>>,
    tokio::sync::watch::Receiver<u64>,
    tokio::task::JoinHandle<()>,
);

fn collect(
    all: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
) -> Collected {
    let received = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (poses_tx, poses_rx) = tokio::sync::watch::channel(0u64);
    let reader = tokio::spawn({
        let received = received.clone();
        async move {
            while let Ok(sample) = all.recv_async().await {
                let key = sample.key_expr().as_str().to_owned();
                let bytes = sample.payload().to_bytes().to_vec();
                let pose = Keys::parse_uav(&key).is_ok_and(|k| k.topic == Topic::Pose);
                received
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push((key, bytes));
                if pose {
                    poses_tx.send_modify(|n| *n += 1);
                }
            }
        }
    });
    (received, poses_rx, reader)
}

/// The liveliness token's samples until it is deleted (or 3 s of silence).
async fn token_kinds(
    alive: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
) -> anyhow::Result<Vec<SampleKind>> {
    let mut kinds = Vec::new();
    while let Ok(Ok(s)) = tokio::time::timeout(Duration::from_secs(3), alive.recv_async()).await {
        assert_eq!(Keys::parse_alive(s.key_expr().as_str())?.as_str(), "uav7");
        kinds.push(s.kind());
        if s.kind() == SampleKind::Delete {
            break;
        }
    }
    Ok(kinds)
}

/// The next payload on `subscriber`, decoded; an error after 10 s of nothing.
async fn next_payload<M: towernav_protocol::Message>(
    subscriber: &zenoh::pubsub::Subscriber<
        zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>,
    >,
) -> anyhow::Result<M> {
    let sample = tokio::time::timeout(Duration::from_secs(10), subscriber.recv_async())
        .await?
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(decode(&sample.payload().to_bytes())?)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_subscriber_gets_every_topic_and_the_poses_match_the_truth() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let listener = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
        ..Default::default()
    })
    .await?;
    let keys = Keys::new(NodeId::new("itest")?);
    let all = listener
        .declare_subscriber(keys.all_uavs_any_topic())
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let alive = listener
        .liveliness()
        .declare_subscriber(keys.all_alive())
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;

    // Read while the edge runs: a subscriber that stops reading makes the publisher wait or drop.
    let (received, mut poses_rx, reader) = collect(all);
    let dir = tempfile::tempdir()?;
    let mut config = oracle_config("itest", &endpoint, 600);
    config.output.jsonl = Some(dir.path().join("poses.jsonl"));
    let summary = run_edge(&config, None, Arc::new(AtomicBool::new(false))).await?;
    assert_eq!(summary.record.frames, 600);
    assert!(
        summary.record.poses_published > 450,
        "{}",
        summary.record.poses_published
    );
    assert_eq!((summary.dropped, summary.failed), (0, 0));

    let scenario = Scenario::paper(11);
    let (mut poses, mut tracks, mut detections, mut statuses) = (Vec::new(), 0, 0, Vec::new());
    // Every published pose has arrived, or the count below says how many did not.
    let published = summary.record.poses_published;
    let _ = tokio::time::timeout(
        Duration::from_secs(5),
        poses_rx.wait_for(|n| *n >= published),
    )
    .await;
    reader.abort();
    let samples = std::mem::take(&mut *received.lock().unwrap_or_else(|e| e.into_inner()));
    for (key, bytes) in samples {
        let key = Keys::parse_uav(&key)?;
        assert_eq!(key.uav.as_str(), "uav7");
        match key.topic {
            Topic::Pose => poses.push(decode::<PoseEstimate>(&bytes)?),
            Topic::Tracks => tracks += usize::from(decode::<TrackReport>(&bytes).is_ok()),
            Topic::Detections => detections += 1,
            Topic::Status => statuses.push(decode::<StatusHeartbeat>(&bytes)?),
            _ => {}
        }
    }
    assert_eq!(
        poses.len() as u64,
        summary.record.poses_published,
        "no pose lost"
    );
    assert_eq!((tracks, detections), (600, 600));
    let errors: Vec<f64> = poses
        .iter()
        .map(|p| {
            let t = scenario.truth(p.seq).pose.position_in_world;
            ((p.east_m - t.x).powi(2) + (p.north_m - t.y).powi(2)).sqrt()
        })
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    assert!(rms < MAX_RMS_M, "horizontal RMS {rms:.2} m");
    // Status comes once a second; a fast run may send only the first.
    if let Some(s) = statuses.last() {
        assert_eq!((s.detector.as_str(), s.health), ("oracle", Health::Ok));
    }
    let log = std::fs::read_to_string(dir.path().join("poses.jsonl"))?;
    assert_eq!(log.lines().count() as u64, summary.record.poses_published);
    let first: PoseEstimate = serde_json::from_str(log.lines().next().unwrap_or_default())?;
    assert_eq!(first.uav.as_str(), "uav7");

    let kinds = token_kinds(&alive).await?;
    assert_eq!(
        kinds,
        [SampleKind::Put, SampleKind::Delete],
        "the token comes and goes with the daemon"
    );
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_no_ground_station_the_edge_keeps_localizing() -> anyhow::Result<()> {
    // Nobody listens at this endpoint.
    let endpoint = towernav_tests::loopback_endpoint();
    let config = oracle_config("alone", &endpoint, 300);
    let summary = run_edge(&config, None, Arc::new(AtomicBool::new(false))).await?;
    assert_eq!(summary.record.frames, 300);
    assert!(summary.record.poses_published > 200);
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_correction_is_applied_acknowledged_and_kept() -> anyhow::Result<()> {
    let endpoint = towernav_tests::loopback_endpoint();
    let gs = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
        ..Default::default()
    })
    .await?;
    let uav = NodeId::new("uav7")?;
    let keys = Keys::new(NodeId::new("corr")?);
    let tracks = gs
        .declare_subscriber(keys.uav_key::<TrackReport>(&uav))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let acks = gs
        .declare_subscriber(keys.uav_key::<CorrectionAck>(&uav))
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut config = oracle_config("corr", &endpoint, 900);
    config.source.speed = Some(2.0);
    let stop = Arc::new(AtomicBool::new(false));
    let edge = tokio::spawn({
        let stop = stop.clone();
        async move { run_edge(&config, None, stop).await }
    });
    wait_for_peer(&gs, Duration::from_secs(10)).await?;

    // Wait for a track bound to a tower, then pin it to another tower of the field.
    let bound = loop {
        let report: TrackReport = next_payload(&tracks).await?;
        if let Some(t) = report.tracks.iter().find(|t| t.tower_id.is_some()) {
            break t.clone();
        }
    };
    // Another tower of the track's type: one of another type would be refused.
    let other = Scenario::paper(11)
        .world
        .landmarks()
        .into_iter()
        .find(|r| Some(&r.id) != bound.tower_id.as_ref() && r.tower_type == bound.tower_type)
        .map(|r| r.id)
        .ok_or_else(|| anyhow::anyhow!("a second tower of type {}", bound.tower_type))?;
    let send = |request_id: u64, tower: &str| {
        let correction = IdCorrection {
            uav: uav.clone(),
            request_id,
            track_id: bound.track_id,
            tower_id: Some(tower.to_string()),
            issued_by: "test".into(),
            release: false,
            session: None,
        };
        let key = keys.uav_key::<IdCorrection>(&uav);
        let gs = gs.clone();
        async move {
            gs.put(key, encode(&correction)?)
                .await
                .map_err(|e| anyhow::anyhow!("{e}"))
        }
    };
    send(1, &other).await?;
    send(2, "NO-SUCH-TOWER").await?;
    let mut answers: Vec<CorrectionAck> = Vec::new();
    while answers.len() < 2 {
        answers.push(next_payload(&acks).await?);
    }
    answers.sort_by_key(|a| a.request_id);
    assert!(answers[0].accepted, "{:?}", answers[0]);
    assert!(!answers[1].accepted);
    assert!(
        answers[1]
            .reason
            .as_deref()
            .unwrap_or_default()
            .contains("NO-SUCH-TOWER"),
        "{:?}",
        answers[1].reason
    );
    // Reports queued before the correction still show the old binding; once
    // the pin shows, every later report keeps it while the track lives.
    let mut pinned_seen = 0;
    for _ in 0..120 {
        let report: TrackReport = next_payload(&tracks).await?;
        if let Some(t) = report.tracks.iter().find(|t| t.track_id == bound.track_id)
            && (pinned_seen > 0 || t.pinned)
        {
            assert!(
                t.pinned && t.tower_id.as_deref() == Some(other.as_str()),
                "{t:?}"
            );
            pinned_seen += 1;
        }
    }
    assert!(
        pinned_seen > 10,
        "the corrected track stayed pinned ({pinned_seen} reports)"
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let summary = edge.await??;
    assert!(
        summary.record.frames < 900,
        "the stop flag ended the run early"
    );
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupt_frame_is_skipped_and_counted_and_the_rest_are_processed() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let mut c = frames_and_towers(dir.path(), "fake-v8-towers.onnx")?;
    std::fs::write(
        dir.path().join("frames").join("f2b.png"),
        b"not a png at all",
    )?;
    c.output.annotated = Some(dir.path().join("annotated"));
    let summary = run_edge(&c, None, Arc::new(AtomicBool::new(false))).await?;
    assert_eq!(summary.failed, 1, "the corrupt file");
    assert_eq!(summary.record.frames, 4, "every good frame went through");
    let written = std::fs::read_dir(dir.path().join("annotated"))?.count();
    assert_eq!(written, 4, "one annotated frame per processed frame");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_landmark_change_at_the_ground_station_reaches_the_running_edge() -> anyhow::Result<()> {
    use towernav_landmark_db::{Author, LandmarkDb};
    let dir = tempfile::tempdir()?;
    let db_path = dir.path().join("gs.sqlite");
    let crew = Author {
        by: "crew".into(),
        at_unix_s: 0,
    };
    let mut db = LandmarkDb::open(&db_path)?;
    db.upsert_all(&towernav_sim::World::paper_field().landmarks(), &crew)?;
    let towers_before = db.list()?.len() as u32;

    let endpoint = towernav_tests::loopback_endpoint();
    let gs = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
        ..Default::default()
    })
    .await?;
    let fleet = NodeId::new("lmtest")?;
    let service = tokio::spawn(towernav_ground_station::landmark_service::serve(
        gs.clone(),
        fleet.clone(),
        db_path.clone(),
    ));
    let status_key = Keys::new(fleet).all_uavs_of::<StatusHeartbeat>();
    let statuses = gs
        .declare_subscriber(status_key)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let loaded = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (beats_tx, mut beats_rx) = tokio::sync::watch::channel(0usize);
    let reader = tokio::spawn({
        let loaded = loaded.clone();
        async move {
            while let Ok(sample) = statuses.recv_async().await {
                if let Ok(s) = decode::<StatusHeartbeat>(&sample.payload().to_bytes()) {
                    loaded
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push(s.landmarks_loaded);
                    beats_tx.send_modify(|n| *n += 1);
                }
            }
        }
    });

    let mut config = oracle_config("lmtest", &endpoint, 150);
    config.source.speed = Some(1.0);
    config.output.preview_hz = 0.0;
    config.landmarks.replica = Some(dir.path().join("replica.json"));
    let edge =
        tokio::spawn(
            async move { run_edge(&config, None, Arc::new(AtomicBool::new(false))).await },
        );
    // Mid-flight (the edge has reported in), the survey crew removes two towers far from the flight.
    tokio::time::timeout(Duration::from_secs(20), beats_rx.wait_for(|n| *n >= 1)).await??;
    db.remove("D4", &crew)?;
    db.remove("C4", &crew)?;
    let summary = edge.await??;
    service.abort();
    reader.abort();

    let loaded = loaded.lock().unwrap_or_else(|e| e.into_inner()).clone();
    assert_eq!(loaded.first(), Some(&towers_before), "status: {loaded:?}");
    assert_eq!(
        loaded.last(),
        Some(&(towers_before - 2)),
        "status: {loaded:?}"
    );
    assert!(
        summary.record.poses_published > 100,
        "kept localizing through the change: {} poses",
        summary.record.poses_published
    );
    Ok(())
}

/// Four white 128x64 frames, a level attitude log and the paper's towers (types
/// A-D) in `dir`; the daemon's config reads them with the stand-in `model`.
fn frames_and_towers(dir: &std::path::Path, model: &str) -> anyhow::Result<EdgeConfig> {
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames)?;
    for i in 0..4 {
        image::RgbImage::from_pixel(128, 64, image::Rgb([255, 255, 255]))
            .save(frames.join(format!("f{i}.png")))?;
    }
    std::fs::write(
        dir.join("att.csv"),
        "time_s,roll_deg,pitch_deg,heading_deg\n0,0,0,90\n10,0,0,90\n",
    )?;
    let world = Scenario::paper(1).world;
    let towers = dir.join("towers.csv");
    towernav_landmark_db::export_csv(&world.landmarks(), std::fs::File::create(&towers)?)?;
    let mut c = EdgeConfig {
        fleet: "types".into(),
        ..EdgeConfig::default()
    };
    c.zenoh.listen = vec![towernav_tests::loopback_endpoint()];
    c.source.kind = SourceKind::Images;
    c.source.path = Some(frames.display().to_string());
    c.source.width = 128;
    c.source.height = 64;
    c.source.speed = Some(0.0);
    c.attitude.kind = AttitudeKind::Csv;
    c.attitude.path = Some(dir.join("att.csv"));
    c.detector.model = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(model);
    c.detector.classify_types = false;
    c.landmarks.file = Some(towers);
    c.pipeline.takeoff = Some([world.datum.origin.lat_deg, world.datum.origin.lon_deg, 30.0]);
    Ok(c)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_one_class_model_flies_over_any_typed_database() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let c = frames_and_towers(dir.path(), "fake-v8-tower.onnx")?;
    let summary = run_edge(&c, None, Arc::new(AtomicBool::new(false))).await?;
    assert_eq!(summary.record.frames, 4, "every frame went through");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_model_without_the_databases_types_is_refused_naming_both() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let c = frames_and_towers(dir.path(), "fake-v8-lattice.onnx")?;
    let Err(err) = run_edge(&c, None, Arc::new(AtomicBool::new(false))).await else {
        panic!("A-D towers and a lattice/tubular model: the daemon should refuse");
    };
    let text = format!("{err:#}");
    for needle in [
        "fake-v8-lattice.onnx",
        "\"A\"",
        "\"D\"",
        "\"lattice\"",
        "\"tubular\"",
    ] {
        assert!(text.contains(needle), "{needle} missing from: {text}");
    }
    Ok(())
}
