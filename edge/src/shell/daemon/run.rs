//! Wiring: source thread -> drop-oldest queue -> worker thread -> this task,
//! which publishes, sends MAVLink, logs JSONL, forwards corrections and
//! landmark changes, and sends the status heartbeat once a second.

use std::io::Write;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use towernav_geometry::Datum;
use towernav_protocol::{Health, StatusHeartbeat, TruthPose};

use super::config::Pacing;
use super::mavlink_out::MavlinkOut;
use super::queue::DropOldest;
use super::source::{CapturedFrame, FrameSource};
use super::worker::{Processed, Worker, WorkerCommand, WorkerTotals};
use crate::landmarks::LandmarkMap;
use crate::shell::ShellError;
use crate::shell::flight_record::FlightRecord;
use crate::shell::landmark_sync::LandmarkSync;
use crate::shell::node::EdgeNode;

/// How the shell around the worker behaves.
pub struct RunOptions {
    /// Every frame, at a multiple of the source's clock, or a live camera's pace.
    pub pacing: Pacing,
    pub queue: usize,
    /// The detector, for the status: "oracle" or the model's file name.
    pub detector_name: String,
    pub jsonl: Option<std::path::PathBuf>,
    pub mavlink: Option<MavlinkOut>,
}

/// What happened, for the report and the closing log.
pub struct RunSummary {
    pub record: FlightRecord,
    /// Frame-to-publish latency of every processed frame, milliseconds.
    pub latency_ms: Vec<f64>,
    pub dropped: u64,
    pub failed: u64,
    pub mavlink_sent: u64,
}

