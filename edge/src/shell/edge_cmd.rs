//! `towernav-edge run` and `demo`: build the daemon from a validated config
//! and run it until the source ends or SIGINT/SIGTERM; the demo also listens
//! on loopback like a ground station and ends with the report and plots.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use nalgebra::{Point3, Vector3};
use towernav_geometry::{Datum, Geodetic, Intrinsics, PinholeCamera};
use towernav_protocol::NodeId;
use towernav_protocol::session::Endpoints;
use towernav_sim::waypoints::{FlightPlan, PlanSource, along_longest_line};
use towernav_sim::{Scenario, World};

use super::collector::{PoseCollector, wait_for_peer};
use super::daemon::attitude::{AttitudeLog, AttitudeSource, MavlinkAttitude};
use super::daemon::config::{AttitudeKind, DetectorKind, EdgeConfig, SourceKind, SourceSection};
use super::daemon::mavlink_out::MavlinkOut;
use super::daemon::run::{RunOptions, RunSummary, drop_advice, dropped_share, percentiles, run};
use super::daemon::source::{FfmpegSource, FrameSource, ImageFolderSource, SimRender, SimSource};
use super::daemon::worker::Worker;
use super::demo_plots;
use super::landmark_sync::LandmarkSync;
use super::node::{EdgeNode, open_session, open_session_as};
use super::progress::bar;
use super::yolo::{DetectorOptions, YoloDetector};
use crate::detector::PostprocessParams;
use crate::landmarks::LandmarkMap;
use crate::localizer::Method;
use crate::pipeline::{Pipeline, PipelineConfig};
use crate::report::FlightReport;
use crate::wire::pose_method;

/// Where the simulated take-off is assumed, off the true one (metres east, north).
const SIM_TAKEOFF_ERROR_M: (f64, f64) = (3.0, -4.0);

