//! The imperative shell around `DaemonCore`: source thread -> drop-oldest
//! queue -> detector thread -> this loop. The loop waits on whichever comes
//! first (a detected frame, an operator's correction, a landmark change, the
//! core's timer), hands it to the core, and sends what the core returns:
//! Zenoh, MAVLink, the JSONL log, previews and annotated frames.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use image::RgbImage;
use image::codecs::jpeg::JpegEncoder;
use towernav_core::daemon::{
    Command, DaemonCore, DetectedFrame, FrameObserver, Output, SourceCounters,
};
use towernav_core::flight_record::FlightRecord;
use towernav_core::{LandmarkMap, TypeMatch, match_types};
use towernav_geometry::Datum;
use towernav_protocol::{IdCorrection, PoseEstimate, Preview, TowerType, TrackReport, TruthPose};
use zenoh::sample::Sample;

use super::config::Pacing;
use super::jsonl_log::JsonlLog;
use super::mavlink_out::{MavlinkOut, Received};
use super::queue::DropOldest;
use super::ros2_out::OnboardBus;
use super::source::{CapturedFrame, FrameSource};
use super::worker::{Detected, Worker, WorkerTotals};
use crate::ShellError;
use crate::landmark_sync::LandmarkSync;
use crate::node::EdgeNode;

/// How often the status goes to the log as one line (seconds of source time).
const STATUS_LOG_PERIOD_S: f64 = 60.0;

/// How the shell around the core behaves.
pub struct RunOptions {
    /// Every frame, at a multiple of the source's clock, or a live camera's pace.
    pub pacing: Pacing,
    pub queue: usize,
    /// The detector, for the report: "oracle" or the model's file name.
    pub detector_name: String,
    pub jsonl: Option<std::path::PathBuf>,
    /// The autopilot's GNSS positions, one JSON line each.
    pub autopilot_log: Option<std::path::PathBuf>,
    /// The autopilot link, and what the autopilot sends on it.
    pub mavlink: Option<(MavlinkOut, tokio::sync::mpsc::Receiver<Received>)>,
    /// ROS 2 topics and PX4 over the onboard Zenoh.
    pub onboard: Option<OnboardBus>,
    pub annotate_dir: Option<std::path::PathBuf>,
    /// The detector's classes, each new landmark set checked against them
    /// (`None`: the oracle, which reports the surveyed types themselves).
    pub classes: Option<Vec<TowerType>>,
}

/// Everything one run of the daemon is made of.
pub struct Daemon<'a> {
    pub node: &'a EdgeNode,
    pub source: Box<dyn FrameSource>,
    pub worker: Worker,
    pub core: DaemonCore,
    pub datum: Datum,
    pub options: RunOptions,
    pub sync: Option<&'a mut LandmarkSync>,
    /// Watches each frame's pipeline output from outside (the demo's scoring).
    pub observer: Option<&'a mut (dyn FrameObserver + 'static)>,
    pub stop: Arc<AtomicBool>,
}

/// What happened, for the report and the closing log.
pub struct RunSummary {
    pub record: FlightRecord,
    /// Frame-to-publish latency over the whole run, p50 and p99, milliseconds.
    pub latency_ms: (f64, f64),
    pub dropped: u64,
    pub failed: u64,
    pub mavlink_sent: u64,
}

/// What the loop woke up for.
enum Event {
    Frame(Option<Detected>),
    Correction(IdCorrection),
    Landmarks(Option<Sample>),
    Autopilot(Received),
    Px4Time(u64),
    Timer,
}

/// A frame the core has just processed, with what the loop kept of it.
struct Processed {
    seq: u64,
    time_s: f64,
    image: Option<RgbImage>,
    truth: Option<nalgebra::Point3<f64>>,
}

/// The loop's state beside the core: sinks and what it has counted.
struct Sinks<'a> {
    node: &'a EdgeNode,
    datum: Datum,
    jsonl: Option<JsonlLog>,
    mavlink: Option<MavlinkOut>,
    mavlink_errors: u64,
    onboard: Option<OnboardBus>,
    autopilot_log: Option<JsonlLog>,
    annotate_dir: Option<std::path::PathBuf>,
    record: FlightRecord,
    pacing: Pacing,
    warned_drops: bool,
    /// When the last status line went to the log (the source's clock).
    status_logged_at_s: Option<f64>,
}

