//! `towernav-edge run` and `demo`: build the daemon from a validated config
//! and run it until the source ends or SIGINT/SIGTERM; the demo also listens
//! on loopback like a ground station and ends with the report and plots.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use nalgebra::Point3;
use towernav_core::autopilot_link::AutopilotLink;
use towernav_core::daemon::{DaemonConfig, DaemonCore, FrameObserver};
use towernav_core::detector::PostprocessParams;
use towernav_core::localizer::Method;
use towernav_core::pipeline::{Pipeline, PipelineConfig};
use towernav_core::ros_link::RosLink;
use towernav_core::wire::pose_method;
use towernav_core::{LandmarkMap, TypeMatch, match_types};
use towernav_geometry::{Datum, Geodetic, PinholeCamera};
use towernav_onnx::{DetectorOptions, YoloDetector};
use towernav_protocol::security::Credentials;
use towernav_protocol::session::Endpoints;
use towernav_protocol::{LandmarkRecord, NodeId, TowerType};
use zenoh::Session;

#[cfg(feature = "demo")]
pub use crate::demo::Sim;
#[cfg(not(feature = "demo"))]
pub use crate::no_sim::Sim;

use crate::daemon::attitude::{AttitudeSource, MavlinkAttitude};
use crate::daemon::config::{
    AttitudeKind, AttitudeSection, DetectorKind, DetectorSection, EdgeConfig, SourceKind,
};
use crate::daemon::mavlink_out::MavlinkOut;
use crate::daemon::ros2_out::{OnboardBus, Px4Attitude};
use crate::daemon::run::{Daemon, RunOptions, RunSummary, drop_advice, dropped_share};
use crate::daemon::source::{FfmpegSource, FirstFrames, FrameSource, ImageFolderSource};
use crate::daemon::worker::Worker;
use crate::landmark_sync::LandmarkSync;
use crate::node::{EdgeNode, open_session_as, wait_for_peer};
pub use crate::peak_rss::peak_rss_mb;

