//! `towernav-edge replay`: a recorded flight (video or images, flight log,
//! calibration, landmarks) through the pipeline, every frame, scored against
//! the log's GNSS when it has one, with the estimates, a summary and plots
//! written out (demo build: the plots link the plotting library).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use towernav_edge::daemon::config::{AttitudeKind, EdgeConfig, SourceKind};
use towernav_edge::replay::{ReplayRun, replay};
use towernav_eval::cmd::demo_plots::{ErrorPoint, write_track_and_error};
use towernav_eval::gnss_score::{ReferenceFix, ReplayEstimate, ReplayScore, score};

use crate::cli::recording_args::RecordingArgs;

/// Flags override `--config` (an edge config, such as the simulator's
/// `replay.toml`), which overrides the daemon's defaults.
#[derive(Args)]
pub struct ReplayArgs {
    /// An edge config file to start from.
    #[arg(long)]
    config: Option<PathBuf>,
    #[command(flatten)]
    recording: RecordingArgs,
    /// The flight log: ArduPilot .bin, MAVLink .tlog, PX4 .ulg, CSV, DJI .srt
    /// or a GoPro .mp4; default: a GoPro --video's own GPMF telemetry.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Where the replay starts, lat_deg,lon_deg,alt_m (ellipsoid); default:
    /// the log's GNSS at the first frame.
    #[arg(long, value_parser = lat_lon_alt, allow_hyphen_values = true)]
    takeoff: Option<[f64; 3]>,
    /// YOLO model; default: the daemon's.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Keep the detector's own types (no type classifier).
    #[arg(long)]
    no_type_model: bool,
    /// Stop after this many frames.
    #[arg(long)]
    max_frames: Option<u64>,
    /// Folder for poses.jsonl, replay.json and the plots.
    #[arg(long, default_value = "target/replay")]
    out: PathBuf,
}

/// `lat_deg,lon_deg,alt_m`.
fn lat_lon_alt(text: &str) -> Result<[f64; 3], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("{v:?}: {e}")))
        .collect::<Result<_, _>>()?;
    <[f64; 3]>::try_from(values)
        .map_err(|v| format!("three numbers lat_deg,lon_deg,alt_m, got {}", v.len()))
}

impl ReplayArgs {
    fn config(&self) -> anyhow::Result<EdgeConfig> {
        let mut c = match &self.config {
            Some(path) => EdgeConfig::read(path)?,
            None => EdgeConfig::default(),
        };
        self.recording.apply(&mut c);
        if let Some(v) = self.recording.log_or_gopro(self.log.as_ref()) {
            c.attitude.kind = AttitudeKind::Log;
            c.attitude.path = Some(v);
        }
        if let Some(t) = self.takeoff {
            c.pipeline.takeoff = Some(t);
        }
        if let Some(v) = &self.model {
            c.detector.model = v.clone();
        }
        if self.no_type_model {
            c.detector.classify_types = false;
        }
        if let Some(v) = self.max_frames {
            c.source.max_frames = Some(v);
        }
        anyhow::ensure!(
            matches!(c.source.kind, SourceKind::Video | SourceKind::Images),
            "give the recording: --video FILE or --images DIR"
        );
        Ok(c)
    }

    pub fn run(&self) -> anyhow::Result<()> {
        let config = self.config()?;
        let bar = towernav_eval::progress::bar(0, "frames");
        let run = replay(&config, |seq, total| {
            if let Some(n) = total {
                bar.set_length(n);
            }
            bar.set_position(seq + 1);
        })?;
        bar.finish_and_clear();
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("creating {}", self.out.display()))?;
        write_poses(&self.out, &run)?;
        let scored = score_run(&run);
        print_summary(&run, scored.as_ref());
        if let Some(score) = &scored {
            let (track, errors) = plot(&self.out, &run, score)?;
            println!("plots: {} {}", track.display(), errors.display());
        }
        let summary = self.out.join("replay.json");
        std::fs::write(&summary, summary_json(&run, scored.as_ref()).to_string())
            .with_context(|| format!("writing {}", summary.display()))?;
        println!("summary: {}", summary.display());
        Ok(())
    }
}