impl Daemon<'_> {
    /// Runs until the source ends, or `stop` is set and the queued frames are done.
    pub async fn run(self, mut on_frame: impl FnMut(u64)) -> Result<RunSummary, ShellError> {
        let Daemon {
            node,
            source,
            worker,
            mut core,
            datum,
            mut options,
            mut sync,
            mut observer,
            stop,
        } = self;
        tracing::info!(source = %source.describe(), detector = %options.detector_name, "edge daemon starting");
        let queue = Arc::new(DropOldest::<CapturedFrame>::new(options.queue));
        let failed_source = Arc::new(AtomicU64::new(0));
        let source_thread = spawn_source(
            source,
            queue.clone(),
            stop.clone(),
            failed_source.clone(),
            options.pacing,
        )?;
        let (frames_tx, mut frames_rx) = tokio::sync::mpsc::channel::<Detected>(4);
        let worker_queue = queue.clone();
        let worker_task = tokio::task::spawn_blocking(move || worker.run(worker_queue, frames_tx));

        let classes = options.classes.take();
        let (link, mut from_autopilot) = options.mavlink.take().unzip();
        let mut sinks = Sinks::new(node, datum, &mut options, link)?;
        let counters = || SourceCounters {
            dropped: queue.dropped(),
            failed: failed_source.load(Ordering::Relaxed),
        };
        let wall = Instant::now();
        loop {
            let deadline = tokio::time::Instant::from_std(core.poll_timeout());
            let event = tokio::select! {
                detected = frames_rx.recv() => Event::Frame(detected),
                correction = node.next_correction() => Event::Correction(correction),
                change = next_change(sync.as_deref()) => Event::Landmarks(change),
                Some(message) = next_message(from_autopilot.as_mut()) => Event::Autopilot(message),
                Some(t) = next_message(sinks.onboard.as_mut().map(OnboardBus::px4_times)) => Event::Px4Time(t),
                () = tokio::time::sleep_until(deadline) => Event::Timer,
            };
            match event {
                Event::Frame(None) => break,
                Event::Frame(Some(detected)) => {
                    let seq = detected.frame.seq;
                    core = sinks
                        .detected(core, detected, observer.as_deref_mut())
                        .await?;
                    on_frame(seq);
                }
                Event::Correction(c) => core.handle_command(Instant::now(), Command::Correct(c)),
                Event::Autopilot((from, message)) => {
                    core.handle_command(Instant::now(), Command::FromAutopilot { from, message })
                }
                Event::Px4Time(t) => core.handle_command(Instant::now(), Command::Px4Time(t)),
                Event::Landmarks(change) => {
                    let changed =
                        changed_map(sync.as_deref_mut(), change, &datum, classes.as_deref());
                    if let Some(map) = changed.await? {
                        core.handle_command(Instant::now(), Command::ReplaceMap(map));
                    }
                }
                Event::Timer => {
                    if stop.load(Ordering::Relaxed) {
                        // A stalled source may never return: finish what is queued and go.
                        queue.close();
                    }
                }
            }
            core.handle_timeout(Instant::now(), counters());
            sinks.flush(&mut core, None).await?;
        }
        sinks.record.wall_seconds = wall.elapsed().as_secs_f64();
        stop.store(true, Ordering::Relaxed);
        queue.close();
        let totals: WorkerTotals = worker_task
            .await
            .map_err(|e| ShellError::Daemon(format!("the worker thread failed: {e}")))?;
        if source_thread.is_finished() {
            let _ = source_thread.join();
        }
        let failed = totals.failed + failed_source.load(Ordering::Relaxed);
        let summary = sinks.summary(&core, &totals, failed, queue.dropped(), &options);
        log_stop(&summary, options.pacing);
        Ok(summary)
    }
}

impl<'a> Sinks<'a> {
    /// The sinks `options` ask for; takes its MAVLink link and folders.
    fn new(
        node: &'a EdgeNode,
        datum: Datum,
        options: &mut RunOptions,
        mavlink: Option<MavlinkOut>,
    ) -> Result<Self, ShellError> {
        Ok(Self {
            node,
            datum,
            jsonl: open_jsonl(options.jsonl.as_deref(), "pose log")?,
            mavlink,
            mavlink_errors: 0,
            onboard: options.onboard.take(),
            autopilot_log: open_jsonl(options.autopilot_log.as_deref(), "autopilot log")?,
            annotate_dir: options.annotate_dir.take(),
            record: FlightRecord::default(),
            pacing: options.pacing,
            warned_drops: false,
            status_logged_at_s: None,
        })
    }