/// Run the daemon as `config` says until the source ends or `stop` is set.
/// With `demo` (demo build), listen on loopback like a ground station and end
/// with the report and plots in that folder.
pub async fn run_edge(
    config: &EdgeConfig,
    demo: Option<&Path>,
    stop: Arc<AtomicBool>,
) -> anyhow::Result<RunSummary> {
    config.validate()?;
    let fleet = NodeId::new(config.fleet.clone())?;
    let uav = NodeId::new(config.uav.clone())?;
    let sim = match config.source.kind {
        SourceKind::Sim => Some(Sim::from_config(&config.source)?),
        _ => None,
    };
    let (camera, datum, takeoff_in_world) = frame_of(config, sim.as_deref())?;
    let session = open_zenoh(config).await?;
    let mut sync = start_sync(&session, config, &fleet).await?;
    let records = landmark_records(config, sync.as_ref(), sim.as_deref())?;
    let (detector, detector_name) = load_detector(&config.detector)?;
    let classes: Option<Vec<TowerType>> = detector.as_ref().map(|d| d.classes().to_vec());
    let types = types_for(config, classes.as_deref(), &records)?;
    let map = LandmarkMap::from_records(&records, &datum).matched(types);
    let node = EdgeNode::new(session, fleet.clone(), uav.clone()).await?;

    #[cfg(feature = "demo")]
    let mut demo_run = match (demo, &sim) {
        (Some(out), Some(sim)) => {
            Some(crate::demo::DemoRun::start(config, &fleet, sim.clone(), out).await?)
        }
        _ => None,
    };
    #[cfg(not(feature = "demo"))]
    if demo.is_some() {
        anyhow::bail!("the demo needs the simulator: build towernav-edge with `--features demo`");
    }

    let source: Box<dyn FrameSource> = match &sim {
        Some(sim) => sim.source(config),
        None => open_source(config)?,
    };
    let onboard = OnboardBus::open(config).await?;
    let (onboard, px4_attitude) = onboard.unzip();
    let attitude = open_attitude(&config.attitude, px4_attitude)?;
    check_log_covers(source.as_ref(), &attitude, &config.attitude)?;
    let (pipeline, method) = pipeline_for(config, camera, takeoff_in_world, map)?;
    let core = DaemonCore::new(
        DaemonConfig {
            uav,
            datum,
            method: pose_method(method, config.pipeline.filter),
            detector: detector_name.clone(),
            preview_every: (config.output.preview_hz > 0.0)
                .then(|| Duration::from_secs_f64(1.0 / config.output.preview_hz)),
            session: run_session(),
        },
        pipeline,
        Instant::now(),
    );
    let core = match config.mavlink.enabled {
        true => core.with_autopilot(autopilot_link(config, datum)),
        false => core,
    };
    let core = match config.ros2.enabled || config.px4.enabled {
        true => core.with_ros(ros_link(config, datum)),
        false => core,
    };
    let mut options = run_options(config, detector_name, classes)?;
    options.onboard = onboard;
    print_banner(config, &fleet);

    #[cfg(feature = "demo")]
    let observer = demo_run
        .as_mut()
        .map(|d| &mut d.scorer as &mut dyn FrameObserver);
    #[cfg(not(feature = "demo"))]
    let observer: Option<&mut dyn FrameObserver> = None;
    let daemon = Daemon {
        node: &node,
        source,
        worker: Worker { detector, attitude },
        core,
        datum,
        options,
        sync: sync.as_mut(),
        observer,
        stop,
    };
    let frames = sim.as_ref().map_or(0, |s| {
        s.frame_count()
            .min(config.source.max_frames.unwrap_or(u64::MAX))
    });
    let summary = run_with_progress(daemon, frames).await?;

    #[cfg(feature = "demo")]
    if let Some(demo_run) = demo_run {
        demo_run.finish(config, &summary).await?;
        warn_drops(config, &summary);
        return Ok(summary);
    }
    print_closing_line(&summary);
    warn_drops(config, &summary);
    Ok(summary)
}

/// How the detector's classes meet the landmarks' types: refused when it
/// cannot tell them apart, by geometry alone for a one-class detector.
fn types_for(
    config: &EdgeConfig,
    classes: Option<&[TowerType]>,
    records: &[LandmarkRecord],
) -> anyhow::Result<TypeMatch> {
    let Some(classes) = classes else {
        return Ok(TypeMatch::Typed);
    };
    let types = match_types(classes, records).with_context(|| {
        format!(
            "the detector {} cannot tell the landmarks' types apart",
            config.detector.model.display()
        )
    })?;
    if let TypeMatch::Untyped(class) = types {
        tracing::info!(%class, "one-class detector: towers are bound by geometry alone");
    }
    Ok(types)
}

/// The bound on the published horizontal 1-sigma that ends a 2-D coast: the
/// filter's report bound carried through the covariance's scale. The link
/// grows the published covariance between estimates with the velocity's
/// spread, which is not scaled, so it draws the line a little before the
/// filter does, never after.
fn coast_max_sigma_m(config: &EdgeConfig) -> f64 {
    config.pipeline.max_report_sigma_m * config.covariance_scale().sqrt()
}

/// The core's MAVLink link, its clock set from this machine's until the
/// autopilot's SYSTEM_TIME says otherwise.
/// The ROS 2 / PX4 link, on the MAVLink link's rules of how long a fix is good.
fn ros_link(config: &EdgeConfig, datum: Datum) -> RosLink {
    let unix_now_us = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64);
    let accel_sigma = towernav_core::filter::FilterParams::default().accel_sigma_h;
    let rules = config
        .mavlink
        .link_config(accel_sigma, coast_max_sigma_m(config))
        .fix_rules();
    RosLink::new(
        config.ros2.link_config(&config.px4, rules),
        datum,
        Instant::now(),
        unix_now_us,
    )
}

