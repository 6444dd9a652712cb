//! The flags that name a recorded flight, shared by `replay` and `label`.

use std::path::PathBuf;

use clap::Args;
use towernav_edge::daemon::config::{AttitudeKind, EdgeConfig, SourceKind};

#[derive(Args)]
pub struct RecordingArgs {
    /// The camera's video (anything ffmpeg reads); frames are timed by its
    /// presentation timestamps. A GoPro video is its own flight log (its
    /// GPMF telemetry) unless --log names another.
    #[arg(long, conflicts_with = "images")]
    pub video: Option<PathBuf>,
    /// A folder of the camera's images, in name order.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// How frames are timed: pts, rate (with --fps), names, names_ms,
    /// names_us, names_ns, or a timestamps file.
    #[arg(long)]
    pub timestamps: Option<String>,
    /// The frame rate, for --timestamps rate.
    #[arg(long)]
    pub fps: Option<f64>,
    /// Seconds from the camera's clock to the log's: a frame at camera time t
    /// takes the log's attitude at t + offset.
    #[arg(long, allow_hyphen_values = true)]
    pub time_offset: Option<f64>,
    /// The camera's calibration: OpenCV YAML/JSON, ROS camera_info or Kalibr.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// The towers: a landmark CSV or database.
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
}

impl RecordingArgs {
    /// The flight log: `log` where given, else a GoPro video's own GPMF track.
    pub fn log_or_gopro(&self, log: Option<&PathBuf>) -> Option<PathBuf> {
        log.cloned().or_else(|| {
            self.video
                .as_ref()
                .filter(|v| towernav_flightlog::gpmf::Telemetry::in_video(v))
                .cloned()
        })
    }

    /// A survey flight's config (`label`, `map-towers`): the recording, and
    /// its log with attitude and GNSS (`log`, else a GoPro video's own).
    pub fn survey_config(&self, log: Option<&PathBuf>) -> anyhow::Result<EdgeConfig> {
        anyhow::ensure!(
            self.video.is_some() || self.images.is_some(),
            "give the survey flight: --video FILE or --images DIR"
        );
        let log = self.log_or_gopro(log).ok_or_else(|| {
            anyhow::anyhow!(
                "give the flight log with attitude and GNSS: --log (a GoPro video with GPMF telemetry needs none)"
            )
        })?;
        let mut c = EdgeConfig::default();
        self.apply(&mut c);
        c.attitude.kind = AttitudeKind::Log;
        c.attitude.path = Some(log);
        Ok(c)
    }

    /// These flags over `c`.
    pub fn apply(&self, c: &mut EdgeConfig) {
        if let Some(v) = &self.video {
            c.source.kind = SourceKind::Video;
            c.source.path = Some(v.display().to_string());
        }
        if let Some(v) = &self.images {
            c.source.kind = SourceKind::Images;
            c.source.path = Some(v.display().to_string());
        }
        if let Some(v) = &self.timestamps {
            c.source.timestamps = Some(v.clone());
        }
        if let Some(v) = self.fps {
            c.source.fps = v;
        }
        if let Some(v) = self.time_offset {
            c.attitude.time_offset_s = v;
        }
        if let Some(v) = &self.camera {
            c.camera.calibration = Some(v.clone());
        }
        if let Some(v) = &self.landmarks {
            c.landmarks.file = Some(v.clone());
        }
    }
}