/// Run the daemon as `config` says until the source ends or `stop` is set.
/// With `demo`, listen on loopback like a ground station and end with the
/// report and plots in that folder.
pub async fn run_edge(
    config: &EdgeConfig,
    demo: Option<&Path>,
    stop: Arc<AtomicBool>,
) -> anyhow::Result<RunSummary> {
    config.validate()?;
    let fleet = NodeId::new(config.fleet.clone())?;
    let uav = NodeId::new(config.uav.clone())?;
    let scenario = match config.source.kind {
        SourceKind::Sim => Some(Arc::new(sim_scenario(&config.source)?)),
        _ => None,
    };
    let (camera, datum, takeoff_in_world) = match (&scenario, config.pipeline.takeoff) {
        (Some(s), _) => (
            s.camera,
            s.world.datum,
            s.start_in_world() + Vector3::new(SIM_TAKEOFF_ERROR_M.0, SIM_TAKEOFF_ERROR_M.1, 0.0),
        ),
        (None, Some([lat, lon, alt])) => (
            PinholeCamera {
                intrinsics: Intrinsics::from_hfov(
                    config.source.width,
                    config.source.height,
                    config.camera.hfov_deg,
                ),
                ..PinholeCamera::default_hd()
            },
            Datum::new(Geodetic::new(lat, lon, alt)?),
            Point3::origin(),
        ),
        (None, None) => anyhow::bail!("pipeline.takeoff is needed for a real source"),
    };

    let endpoints = Endpoints {
        listen: config.zenoh.listen.clone(),
        connect: config.zenoh.connect.clone(),
    };
    let session = open_session_as(&endpoints, config.zenoh.mode).await?;
    if !config.zenoh.connect.is_empty()
        && wait_for_peer(&session, Duration::from_secs(5))
            .await
            .is_err()
    {
        tracing::warn!(connect = ?config.zenoh.connect, "no peer or router reachable yet; localizing anyway");
    }
    let mut sync = match &config.landmarks.replica {
        Some(path) => {
            // Zenoh retries links every few seconds: give the ground station a moment to reach us.
            if wait_for_peer(&session, Duration::from_secs(6))
                .await
                .is_err()
            {
                tracing::warn!("no peer yet; asking for landmarks anyway");
            }
            let (sync, source) = LandmarkSync::start(
                &session,
                fleet.clone(),
                path.clone(),
                Duration::from_secs(3),
            )
            .await?;
            println!(
                "landmarks: {} towers at revision {} ({source:?})",
                sync.replica().len(),
                sync.replica().revision
            );
            Some(sync)
        }
        None => None,
    };
    let records = match (&sync, &config.landmarks.file, &scenario) {
        (Some(sync), _, _) => sync.replica().records(),
        (None, Some(path), _) => towernav_landmark_db::load_towers(path)?,
        (None, None, Some(s)) => s.world.landmarks(),
        (None, None, None) => {
            anyhow::bail!("a real source needs landmarks: set landmarks.file or landmarks.replica")
        }
    };
    let map = LandmarkMap::from_records(&records, &datum);
    let node = EdgeNode::new(session, fleet.clone(), uav.clone()).await?;

    let listener = match demo {
        Some(_) => {
            let connect = config
                .zenoh
                .listen
                .first()
                .cloned()
                .context("the demo needs a zenoh.listen endpoint to listen on")?;
            let session = open_session(&Endpoints {
                listen: vec![],
                connect: vec![connect],
            })
            .await?;
            let collector = PoseCollector::start(&session, fleet.clone()).await?;
            wait_for_peer(&session, Duration::from_secs(10)).await?;
            Some((session, collector))
        }
        None => None,
    };

    let (detector, detector_name) = match config.detector.kind {
        DetectorKind::Oracle => (None, "oracle".to_string()),
        DetectorKind::Yolo => {
            let options = DetectorOptions {
                threads: config.detector.threads,
                cuda: config.detector.cuda,
                post: PostprocessParams {
                    min_score: config.detector.min_score,
                    detector_type_weight: config.detector.detector_type_weight,
                    ..PostprocessParams::default()
                },
            };
            let yolo = YoloDetector::load_with_types(
                &config.detector.model,
                config.detector.type_model(),
                &options,
            )
            .context(
                "loading the detector (`cargo xtask setup-ort` installs ONNX Runtime; \
                 `--no-type-model` runs without the type classifier; \
                 `--detector oracle` flies the simulator without either)",
            )?;
            let name = config
                .detector
                .model
                .file_name()
                .map_or_else(|| "yolo".into(), |n| n.to_string_lossy().into_owned());
            (Some(yolo), name)
        }
    };
    let source: Box<dyn FrameSource> = match (config.source.kind, &scenario) {
        (SourceKind::Sim, Some(s)) => Box::new(SimSource::new(
            s.clone(),
            match config.detector.kind {
                DetectorKind::Yolo => SimRender::Detector,
                // Render just the frames the preview will show.
                DetectorKind::Oracle if config.output.preview_hz > 0.0 => SimRender::PreviewEvery(
                    (s.fps / config.output.preview_hz).round().max(1.0) as u64,
                ),
                DetectorKind::Oracle => SimRender::Never,
            },
            config.source.max_frames,
        )),
        (SourceKind::Images, _) => Box::new(ImageFolderSource::open(
            Path::new(config.source.path.as_deref().unwrap_or_default()),
            config.source.fps,
        )?),
        (_, _) => Box::new(FfmpegSource::open(
            config.source.path.as_deref().unwrap_or_default(),
            config.source.width,
            config.source.height,
            config.source.fps,
        )?),
    };
    let attitude = match config.attitude.kind {
        AttitudeKind::Source => AttitudeSource::Frames,
        AttitudeKind::Csv => AttitudeSource::Log(AttitudeLog::read(
            config.attitude.path.as_deref().unwrap_or(Path::new("")),
        )?),
        AttitudeKind::Mavlink => {
            AttitudeSource::Mavlink(MavlinkAttitude::listen(&config.attitude.address)?)
        }
    };
    let method = if config.pipeline.method == "seed" {
        Method::Seed
    } else {
        Method::Rays
    };
    let mut pipeline_config = PipelineConfig::new(camera, takeoff_in_world);
    pipeline_config.method = method;
    if !config.pipeline.filter {
        pipeline_config.filter = None;
    }
    if let Some(dir) = &config.output.annotated {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let worker = Worker {
        uav: uav.clone(),
        datum,
        method: pose_method(method, config.pipeline.filter),
        pipeline: Pipeline::new(pipeline_config, map),
        detector,
        attitude,
        preview_every: (config.output.preview_hz > 0.0)
            .then(|| Duration::from_secs_f64(1.0 / config.output.preview_hz)),
        annotate_dir: config.output.annotated.clone(),
        scenario: scenario.clone(),
    };
    let mavlink = if config.mavlink.enabled {
        Some(MavlinkOut::open(&config.mavlink)?)
    } else {
        None
    };
    let options = RunOptions {
        pacing: config.source.pacing(),
        queue: config.source.queue,
        detector_name,
        jsonl: config.output.jsonl.clone(),
        mavlink,
    };

    println!(
        "towernav edge: fleet {fleet} uav {uav} on {:?}",
        config.zenoh.listen
    );
    let endpoint = config
        .zenoh
        .listen
        .first()
        .map_or("tcp/127.0.0.1:7447", String::as_str);
    println!(
        "watch live: `cargo xtask gs` in another terminal, or `towernav-gs --db <towers.sqlite> --connect {endpoint}`"
    );
    let frames = scenario.as_ref().map_or(0, |s| {
        s.frame_count()
            .min(config.source.max_frames.unwrap_or(u64::MAX))
    });
    let progress = bar(frames, "frames");
    let mut summary = run(
        &node,
        source,
        worker,
        datum,
        options,
        sync.as_mut(),
        stop,
        |seq| progress.set_position(seq + 1),
    )
    .await?;
    progress.finish_and_clear();

    let mut latency = summary.latency_ms.clone();
    let (p50, p99) = percentiles(&mut latency);
    match (listener, demo, &scenario) {
        (Some((_session, collector)), Some(out), Some(scenario)) => {
            let received = collector
                .drain(
                    summary.record.poses_published as usize,
                    Duration::from_secs(3),
                )
                .await;
            if collector.rejected() > 0 {
                println!("warning: {} poses did not decode", collector.rejected());
            }
            let report = FlightReport::new(&summary.record, &received, scenario.fps);
            println!(
                "\ntowernav demo report ({}, {} towers, seed {})\n{report}",
                world_name(&config.source),
                scenario.world.towers.len(),
                config.source.seed
            );
            println!(
                "latency            frame to publish p50 {p50:.1} ms, p99 {p99:.1} ms; {} frames dropped by the queue, {} failed",
                summary.dropped, summary.failed
            );
            println!(
                "throughput         {:.1} frames/s over {:.1} s; peak RSS {}",
                summary.record.frames as f64 / summary.record.wall_seconds.max(1e-9),
                summary.record.wall_seconds,
                peak_rss_mb().map_or_else(|| "unknown".into(), |mb| format!("{mb:.0} MB"))
            );
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            let (trajectory, errors) =
                demo_plots::write(out, &summary.record, &received, scenario.fps)?;
            println!(
                "plots              {} and {}",
                trajectory.display(),
                errors.display()
            );
        }
        _ => println!(
            "flew {} frames, published {} poses; {:.1} frames/s; latency p50 {p50:.1} ms, p99 {p99:.1} ms; {} dropped, {} failed; peak RSS {}",
            summary.record.frames,
            summary.record.poses_published,
            summary.record.frames as f64 / summary.record.wall_seconds.max(1e-9),
            summary.dropped,
            summary.failed,
            peak_rss_mb().map_or_else(|| "unknown".into(), |mb| format!("{mb:.0} MB"))
        ),
    }
    if let Some(share) = dropped_share(summary.dropped, summary.record.frames) {
        println!("warning: {}", drop_advice(share, config.source.pacing()));
    }
    summary.latency_ms = latency;
    Ok(summary)
}

/// The simulated flight `source` asks for: its world (the seed's field, a
/// random one, or one built from a landmark file) and its flight (a preset, a
/// plan file, or by default the skeleton's level flight over the seed's field
/// and a pass along the longest line over any other world).
pub fn sim_scenario(source: &SourceSection) -> anyhow::Result<Scenario> {
    let world = World::chosen(
        source.world.as_deref(),
        source.random_world,
        towernav_landmark_db::load_towers,
    )?;
    let seed = source.seed;
    let plan = match &source.flight {
        Some(flight) => match PlanSource::parse(flight) {
            PlanSource::Preset(name) => FlightPlan::preset(&name)?,
            PlanSource::File(path) => {
                let text = std::fs::read_to_string(&path).with_context(|| {
                    format!(
                        "reading the flight plan {} (not a preset either: {})",
                        path.display(),
                        towernav_sim::waypoints::PRESETS.map(|(n, _)| n).join(", ")
                    )
                })?;
                FlightPlan::parse(&text, &path.display().to_string())?
            }
        },
        None if source.world.is_none() && source.random_world.is_none() => {
            return Ok(Scenario::seed(seed));
        }
        None => along_longest_line(&world)
            .context("the world has no line of two towers to fly along; give source.flight")?,
    };
    Ok(Scenario::flying(world, &plan, seed))
}

/// The process's peak resident set/// The world a simulated source flies over, for the report.
fn world_name(source: &SourceSection) -> String {
    match (&source.world, source.random_world) {
        (Some(path), _) => format!("towers of {}", path.display()),
        (None, Some(seed)) => format!("random world {seed}"),
        (None, None) => "seed field".into(),
    }
}

/// The process's peak resident set (VmHWM), from /proc on Linux.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// SIGINT or SIGTERM: stop taking frames; what is queued is finished and published.
pub fn spawn_signal_watch(stop: Arc<AtomicBool>) {
    tokio::spawn(async move {
        let terminate = async {
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(mut s) => {
                    s.recv().await;
                }
                Err(e) => {
                    tracing::warn!(error = %e, "SIGTERM cannot be watched");
                    std::future::pending::<()>().await;
                }
            }
        };
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            _ = terminate => {}
        }
        tracing::info!("signal received: finishing the queued frames and stopping");
        stop.store(true, Ordering::Relaxed);
    });
}
