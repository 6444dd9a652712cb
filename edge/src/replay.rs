//! A recorded flight through the pipeline, every frame, as the paper
//! validated its method: the camera's video or images, the autopilot's flight
//! log for attitude, the calibration and the landmarks. No Zenoh, no MAVLink,
//! no pacing. The log's GNSS may place the start (the take-off point a UAV
//! knows before GNSS is lost); after that the estimator never sees it, and
//! the scoring (`towernav-eval`'s `gnss_score`) compares against it.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use nalgebra::{Matrix2, Point2, Point3};
use towernav_core::LandmarkMap;
use towernav_core::wire::{pose_estimate, pose_method};
use towernav_flightlog::{FlightLog, GnssSample};
use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{DetectionFrame, NodeId, PoseEstimate, TowerType};

use crate::daemon::attitude::AttitudeSource;
use crate::daemon::config::{AttitudeKind, EdgeConfig, SourceKind};
use crate::daemon::source::{FrameSource, image_size, video_size};
use crate::edge_cmd::{check_log_covers, load_detector, open_attitude, open_source, pipeline_for};

/// One published estimate of the replay, with its time on the log's clock.
#[derive(Debug, Clone)]
pub struct ReplayedPose {
    pub pose: PoseEstimate,
    pub log_time_s: f64,
    /// Horizontal covariance (east, north), m^2.
    pub covariance_en: Matrix2<f64>,
}

impl ReplayedPose {
    pub fn east_north(&self) -> Point2<f64> {
        Point2::new(self.pose.east_m, self.pose.north_m)
    }
}

/// What a replay did.
#[derive(Debug, Clone)]
pub struct ReplayRun {
    pub frames: u64,
    /// Frames the log had no attitude for, or the detector failed on.
    pub skipped: u64,
    pub poses: Vec<ReplayedPose>,
    pub datum: Datum,
    /// Where the start came from, for the report.
    pub start: String,
    /// The log's GNSS, the reference; never given to the estimator.
    pub gnss: Vec<GnssSample>,
    pub wall_seconds: f64,
    pub detect_seconds: f64,
}

/// The frames' size as recorded: a replay's calibration must match it, not
/// a size the frames are scaled to.
fn recorded_size(config: &EdgeConfig) -> anyhow::Result<(u32, u32)> {
    let path = config.source.path.as_deref().unwrap_or_default();
    match config.source.kind {
        SourceKind::Video => Ok(video_size(path)?),
        SourceKind::Images => Ok(image_size(Path::new(path))?),
        other => anyhow::bail!("a replay reads a video or an image folder, not a {other:?} source"),
    }
}

/// A recording opened with its flight log: the config with the frames'
/// recorded size, the frame source, the log, and the camera-to-log offset.
/// Frames the log does not cover are refused here.
pub(crate) struct Recording {
    pub config: EdgeConfig,
    pub source: Box<dyn FrameSource>,
    pub log: FlightLog,
    pub offset_s: f64,
}

impl Recording {
    pub(crate) fn open(config: &EdgeConfig) -> anyhow::Result<Self> {
        anyhow::ensure!(
            matches!(config.attitude.kind, AttitudeKind::Log | AttitudeKind::Csv)
                && config.attitude.path.is_some(),
            "a recording needs its flight log (--log; a GoPro video with GPMF telemetry is its own, this one has none)"
        );
        let mut config = config.clone();
        let (width, height) = recorded_size(&config)?;
        config.source.width = width;
        config.source.height = height;
        let source = open_source(&config)?;
        let attitude = open_attitude(&config.attitude, None)?;
        check_log_covers(source.as_ref(), &attitude, &config.attitude)?;
        let AttitudeSource::Log { log, offset_s } = attitude else {
            anyhow::bail!(
                "a recording needs its flight log (--log; a GoPro video with GPMF telemetry is its own, this one has none)"
            );
        };
        Ok(Self {
            config,
            source,
            log,
            offset_s,
        })
    }
}

/// The start: `pipeline.takeoff`, else the log's GNSS at the first frame,
/// its height above mean sea level turned into the ellipsoid's.
fn start_of(
    config: &EdgeConfig,
    log: &FlightLog,
    first_log_s: f64,
) -> anyhow::Result<([f64; 3], String)> {
    if let Some(takeoff) = config.pipeline.takeoff {
        return Ok((takeoff, "pipeline.takeoff".into()));
    }
    let fix = log
        .gnss
        .iter()
        .min_by(|a, b| (a.time_s - first_log_s).abs().total_cmp(&(b.time_s - first_log_s).abs()))
        .filter(|f| (f.time_s - first_log_s).abs() <= 2.0)
        .with_context(|| {
            format!(
                "the log has no GNSS fix within 2 s of the first frame ({first_log_s:.3} s on its clock); \
                 give the start with --takeoff lat,lon,alt"
            )
        })?;
    let at = fix
        .geodetic()
        .with_context(|| format!("the log's GNSS fix at {:.3} s is not a place", fix.time_s))?;
    Ok((
        [at.lat_deg, at.lon_deg, at.height_m],
        format!("the log's GNSS fix at {:.3} s", fix.time_s),
    ))
}