/// Run `source` through `worker` until the source ends or `stop` is set.
#[allow(clippy::too_many_arguments)]
pub async fn run(
    node: &EdgeNode,
    mut source: Box<dyn FrameSource>,
    worker: Worker,
    datum: Datum,
    mut options: RunOptions,
    mut sync: Option<&mut LandmarkSync>,
    stop: Arc<AtomicBool>,
    mut on_frame: impl FnMut(u64),
) -> Result<RunSummary, ShellError> {
    tracing::info!(source = %source.describe(), detector = %options.detector_name, "edge daemon starting");
    let queue = Arc::new(DropOldest::<CapturedFrame>::new(options.queue));
    let failed_source = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let source_thread = {
        let (queue, stop, failed) = (queue.clone(), stop.clone(), failed_source.clone());
        let speed = match options.pacing {
            Pacing::Speed(speed) => Some(speed),
            Pacing::EveryFrame | Pacing::Live => None,
        };
        let paced = options.pacing != Pacing::EveryFrame;
        std::thread::Builder::new()
            .name("frame-source".into())
            .spawn(move || {
                let start = Instant::now();
                while !stop.load(Ordering::Relaxed) {
                    match source.next_frame() {
                        Some(Ok(frame)) => {
                            if let Some(speed) = speed {
                                let due = Duration::from_secs_f64(frame.time_s / speed);
                                if let Some(wait) = due.checked_sub(start.elapsed()) {
                                    std::thread::sleep(wait);
                                }
                            }
                            let mut frame = frame;
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
            .map_err(|e| ShellError::Daemon(format!("starting the source thread: {e}")))?
    };
    let (commands_tx, commands_rx) = std::sync::mpsc::channel::<WorkerCommand>();
    let (out_tx, mut out_rx) = tokio::sync::mpsc::channel::<Processed>(4);
    let worker_queue = queue.clone();
    let worker_task =
        tokio::task::spawn_blocking(move || worker.run(worker_queue, commands_rx, out_tx));

    let mut jsonl = match &options.jsonl {
        Some(path) => Some(std::io::BufWriter::new(
            std::fs::File::create(path).map_err(|e| {
                ShellError::Daemon(format!("creating the JSONL log {}: {e}", path.display()))
            })?,
        )),
        None => None,
    };
    let mut record = FlightRecord::default();
    let mut latency_ms = Vec::new();
    let mut window: Vec<f64> = Vec::new();
    let mut last_status = Instant::now();
    let mut frames_since_status = 0u64;
    // Dropped + failed at the last status: health reflects the last period only.
    let mut troubles_at_status = 0u64;
    let mut warned_drops = false;
    let wall = Instant::now();
    while let Some(p) = out_rx.recv().await {
        if let Some(sync) = sync.as_deref_mut()
            && sync.poll().await?
        {
            let replica = sync.replica();
            tracing::info!(
                revision = replica.revision,
                towers = replica.len(),
                "landmarks updated from the ground station"
            );
            let map = LandmarkMap::from_records(&replica.records(), &datum);
            let _ = commands_tx.send(WorkerCommand::ReplaceMap(map));
        }
        for correction in node.pending_corrections() {
            let _ = commands_tx.send(WorkerCommand::Correct(correction));
        }
        for ack in &p.acks {
            node.acknowledge(ack).await?;
        }
        if let Some(pose) = &p.pose {
            node.publish_pose(pose).await?;
            record.poses_published += 1;
            if let Some(out) = options.mavlink.as_mut()
                && let Err(e) = out.offer(pose, p.state, &p.attitude)
            {
                tracing::warn!(error = %e, "MAVLink send failed");
            }
            if let Some(log) = jsonl.as_mut()
                && let Ok(line) = serde_json::to_string(pose)
                && writeln!(log, "{line}").is_err()
            {
                tracing::warn!("the JSONL log could not be written; stopping it");
                jsonl = None;
            }
        }
        node.publish_tracks(&p.tracks).await?;
        node.publish_detections(&p.detections).await?;
        if let Some(preview) = &p.preview {
            node.publish_preview(preview).await?;
        }
        let latency = p.captured.elapsed().as_secs_f64() * 1e3;
        latency_ms.push(latency);
        window.push(latency);
        if let Some(truth) = p.truth_in_world {
            record.truth_en.push((truth.x, truth.y));
            let g = datum.to_geodetic(&truth);
            node.publish_truth(&TruthPose {
                uav: node.uav().clone(),
                time_s: p.time_s,
                seq: p.seq,
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_m: g.height_m,
            })
            .await?;
        }
        record.frames += 1;
        frames_since_status += 1;
        on_frame(p.seq);

        if last_status.elapsed() >= Duration::from_secs(1) {
            let failed = failed_source.load(Ordering::Relaxed);
            let dropped = queue.dropped();
            let (p50, p99) = percentiles(&mut window);
            node.publish_status(&StatusHeartbeat {
                uav: node.uav().clone(),
                time_s: p.time_s,
                state: p.state,
                frames_processed: record.frames,
                frame_rate_hz: frames_since_status as f64 / last_status.elapsed().as_secs_f64(),
                landmarks_loaded: p.landmarks,
                datum_lat_deg: datum.origin.lat_deg,
                datum_lon_deg: datum.origin.lon_deg,
                datum_alt_m: datum.origin.height_m,
                health: if dropped + failed > troubles_at_status {
                    Health::Degraded
                } else {
                    Health::Ok
                },
                frames_dropped: dropped,
                frames_failed: failed,
                latency_p50_ms: p50,
                latency_p99_ms: p99,
                detector: options.detector_name.clone(),
            })
            .await?;
            if !warned_drops && let Some(share) = dropped_share(dropped, record.frames) {
                warned_drops = true;
                tracing::warn!(
                    dropped,
                    processed = record.frames,
                    "{}",
                    drop_advice(share, options.pacing)
                );
            }
            window.clear();
            troubles_at_status = dropped + failed;
            last_status = Instant::now();
            frames_since_status = 0;
        }
    }
    record.wall_seconds = wall.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    queue.close();
    let totals: WorkerTotals = worker_task
        .await
        .map_err(|e| ShellError::Daemon(format!("the worker thread failed: {e}")))?;
    let _ = source_thread.join();
    if let Some(log) = jsonl.as_mut() {
        let _ = log.flush();
    }
    record.core_seconds = totals.core_seconds;
    record.detect_seconds = totals.detect_seconds;
    record.detector_errors = totals.failed;
    record.identity = totals.identity;
    record.detector = (options.detector_name != "oracle").then(|| options.detector_name.clone());
    let summary = RunSummary {
        failed: totals.failed + failed_source.load(Ordering::Relaxed),
        dropped: queue.dropped(),
        mavlink_sent: options.mavlink.as_ref().map_or(0, |m| m.sent),
        record,
        latency_ms,
    };
    match dropped_share(summary.dropped, summary.record.frames) {
        Some(share) => tracing::warn!(
            frames = summary.record.frames,
            dropped = summary.dropped,
            failed = summary.failed,
            "edge daemon stopped; {}",
            drop_advice(share, options.pacing)
        ),
        None => tracing::info!(
            frames = summary.record.frames,
            dropped = summary.dropped,
            failed = summary.failed,
            "edge daemon stopped"
        ),
    }
    Ok(summary)
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

/// p50 and p99 of `values` (sorted in place); zeros when empty.
pub fn percentiles(values: &mut [f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    values.sort_by(f64::total_cmp);
    let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.99))
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