fn autopilot_link(config: &EdgeConfig, datum: Datum) -> AutopilotLink {
    let unix_now_us = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64);
    let accel_sigma = towernav_core::filter::FilterParams::default().accel_sigma_h;
    AutopilotLink::new(
        config
            .mavlink
            .link_config(accel_sigma, coast_max_sigma_m(config)),
        datum,
        Instant::now(),
        unix_now_us,
    )
}

/// The pipeline the config asks for, and its method.
pub(crate) fn pipeline_for(
    config: &EdgeConfig,
    camera: PinholeCamera,
    takeoff_in_world: Point3<f64>,
    map: LandmarkMap,
) -> anyhow::Result<(Pipeline, Method)> {
    let method = Method::from_name(&config.pipeline.method)
        .with_context(|| format!("pipeline.method = {:?}", config.pipeline.method))?;
    let mut pipeline_config = PipelineConfig::new(camera, takeoff_in_world);
    pipeline_config.method = method;
    // A model's boxes stray further than the oracle's (the pipeline's default).
    if config.detector.kind == DetectorKind::Yolo {
        pipeline_config.localizer.edge_sigma_px = config.detector.edge_sigma_px;
        pipeline_config.localizer.edge_sigma_share = config.detector.edge_sigma_share;
        pipeline_config.localizer.cut_margin_share = config.detector.cut_margin_share;
        pipeline_config.localizer.cut_sigma_scale = config.detector.cut_sigma_scale;
    }
    if let Some(filter) = pipeline_config.filter.as_mut() {
        filter.max_report_sigma_m = config.pipeline.max_report_sigma_m;
        filter.report_covariance_scale = config.covariance_scale();
    }
    if !config.pipeline.filter {
        pipeline_config.filter = None;
    }
    Ok((Pipeline::new(pipeline_config, map), method))
}