/// Replays the recording `config` names (source, attitude log, camera,
/// landmarks, detector) through the pipeline. `progress` gets each frame's
/// sequence number and the recording's frame count when known.
pub fn replay(
    config: &EdgeConfig,
    mut progress: impl FnMut(u64, Option<u64>),
) -> anyhow::Result<ReplayRun> {
    let Recording {
        mut config,
        source,
        log,
        offset_s,
    } = Recording::open(config)?;
    let (width, height) = (config.source.width, config.source.height);
    let first_s = source.span_s().map_or(0.0, |s| s.0);
    let (takeoff, start) = start_of(&config, &log, first_s + offset_s)?;
    config.pipeline.takeoff = Some(takeoff);
    config.validate()?;

    let camera = config.camera.camera(width, height)?;
    let datum = Datum::new(Geodetic::new(takeoff[0], takeoff[1], takeoff[2])?);
    let landmarks = config
        .landmarks
        .file
        .as_deref()
        .context("a replay needs the landmarks (--landmarks)")?;
    let records = towernav_landmark_db::load_towers(landmarks)?;
    let (detector, detector_name) = load_detector(&config.detector)?;
    let mut detector = detector.context("a replay needs the YOLO detector")?;
    let classes: Vec<TowerType> = detector.classes().to_vec();
    let types = towernav_core::match_types(&classes, &records).with_context(|| {
        format!(
            "the detector {} cannot tell the landmarks' types apart",
            config.detector.model.display()
        )
    })?;
    let map = LandmarkMap::from_records(&records, &datum).matched(types);
    let (mut pipeline, method) = pipeline_for(&config, camera, Point3::origin(), map)?;
    let method = pose_method(method, config.pipeline.filter);
    let uav = NodeId::new(config.uav.clone())?;
    tracing::info!(
        source = %source.describe(),
        detector = %detector_name,
        %start,
        offset_s,
        "replaying"
    );

    // The barometer's climb since the first frame: the start is where the
    // first frame was taken (the pipeline's origin), so its reading then is the zero.
    let baro_zero = log.barometer_at(first_s + offset_s);
    if baro_zero.is_none() {
        tracing::info!(
            "the log has no barometer at the first frame: the paper's method reports its height as unknown"
        );
    }
    let started = Instant::now();
    let mut run = ReplayRun {
        frames: 0,
        skipped: 0,
        poses: Vec::new(),
        datum,
        start,
        gnss: log.gnss.clone(),
        wall_seconds: 0.0,
        detect_seconds: 0.0,
    };
    let max_frames = config.source.max_frames.unwrap_or(u64::MAX);
    let mut source: Box<dyn FrameSource> = source;
    let total = source.frame_count();
    while run.frames < max_frames {
        let Some(frame) = source.next_frame() else {
            break;
        };
        let frame = frame?;
        run.frames += 1;
        progress(frame.seq, total);
        let log_time_s = frame.time_s + offset_s;
        let (Some(attitude), Some(image)) = (log.attitude_at(log_time_s), frame.image.as_ref())
        else {
            run.skipped += 1;
            continue;
        };
        let t0 = Instant::now();
        let detections = match detector.detect(image, frame.seq) {
            Ok(d) => d,
            Err(e) => {
                tracing::warn!(seq = frame.seq, error = %e, "detector failed; frame skipped");
                run.skipped += 1;
                continue;
            }
        };
        run.detect_seconds += t0.elapsed().as_secs_f64();
        if let (Some(zero), Some(now)) = (baro_zero, log.barometer_at(log_time_s)) {
            pipeline.barometric_height(frame.time_s, now - zero);
        }
        let out = pipeline.process(&DetectionFrame {
            seq: frame.seq,
            time_s: frame.time_s,
            imu_attitude: attitude,
            detections,
        });
        if let Some(estimate) = &out.estimate {
            let c = &estimate.covariance;
            run.poses.push(ReplayedPose {
                pose: pose_estimate(&uav, &out, estimate, method, &datum),
                log_time_s,
                covariance_en: Matrix2::new(c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]),
            });
        }
    }
    run.wall_seconds = started.elapsed().as_secs_f64();
    Ok(run)
}
