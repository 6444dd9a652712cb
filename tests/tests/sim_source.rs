//! The simulator as the edge's frame source over any world (a random one, or
//! one built from a landmark file) along any plan file, and the replay
//! configs that `towernav-sim flight` writes.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use towernav_edge::daemon::config::{DetectorKind, EdgeConfig, Pacing, SourceKind};
use towernav_edge::daemon::run::RunSummary;
use towernav_edge::demo::sim_scenario;
use towernav_edge::edge_cmd::run_edge;
use towernav_protocol::PoseEstimate;
use towernav_sim::replay::{ReplaySource, ReplayWorld};
use towernav_sim::waypoints::{FlightPlan, along_longest_line};
use towernav_sim::world::WorldParams;
use towernav_sim::{Scenario, World};

/// Runs `config` with nobody listening; returns the summary, every published
/// pose, and the scenario the config flies (its truth).
async fn fly(
    mut config: EdgeConfig,
    dir: &Path,
) -> anyhow::Result<(RunSummary, Vec<PoseEstimate>, Scenario)> {
    config.zenoh.listen = vec![towernav_tests::loopback_endpoint()];
    config.zenoh.connect = vec![];
    let jsonl = dir.join("poses.jsonl");
    config.output.jsonl = Some(jsonl.clone());
    config.output.preview_hz = 0.0;
    let summary = run_edge(&config, None, Arc::new(AtomicBool::new(false))).await?;
    let poses = std::fs::read_to_string(&jsonl)?
        .lines()
        .map(serde_json::from_str)
        .collect::<Result<Vec<PoseEstimate>, _>>()?;
    Ok((summary, poses, sim_scenario(&config.source)?))
}

/// Horizontal RMS error of `poses` against the scenario's truth, by frame.
fn rms_m(scenario: &Scenario, poses: &[PoseEstimate]) -> f64 {
    let sq: f64 = poses
        .iter()
        .map(|p| {
            let t = scenario.truth(p.seq).pose.position_in_world;
            let (e, n) = (t.x, t.y);
            (p.east_m - e).powi(2) + (p.north_m - n).powi(2)
        })
        .sum();
    (sq / poses.len().max(1) as f64).sqrt()
}

fn write_plan(plan: &FlightPlan, path: &Path) -> anyhow::Result<()> {
    std::fs::write(path, toml::to_string(plan)?)?;
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_oracle_flies_a_random_world_along_a_plan_file() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let world = World::random(5, &WorldParams::default());
    let plan_path = dir.path().join("survey.toml");
    write_plan(&along_longest_line(&world).expect("a line"), &plan_path)?;
    let mut config = EdgeConfig::default();
    config.source.random_world = Some(5);
    config.source.flight = Some(plan_path.display().to_string());
    config.source.max_frames = Some(450);
    config.source.speed = Some(0.0);
    config.detector.kind = DetectorKind::Oracle;
    let (summary, poses, flown) = fly(config, dir.path()).await?;
    assert_eq!(summary.record.frames, 450);
    assert_eq!(summary.dropped, 0);
    assert!(poses.len() > 300, "{} poses", poses.len());
    // Towers of the random world, not the paper's field, were used.
    assert!(
        poses
            .iter()
            .any(|p| p.towers_used.iter().any(|t| t.starts_with('L')))
    );
    let rms = rms_m(&flown, &poses);
    assert!(rms < 5.0, "RMS {rms:.2} m over a random world");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_oracle_flies_over_towers_from_a_landmark_file() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    // A user's line: a random world's towers, as their survey would list them.
    let towers = dir.path().join("my-line.csv");
    let records = World::random(9, &WorldParams::default()).landmarks();
    towernav_landmark_db::export_csv(&records, std::fs::File::create(&towers)?)?;
    let mut config = EdgeConfig::default();
    config.source.world = Some(towers);
    config.source.max_frames = Some(300);
    config.source.speed = Some(0.0);
    config.detector.kind = DetectorKind::Oracle;
    // No flight given: a pass along the longest line.
    let (summary, poses, flown) = fly(config, dir.path()).await?;
    assert_eq!(summary.record.frames, 300);
    assert!(poses.len() > 150, "{} poses", poses.len());
    let rms = rms_m(&flown, &poses);
    assert!(rms < 5.0, "RMS {rms:.2} m over the file's towers");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flight_written_without_images_replays_with_the_oracle() -> anyhow::Result<()> {
    // What `towernav-sim flight --random-world 5 --plan survey.toml` writes
    // beside its files (sim/tests/cli.rs checks that the binary writes it).
    let dir = tempfile::tempdir()?;
    let world = World::random(5, &WorldParams::default());
    let plan = along_longest_line(&world).expect("a line");
    let plan_path = dir.path().join("survey.toml");
    write_plan(&plan, &plan_path)?;
    let scenario = Scenario::flying(world, &plan, 3);
    let towers = dir.path().join("towers.csv");
    towernav_landmark_db::export_csv(&scenario.world.landmarks(), std::fs::File::create(&towers)?)?;
    let replay = ReplaySource::Oracle {
        world: ReplayWorld::Random(5),
        flight: plan_path.display().to_string(),
    };
    let config_path = dir.path().join("replay.toml");
    std::fs::write(
        &config_path,
        replay.config_toml(&scenario, &config_path, &towers),
    )?;
    let mut config = EdgeConfig::read(&config_path)?;
    assert_eq!(config.source.kind, SourceKind::Sim);
    assert_eq!(config.detector.kind, DetectorKind::Oracle);
    config.source.max_frames = Some(240);
    // Every frame, not paced: on a busy machine a paced replay drops frames.
    config.source.speed = Some(0.0);
    let (summary, poses, flown) = fly(config, dir.path()).await?;
    assert_eq!(summary.record.frames, 240);
    // The same flight: the replay's truth is the scenario's.
    let flown_truth = flown.truth(100).pose.position_in_world;
    let truth = scenario.truth(100).pose.position_in_world;
    assert!(
        (flown_truth - truth).norm() < 1e-6,
        "{flown_truth} != {truth}"
    );
    assert!(rms_m(&flown, &poses) < 5.0);
    Ok(())
}

#[test]
fn a_camera_replay_processes_every_frame_unless_told_to_pace() -> anyhow::Result<()> {
    let scenario = Scenario::paper(1);
    let replay = ReplaySource::Camera {
        images: "/flight/mot/straight/img1".into(),
        attitude_log: "/flight/attitude.csv".into(),
        calibration: None,
    };
    let text = replay.config_toml(
        &scenario,
        Path::new("/flight/replay.toml"),
        Path::new("/flight/towers.csv"),
    );
    let config = EdgeConfig::parse(&text).map_err(anyhow::Error::msg)?;
    config.validate()?;
    assert_eq!(config.source.kind, SourceKind::Images);
    assert_eq!(config.source.pacing(), Pacing::EveryFrame);
    Ok(())
}
