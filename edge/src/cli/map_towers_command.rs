//! `towernav-edge map-towers`: towers measured from a survey flight (desk
//! build, beside `replay` and `label`).

use std::path::PathBuf;

use clap::Args;
use towernav_core::tower_map::{MatchParams, TriangulationParams, Verdict};
use towernav_edge::map_towers::{MapOptions, SCORE_MATCH_M, SCORE_MIN_VIEWS, map_towers};

use crate::cli::recording_args::RecordingArgs;

/// A survey flight (GNSS still working) into measured towers: each tracked
/// tower's foot from its bearings over many views, its height from the
/// box's top and foot rows; against the landmark file where one is given
/// (confirmed, missed, new).
#[derive(Args)]
pub struct MapTowersArgs {
    #[command(flatten)]
    recording: RecordingArgs,
    /// The flight log with attitude and GNSS: ArduPilot .bin, MAVLink .tlog,
    /// PX4 .ulg, CSV, DJI .srt or a GoPro .mp4; default: a GoPro --video's own.
    #[arg(long)]
    log: Option<PathBuf>,
    /// One-sigma error of the log's GNSS, each horizontal axis, metres.
    #[arg(long, default_value_t = 1.5)]
    gnss_sigma_m: f64,
    /// How long the GNSS error takes to forget itself, seconds: the towers
    /// are placed with the error of every second of flight solved beside them.
    #[arg(long, default_value_t = 10.0)]
    gnss_correlation_s: f64,
    /// One-sigma heading error of the log's attitude, degrees (it wanders
    /// over 3 s); the box's own bearing error is 0.06 degrees.
    #[arg(long, default_value_t = 0.5)]
    bearing_sigma_deg: f64,
    /// One-sigma error of the log's GNSS velocity, m/s: where the log gives
    /// velocities, they tie each second's GNSS error to the next. 0 leaves
    /// them out.
    #[arg(long, default_value_t = 0.1)]
    velocity_sigma_mps: f64,
    /// One-sigma yaw of the camera on its mount against the attitude,
    /// degrees: 0 takes the calibration's mount as exact. Give 1-2 for a
    /// mount never calibrated: the flight then solves one yaw for it from
    /// towers seen from both sides (a lawnmower's passes both ways).
    #[arg(long, default_value_t = 0.0)]
    boresight_sigma_deg: f64,
    /// Known towers whose record states a horizontal sigma of at most this
    /// (metres; a crew's surveyed towers) anchor the survey: all towers are
    /// moved by one translation onto them, taking out the flight's shared
    /// GNSS error, which its views cannot see. 0: none.
    #[arg(long, default_value_t = 1.0)]
    anchor_sigma_m: f64,
    /// A tower needs this many views.
    #[arg(long, default_value_t = 5)]
    min_views: usize,
    /// Towers placed worse than this (one sigma, metres) are reported as
    /// uncertain instead of proposed.
    #[arg(long, default_value_t = 3.0)]
    max_sigma_m: f64,
    /// The true towers (a rendered flight's towers.csv): score the proposals
    /// against them.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// YOLO model; default: the daemon's.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Folder for towers-mapped.csv, towers-mapped.geojson and report.csv.
    #[arg(long)]
    out: PathBuf,
}

impl MapTowersArgs {
    pub fn run(&self) -> anyhow::Result<()> {
        let r = &self.recording;
        anyhow::ensure!(
            r.camera.is_some(),
            "mapping needs the calibration (--camera)"
        );
        anyhow::ensure!(
            self.gnss_sigma_m >= 0.0
                && self.gnss_correlation_s >= 0.0
                && self.bearing_sigma_deg > 0.0
                && self.boresight_sigma_deg >= 0.0
                && self.velocity_sigma_mps >= 0.0
                && self.anchor_sigma_m >= 0.0
                && self.min_views >= 2,
            "--gnss-sigma-m, --gnss-correlation-s, --velocity-sigma-mps, --boresight-sigma-deg and --anchor-sigma-m must be 0 or more, --bearing-sigma-deg positive and --min-views 2 or more"
        );
        let mut c = r.survey_config(self.log.as_ref())?;
        if let Some(m) = &self.model {
            c.detector.model = m.clone();
        }
        let options = MapOptions {
            triangulation: TriangulationParams {
                bearing_sigma_rad: self.bearing_sigma_deg.to_radians(),
                boresight_sigma_rad: self.boresight_sigma_deg.to_radians(),
                position_sigma_m: self.gnss_sigma_m,
                position_correlation_s: self.gnss_correlation_s,
                velocity_sigma_mps: self.velocity_sigma_mps,
                min_views: self.min_views,
                ..TriangulationParams::default()
            },
            max_sigma_m: self.max_sigma_m,
            truth: self.truth.clone(),
            matching: MatchParams::default(),
            anchor_sigma_m: self.anchor_sigma_m,
            out: self.out.clone(),
        };
        let bar = towernav_eval::progress::bar(0, "frames");
        let run = map_towers(&c, &options, |seq, total| {
            if let Some(n) = total {
                bar.set_length(n);
            }
            bar.set_position(seq + 1);
        })?;
        bar.finish_and_clear();
        let confirmed = run
            .report
            .verdicts
            .iter()
            .filter(|v| matches!(v, Verdict::Confirms { .. }))
            .count();
        println!(
            "{} frames ({} without a pose), {} tracks: {} towers measured: {confirmed} confirm the landmark file, {} new, {} too uncertain to propose; {} known towers missed (in view, not measured), {} never in view",
            run.frames,
            run.without_pose,
            run.tracks,
            run.towers.len(),
            run.towers.len() - confirmed,
            run.uncertain.len(),
            run.report.missed.len(),
            run.report.not_seen.len(),
        );
        if let Some(s) = &run.score {
            println!(
                "against the truth: {}/{} towers seen in {SCORE_MIN_VIEWS}+ frames found (within {SCORE_MATCH_M} m), foot RMS {:.2} m (max {:.2}){}, height RMS {:.2} m, {} phantoms",
                s.found,
                s.seen,
                s.position_rms_m,
                s.position_max_m,
                if s.anchored > 0 {
                    format!(" ({} anchored left out)", s.anchored)
                } else {
                    String::new()
                },
                s.height_rms_m,
                s.phantoms
            );
            if let Some(m) = &s.bearing_misses {
                println!(
                    "box bearings against the true towers, with the log's poses ({} views): robust 1-sigma {:.3} deg a view, {:.3} deg a tower's second, {:.3} deg within {} m",
                    m.views,
                    m.per_view.to_degrees(),
                    m.per_tower_second.to_degrees(),
                    m.near.to_degrees(),
                    towernav_core::tower_map::bearing_misses::NEAR_M
                );
            }
        }
        println!(
            "wrote {0}/towers-mapped.csv, {0}/towers-mapped.geojson, {0}/report.csv",
            self.out.display()
        );
        Ok(())
    }
}