/// The shell's side of the config: pacing, queue, logs, MAVLink, annotated frames.
fn run_options(
    config: &EdgeConfig,
    detector_name: String,
    classes: Option<Vec<TowerType>>,
) -> anyhow::Result<RunOptions> {
    if let Some(dir) = &config.output.annotated {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    Ok(RunOptions {
        pacing: config.source.pacing(),
        queue: config.source.queue,
        detector_name,
        jsonl: config.output.jsonl.clone(),
        autopilot_log: config.output.autopilot_log.clone(),
        mavlink: config
            .mavlink
            .enabled
            .then(|| MavlinkOut::open(&config.mavlink))
            .transpose()?,
        onboard: None,
        annotate_dir: config.output.annotated.clone(),
        classes,
    })
}

/// The daemon's run, with a progress bar over a simulated flight in the demo build.
async fn run_with_progress(daemon: Daemon<'_>, frames: u64) -> anyhow::Result<RunSummary> {
    #[cfg(feature = "demo")]
    {
        let progress = towernav_eval::progress::bar(frames, "frames");
        let summary = daemon.run(|seq| progress.set_position(seq + 1)).await?;
        progress.finish_and_clear();
        Ok(summary)
    }
    #[cfg(not(feature = "demo"))]
    {
        let _ = frames;
        Ok(daemon.run(|_| {}).await?)
    }
}

/// The camera, the mission's datum and the assumed take-off, from the
/// simulated flight or from the config of a real one.
fn frame_of(
    config: &EdgeConfig,
    sim: Option<&Sim>,
) -> anyhow::Result<(PinholeCamera, Datum, Point3<f64>)> {
    match (sim, config.pipeline.takeoff) {
        (Some(s), _) => Ok((s.camera(), s.datum(), s.takeoff_in_world())),
        (None, Some([lat, lon, alt])) => Ok((
            config
                .camera
                .camera(config.source.width, config.source.height)?,
            Datum::new(Geodetic::new(lat, lon, alt)?),
            Point3::origin(),
        )),
        (None, None) => anyhow::bail!("pipeline.takeoff is needed for a real source"),
    }
}

async fn open_zenoh(config: &EdgeConfig) -> anyhow::Result<Session> {
    let security = match &config.zenoh.credentials {
        Some(dir) => {
            let credentials = Credentials::load_edge(dir, &config.uav)?;
            tracing::info!(node = credentials.name(), credentials = %dir.display(), "zenoh: mutual TLS, fleet access rules");
            Some(credentials)
        }
        None => {
            tracing::info!(
                "zenoh: plain TCP, no credentials (loopback and tests only; see `towernav-fleet`)"
            );
            None
        }
    };
    let endpoints = Endpoints {
        listen: config.zenoh.listen.clone(),
        connect: config.zenoh.connect.clone(),
        security,
    };
    let session = open_session_as(&endpoints, config.zenoh.mode).await?;
    if !config.zenoh.connect.is_empty()
        && wait_for_peer(&session, Duration::from_secs(5))
            .await
            .is_err()
    {
        tracing::warn!(connect = ?config.zenoh.connect, "no peer or router reachable yet; localizing anyway");
    }
    Ok(session)
}

/// The landmark replica kept in step with the ground station, when asked for.
async fn start_sync(
    session: &Session,
    config: &EdgeConfig,
    fleet: &NodeId,
) -> anyhow::Result<Option<LandmarkSync>> {
    let Some(path) = &config.landmarks.replica else {
        return Ok(None);
    };
    // Zenoh retries links every few seconds: give the ground station a moment to reach us.
    if wait_for_peer(session, Duration::from_secs(6))
        .await
        .is_err()
    {
        tracing::warn!("no peer yet; asking for landmarks anyway");
    }
    let (sync, source) =
        LandmarkSync::start(session, fleet.clone(), path.clone(), Duration::from_secs(3)).await?;
    println!(
        "landmarks: {} towers at revision {} ({source:?})",
        sync.replica().len(),
        sync.replica().revision
    );
    Ok(Some(sync))
}

/// The towers to localize against: the replica, a file, or the simulated world's.
fn landmark_records(
    config: &EdgeConfig,
    sync: Option<&LandmarkSync>,
    sim: Option<&Sim>,
) -> anyhow::Result<Vec<LandmarkRecord>> {
    Ok(match (sync, &config.landmarks.file, sim) {
        (Some(sync), _, _) => sync.replica().records(),
        (None, Some(path), _) => towernav_landmark_db::load_towers(path)?,
        (None, None, Some(s)) => s.landmarks(),
        (None, None, None) => {
            anyhow::bail!("a real source needs landmarks: set landmarks.file or landmarks.replica")
        }
    })
}

/// The YOLO detector and its name for the status, or the oracle.
pub(crate) fn load_detector(
    section: &DetectorSection,
) -> anyhow::Result<(Option<YoloDetector>, String)> {
    match section.kind {
        DetectorKind::Oracle => Ok((None, "oracle".to_string())),
        DetectorKind::Yolo => {
            let options = DetectorOptions {
                threads: section.threads,
                cuda: section.cuda,
                post: PostprocessParams {
                    min_score: section.min_score,
                    detector_type_weight: section.detector_type_weight,
                    ..PostprocessParams::default()
                },
            };
            let yolo =
                YoloDetector::load_with_types(&section.model, section.type_model(), &options)
                    .context(
                        "loading the detector (`cargo xtask setup-ort` installs ONNX Runtime; \
                     `--no-type-model` runs without the type classifier; \
                     `--detector oracle` flies the simulator without either)",
                    )?;
            let name = section
                .model
                .file_name()
                .map_or_else(|| "yolo".into(), |n| n.to_string_lossy().into_owned());
            Ok((Some(yolo), name))
        }
    }
}

/// Refuses a recording whose frames the flight log does not cover (the
/// camera-to-log offset applied), saying by how much.
pub(crate) fn check_log_covers(
    source: &dyn FrameSource,
    attitude: &AttitudeSource,
    section: &AttitudeSection,
) -> anyhow::Result<()> {
    if let (AttitudeSource::Log { log, offset_s }, Some((first, last))) =
        (attitude, source.span_s())
    {
        let path = section.path.as_deref().unwrap_or(Path::new(""));
        log.check_covers(first + offset_s, last + offset_s)
            .map_err(|e| e.in_file(path))
            .with_context(|| {
                format!(
                    "frames {first:.3}-{last:.3} s on the camera's clock, attitude.time_offset_s = {offset_s}"
                )
            })?;
    }
    Ok(())
}

/// An image folder, or anything ffmpeg reads.
pub(crate) fn open_source(config: &EdgeConfig) -> anyhow::Result<Box<dyn FrameSource>> {
    let source = &config.source;
    let path = source.path.as_deref().unwrap_or_default();
    let opened: Box<dyn FrameSource> = match source.kind {
        SourceKind::Images => Box::new(ImageFolderSource::open(
            Path::new(path),
            source.fps,
            &source.frame_times(),
        )?),
        _ => Box::new(FfmpegSource::open(
            path,
            source.width,
            source.height,
            source.fps,
            &source.frame_times(),
        )?),
    };
    Ok(match source.max_frames {
        Some(limit) => Box::new(FirstFrames::new(opened, limit)),
        None => opened,
    })
}

pub(crate) fn open_attitude(
    section: &AttitudeSection,
    px4: Option<Px4Attitude>,
) -> anyhow::Result<AttitudeSource> {
    Ok(match section.kind {
        AttitudeKind::Source => AttitudeSource::Frames,
        AttitudeKind::Log | AttitudeKind::Csv => {
            let path = section.path.as_deref().unwrap_or(Path::new(""));
            let log = towernav_flightlog::FlightLog::read(path)?;
            let (start, end) = log.span();
            tracing::info!(
                path = %path.display(),
                start_s = start,
                end_s = end,
                fixes = log.gnss.len(),
                offset_s = section.time_offset_s,
                "attitude from a flight log"
            );
            AttitudeSource::Log {
                log,
                offset_s: section.time_offset_s,
            }
        }
        AttitudeKind::Mavlink => {
            AttitudeSource::Mavlink(MavlinkAttitude::listen(&section.address)?)
        }
        AttitudeKind::Px4 => AttitudeSource::Px4(px4.context(
            "attitude.kind = \"px4\" reads PX4 on the onboard Zenoh, which did not open",
        )?),
    })
}

fn print_banner(config: &EdgeConfig, fleet: &NodeId) {
    println!(
        "towernav edge: fleet {fleet} uav {} on {:?}",
        config.uav, config.zenoh.listen
    );
    let endpoint = config
        .zenoh
        .listen
        .first()
        .map_or("tcp/127.0.0.1:7447", String::as_str);
    println!(
        "watch live: `cargo xtask gs` in another terminal, or `towernav-gs --db <towers.sqlite> --connect {endpoint}`"
    );
}

fn print_closing_line(summary: &RunSummary) {
    let (p50, p99) = summary.latency_ms;
    println!(
        "flew {} frames, published {} poses; {:.1} frames/s; latency p50 {p50:.1} ms, p99 {p99:.1} ms; {} dropped, {} failed; peak RSS {}",
        summary.record.frames,
        summary.record.poses_published,
        summary.record.frames as f64 / summary.record.wall_seconds.max(1e-9),
        summary.dropped,
        summary.failed,
        peak_rss_mb().map_or_else(|| "unknown".into(), |mb| format!("{mb:.0} MB"))
    );
}

fn warn_drops(config: &EdgeConfig, summary: &RunSummary) {
    if let Some(share) = dropped_share(summary.dropped, summary.record.frames) {
        println!("warning: {}", drop_advice(share, config.source.pacing()));
    }
}

/// This run's number: its start in nanoseconds since the Unix epoch, so a
/// restarted edge (a new run) never takes a correction meant for the last.
fn run_session() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(1, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
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