/// The estimates against the log's GNSS; none when the log has no GNSS.
pub fn score_run(run: &ReplayRun) -> Option<ReplayScore> {
    if run.gnss.is_empty() {
        return None;
    }
    let estimates: Vec<ReplayEstimate> = run
        .poses
        .iter()
        .map(|p| ReplayEstimate {
            seq: p.pose.seq,
            log_time_s: p.log_time_s,
            east_north: p.east_north(),
            covariance: p.covariance_en,
        })
        .collect();
    let fixes: Vec<ReferenceFix> = run
        .gnss
        .iter()
        .filter_map(|g| {
            Some(ReferenceFix {
                time_s: g.time_s,
                position: g.geodetic()?,
            })
        })
        .collect();
    Some(score(&run.datum, run.frames, &estimates, &fixes))
}

fn write_poses(out: &std::path::Path, run: &ReplayRun) -> anyhow::Result<()> {
    let path = out.join("poses.jsonl");
    let file =
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    for p in &run.poses {
        writeln!(w, "{}", serde_json::to_string(&p.pose)?)?;
    }
    w.flush()
        .with_context(|| format!("writing {}", path.display()))
}

fn plot(
    out: &std::path::Path,
    run: &ReplayRun,
    score: &ReplayScore,
) -> anyhow::Result<(PathBuf, PathBuf)> {
    let estimate: Vec<(f64, f64)> = run
        .poses
        .iter()
        .map(|p| (p.pose.east_m, p.pose.north_m))
        .collect();
    let errors: Vec<ErrorPoint> = score
        .scored
        .iter()
        .map(|s| {
            let major = s.estimate.covariance.symmetric_eigenvalues().max().max(0.0);
            (s.estimate.log_time_s, s.error_m, Some(2.0 * major.sqrt()))
        })
        .collect();
    write_track_and_error(
        out,
        "the log's GNSS",
        &score.reference_track,
        &estimate,
        &errors,
    )
}

fn print_summary(run: &ReplayRun, score: Option<&ReplayScore>) {
    println!(
        "replayed {} frames in {:.1} s ({:.1} frames/s, detector {:.1} ms a frame); {} estimates; {} frames skipped; start from {}",
        run.frames,
        run.wall_seconds,
        run.frames as f64 / run.wall_seconds.max(1e-9),
        1e3 * run.detect_seconds / (run.frames.saturating_sub(run.skipped)).max(1) as f64,
        run.poses.len(),
        run.skipped,
        run.start
    );
    match score {
        None => println!("the log has no GNSS: nothing to score against"),
        Some(s) => println!(
            "against the log's GNSS ({} estimates scored): RMS {:.2} m, median {:.2} m, p95 {:.2} m, max {:.2} m, within 5 m {:.1} %, frames with an estimate {:.1} %, 2-sigma coverage {:.1} %",
            s.stats.count,
            s.stats.rms,
            s.stats.median,
            s.stats.p95,
            s.stats.max,
            100.0 * s.stats.within_5m,
            100.0 * s.estimate_share(),
            100.0 * s.two_sigma_coverage
        ),
    }
}

fn summary_json(run: &ReplayRun, score: Option<&ReplayScore>) -> serde_json::Value {
    let scored = score.map(|s| {
        serde_json::json!({
            "scored": s.stats.count,
            "rms_m": s.stats.rms,
            "median_m": s.stats.median,
            "p95_m": s.stats.p95,
            "max_m": s.stats.max,
            "within_5m": s.stats.within_5m,
            "estimate_share": s.estimate_share(),
            "two_sigma_coverage": s.two_sigma_coverage,
        })
    });
    serde_json::json!({
        "frames": run.frames,
        "skipped": run.skipped,
        "estimates": run.poses.len(),
        "start": run.start,
        "wall_s": run.wall_seconds,
        "against_gnss": scored,
    })
}