    /// One frame the core has processed: to the observer, and out.
    /// A detected frame through the core (off the runtime's threads), then out.
    async fn detected(
        &mut self,
        core: DaemonCore,
        detected: Detected,
        observer: Option<&mut (dyn FrameObserver + 'static)>,
    ) -> Result<DaemonCore, ShellError> {
        let processed = Processed {
            seq: detected.frame.seq,
            time_s: detected.frame.time_s,
            image: detected.image,
            truth: detected.truth_in_world,
        };
        let (mut core, seconds) = process(core, detected.frame).await?;
        self.record.core_seconds += seconds;
        self.frame(&mut core, processed, observer).await?;
        Ok(core)
    }

    /// The run's summary once the loop is done: the core's counts, the sinks' and the worker's.
    fn summary(
        self,
        core: &DaemonCore,
        totals: &WorkerTotals,
        failed: u64,
        dropped: u64,
        options: &RunOptions,
    ) -> RunSummary {
        RunSummary {
            failed,
            dropped,
            mavlink_sent: self.mavlink.as_ref().map_or(0, |m| m.sent),
            record: FlightRecord {
                frames: core.frames(),
                poses_published: core.poses(),
                detect_seconds: totals.detect_seconds,
                detector_errors: totals.failed,
                detector: (options.detector_name != "oracle")
                    .then(|| options.detector_name.clone()),
                ..self.record
            },
            latency_ms: core.latency_percentiles(),
        }
    }

    async fn frame(
        &mut self,
        core: &mut DaemonCore,
        processed: Processed,
        observer: Option<&mut (dyn FrameObserver + 'static)>,
    ) -> Result<(), ShellError> {
        let Processed {
            seq,
            time_s,
            image,
            truth,
        } = processed;
        if let (Some(observer), Some(output)) = (observer, core.last_output()) {
            observer.observe(seq, output, core.pipeline().map());
        }
        self.flush(core, image.as_ref()).await?;
        if let Some(truth) = truth {
            let g = self.datum.to_geodetic(&truth);
            self.node
                .publish_truth(&TruthPose {
                    uav: self.node.uav().clone(),
                    time_s,
                    seq,
                    lat_deg: g.lat_deg,
                    lon_deg: g.lon_deg,
                    alt_m: g.height_m,
                })
                .await?;
        }
        Ok(())
    }

    /// Sends everything the core has queued; `image` is the frame just processed.
    async fn flush(
        &mut self,
        core: &mut DaemonCore,
        image: Option<&RgbImage>,
    ) -> Result<(), ShellError> {
        let mut pose: Option<PoseEstimate> = None;
        while let Some(output) = core.poll_output() {
            match output {
                Output::Pose { pose: p, .. } => {
                    self.node.publish_pose(&p).await?;
                    self.log_pose(&p);
                    pose = Some(p);
                }
                Output::Tracks(tracks) => {
                    self.node.publish_tracks(&tracks).await?;
                    if let (Some(dir), Some(image)) = (&self.annotate_dir, image) {
                        write_annotated(dir, image, &tracks, pose.as_ref());
                    }
                }
                Output::Detections(report) => self.node.publish_detections(&report).await?,
                Output::Preview { seq, time_s } => {
                    if let Some(jpeg) = image.and_then(preview_jpeg) {
                        let (width, height) = image.map_or((0, 0), RgbImage::dimensions);
                        self.node
                            .publish_preview(&Preview {
                                uav: self.node.uav().clone(),
                                time_s,
                                seq,
                                frame_width: width,
                                frame_height: height,
                                jpeg,
                            })
                            .await?;
                    }
                }
                Output::Ack(ack) => self.node.acknowledge(&ack).await?,
                Output::AutopilotPosition(position) => {
                    if let Some(log) = self.autopilot_log.as_mut()
                        && !log.line(&position)
                    {
                        self.autopilot_log = None;
                    }
                }
                Output::Ros(output) => {
                    if let Some(bus) = self.onboard.as_mut() {
                        bus.publish(output).await;
                    }
                }
                Output::Mavlink(message) => {
                    if let Some(out) = self.mavlink.as_mut()
                        && let Err(e) = out.send(&message)
                    {
                        self.mavlink_errors += 1;
                        // Once, then every 100th: an unplugged link must not flood the log.
                        if self.mavlink_errors % 100 == 1 {
                            tracing::warn!(error = %e, failures = self.mavlink_errors, "MAVLink send failed");
                        }
                    }
                }
                Output::Status(status) => {
                    self.node.publish_status(&status).await?;
                    // A line a minute for the journal: how the service is doing.
                    if self
                        .status_logged_at_s
                        .is_none_or(|t| status.time_s - t >= STATUS_LOG_PERIOD_S)
                    {
                        self.status_logged_at_s = Some(status.time_s);
                        tracing::info!(
                            state = ?status.state,
                            health = ?status.health,
                            frames_per_s = format!("{:.1}", status.frame_rate_hz),
                            latency_p50_ms = format!("{:.1}", status.latency_p50_ms),
                            latency_p99_ms = format!("{:.1}", status.latency_p99_ms),
                            dropped = status.frames_dropped,
                            failed = status.frames_failed,
                            "status"
                        );
                    }
                    if !self.warned_drops
                        && let Some(share) =
                            dropped_share(status.frames_dropped, status.frames_processed)
                    {
                        self.warned_drops = true;
                        tracing::warn!(
                            dropped = status.frames_dropped,
                            processed = status.frames_processed,
                            "{}",
                            drop_advice(share, self.pacing)
                        );
                    }
                }
            }
        }
        Ok(())
    }

    fn log_pose(&mut self, pose: &PoseEstimate) {
        if let Some(log) = self.jsonl.as_mut()
            && !log.line(pose)
        {
            self.jsonl = None;
        }
    }
}

/// One frame through the core, and the seconds it took. The pipeline is CPU
/// work: it runs off the runtime's threads, so the sockets of this and every
/// other task stay served meanwhile (twenty edges in one process lost whole
/// UAVs' poses when it did not).
async fn process(
    mut core: DaemonCore,
    frame: DetectedFrame,
) -> Result<(DaemonCore, f64), ShellError> {
    tokio::task::spawn_blocking(move || {
        let t0 = Instant::now();
        core.handle_frame(t0, frame);
        (core, t0.elapsed().as_secs_f64())
    })
    .await
    .map_err(|e| ShellError::Daemon(format!("the pipeline failed: {e}")))
}

/// The map after a landmark change, when the change altered the set and its
/// types are ones the detector knows (else the map in use stays, and the
/// refusal is logged naming the types).
async fn changed_map(
    sync: Option<&mut LandmarkSync>,
    change: Option<Sample>,
    datum: &Datum,
    classes: Option<&[TowerType]>,
) -> Result<Option<LandmarkMap>, ShellError> {
    let Some(sync) = sync else {
        return Ok(None);
    };
    if !sync.apply(change).await? {
        return Ok(None);
    }
    let replica = sync.replica();
    tracing::info!(
        revision = replica.revision,
        towers = replica.len(),
        "landmarks updated from the ground station"
    );
    let records = replica.records();
    let types = match classes.map(|c| match_types(c, &records)) {
        None => TypeMatch::Typed,
        Some(Ok(types)) => types,
        Some(Err(mismatch)) => {
            tracing::error!(%mismatch, "keeping the landmark set in use");
            return Ok(None);
        }
    };
    Ok(Some(
        LandmarkMap::from_records(&records, datum).matched(types),
    ))
}

/// The next landmark change, or never when there is no sync.
/// The autopilot's next message; pending forever without a link, or once it closed.
async fn next_message<T>(rx: Option<&mut tokio::sync::mpsc::Receiver<T>>) -> Option<T> {
    match rx {
        Some(rx) => match rx.recv().await {
            Some(m) => Some(m),
            None => std::future::pending().await,
        },
        None => std::future::pending().await,
    }
}

async fn next_change(sync: Option<&LandmarkSync>) -> Option<Sample> {
    match sync {
        Some(sync) => match sync.next_change().await {
            Some(sample) => Some(sample),
            None => std::future::pending().await,
        },
        None => std::future::pending().await,
    }
}

/// The source's own thread: reads frames, paces them if asked, and queues them.
fn spawn_source(
    mut source: Box<dyn FrameSource>,
    queue: Arc<DropOldest<CapturedFrame>>,
    stop: Arc<AtomicBool>,
    failed: Arc<AtomicU64>,
    pacing: Pacing,
) -> Result<std::thread::JoinHandle<()>, ShellError> {
    let speed = match pacing {
        Pacing::Speed(speed) => Some(speed),
        Pacing::EveryFrame | Pacing::Live => None,
    };
    let paced = pacing != Pacing::EveryFrame;
    std::thread::Builder::new()
        .name("frame-source".into())
        .spawn(move || {
            let start = Instant::now();
            while !stop.load(Ordering::Relaxed) {
                match source.next_frame() {
                    Some(Ok(mut frame)) => {
                        if let Some(speed) = speed {
                            let due = Duration::from_secs_f64(frame.time_s / speed);
                            if let Some(wait) = due.checked_sub(start.elapsed()) {
                                std::thread::sleep(wait);
                            }
                        }
                        frame.captured = Instant::now();
                        // Real time drops the oldest; a replay as fast as it goes keeps every frame.
                        if paced {
                            queue.push(frame);
                        } else {
                            queue.push_blocking(frame);
                        }
                    }
                    Some(Err(e)) => {
                        tracing::warn!(error = %e, "frame skipped");
                        failed.fetch_add(1, Ordering::Relaxed);
                    }
                    None => break,
                }
            }
            queue.close();
        })
        .map_err(|e| ShellError::Daemon(format!("starting the source thread: {e}")))
}

fn open_jsonl(
    path: Option<&std::path::Path>,
    what: &'static str,
) -> Result<Option<JsonlLog>, ShellError> {
    path.map(|path| JsonlLog::create(path, what)).transpose()
}

fn log_stop(summary: &RunSummary, pacing: Pacing) {
    match dropped_share(summary.dropped, summary.record.frames) {
        Some(share) => tracing::warn!(
            frames = summary.record.frames,
            dropped = summary.dropped,
            failed = summary.failed,
            "edge daemon stopped; {}",
            drop_advice(share, pacing)
        ),
        None => tracing::info!(
            frames = summary.record.frames,
            dropped = summary.dropped,
            failed = summary.failed,
            "edge daemon stopped"
        ),
    }
}

/// The frame with its tracks and pose drawn, as a JPEG in `dir` (demo build).
#[cfg(feature = "demo")]
fn write_annotated(
    dir: &std::path::Path,
    image: &RgbImage,
    tracks: &TrackReport,
    pose: Option<&PoseEstimate>,
) {
    let path = dir.join(format!("frame{:06}.jpg", tracks.seq));
    let mut canvas = image.clone();
    towernav_eval::annotate::annotate(&mut canvas, tracks, pose);
    if let Err(e) = canvas.save(&path) {
        tracing::warn!(path = %path.display(), error = %e, "annotated frame not written");
    }
}

/// The onboard build draws nothing: the config refuses `output.annotated` there.
#[cfg(not(feature = "demo"))]
fn write_annotated(_: &std::path::Path, _: &RgbImage, _: &TrackReport, _: Option<&PoseEstimate>) {}

/// A half-size JPEG of the frame for the operator's camera view.
fn preview_jpeg(image: &RgbImage) -> Option<Vec<u8>> {
    let small = image::imageops::thumbnail(image, image.width() / 2, image.height() / 2);
    let mut jpeg = Vec::new();
    JpegEncoder::new_with_quality(&mut jpeg, 70)
        .encode_image(&small)
        .map_err(|e| tracing::warn!(error = %e, "preview not encoded"))
        .ok()?;
    Some(jpeg)
}

/// Share of the source's frames that the queue dropped, when over 1 %: enough
/// that a replay is no longer the flight it recorded.
pub fn dropped_share(dropped: u64, processed: u64) -> Option<f64> {
    let seen = dropped + processed;
    let share = dropped as f64 / seen.max(1) as f64;
    (share > 0.01).then_some(share)
}

/// What to say about a share of dropped frames, and what to do about it.
pub fn drop_advice(share: f64, pacing: Pacing) -> String {
    let cause = match pacing {
        Pacing::Speed(speed) => format!(
            "the pipeline is slower than the source played at {speed}x; `--speed 0` processes every frame"
        ),
        Pacing::Live => "the pipeline is slower than the camera's frame rate".into(),
        Pacing::EveryFrame => "frames were dropped although every frame was asked for".into(),
    };
    format!("{:.1} % of frames were dropped: {cause}", share * 100.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dropping_over_one_percent_is_told_with_its_cure() {
        assert_eq!(dropped_share(1, 199), None, "0.5 %");
        assert_eq!(dropped_share(0, 0), None);
        let share = dropped_share(75, 25).expect("75 %");
        assert!((share - 0.75).abs() < 1e-12);
        let advice = drop_advice(share, Pacing::Speed(4.0));
        assert!(
            advice.contains("75.0 %") && advice.contains("--speed 0"),
            "{advice}"
        );
    }
}
