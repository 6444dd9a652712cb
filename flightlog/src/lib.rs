//! What a flight log says about the UAV: its attitude and, where present,
//! its GNSS fixes and barometric altitude, on the autopilot's clock (seconds since boot), from
//! ArduPilot DataFlash (`.bin`), MAVLink telemetry logs (`.tlog`), PX4 ULog
//! (`.ulg`), the project's CSV, DJI's video telemetry subtitles (`.srt`)
//! and a GoPro's GPMF track inside its MP4 (the last two on the video's
//! clock). Attitude between samples is slerped.
//!
//! Readers take bytes; [`FlightLog::read`] is the one place that opens a file.

mod csv_log;
mod dataflash;
pub mod dji_srt;
mod error;
pub mod gpmf;
mod samples;
mod tlog;
mod ulog;

use std::path::Path;

pub use error::LogError;
pub use samples::{AttitudeSample, BaroSample, GnssSample, GroundVelocity, MAX_GNSS_GAP_S};

use towernav_geometry::Attitude;

/// The formats, told apart by the file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    DataFlash,
    Tlog,
    Ulog,
    Csv,
    /// DJI's per-frame subtitles beside a video.
    DjiSrt,
    /// A GoPro video (`.mp4`, `.mov`) with its GPMF telemetry track.
    GoPro,
}

impl LogFormat {
    pub fn of(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "bin" => Self::DataFlash,
            "tlog" => Self::Tlog,
            "ulg" => Self::Ulog,
            "csv" => Self::Csv,
            "srt" => Self::DjiSrt,
            "mp4" | "mov" => Self::GoPro,
            _ => return None,
        })
    }
}

/// A flight's attitude, GNSS and barometer, each sorted by time.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightLog {
    pub attitude: Vec<AttitudeSample>,
    pub gnss: Vec<GnssSample>,
    /// ArduPilot's `BARO` `Alt`, PX4's `vehicle_air_data` `baro_alt_meter`,
    /// a tlog's ALTITUDE `altitude_monotonic` (else VFR_HUD `alt`); none from CSV.
    pub barometer: Vec<BaroSample>,
}

impl FlightLog {
    /// Reads `path` in the format its extension names. A log without
    /// attitude is refused: it cannot place a single frame.
    pub fn read(path: &Path) -> Result<Self, LogError> {
        let bad = |reason: String| LogError::new(path, reason);
        let format = LogFormat::of(path).ok_or_else(|| {
            bad(
                "the extension is not one of .bin (ArduPilot), .tlog (MAVLink), .ulg (PX4), .csv, .srt (DJI), .mp4 (GoPro)"
                    .into(),
            )
        })?;
        if format == LogFormat::GoPro {
            // A video is too big to hold: read its telemetry track in place.
            let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
            let mut reader = std::io::BufReader::new(file);
            return Self::from_gopro(&mut reader).map_err(|e| e.in_file(path));
        }
        let bytes = std::fs::read(path).map_err(|e| bad(e.to_string()))?;
        Self::parse(format, &bytes).map_err(|e| e.in_file(path))
    }

    /// A GoPro video's telemetry as a flight log; refused for a video
    /// without a GPMF track, or one whose track cannot place the camera.
    fn from_gopro<R: std::io::Read + std::io::Seek>(r: &mut R) -> Result<Self, LogError> {
        let telemetry = gpmf::Telemetry::read(r)?.ok_or_else(|| {
            LogError::bare(
                "no GPMF track in this video (a GoPro's has sample entry 'gpmd'; a DJI \
                 video's telemetry is in the .SRT beside it)"
                    .into(),
            )
        })?;
        let mut log = gpmf::flight_log(&telemetry)?;
        samples::tidy(&mut log.attitude, |s| s.time_s);
        samples::tidy(&mut log.gnss, |s| s.time_s);
        samples::tidy(&mut log.barometer, |s| s.time_s);
        Ok(log)
    }

    pub fn parse(format: LogFormat, bytes: &[u8]) -> Result<Self, LogError> {
        let mut log = match format {
            LogFormat::DataFlash => dataflash::parse(bytes)?,
            LogFormat::Tlog => tlog::parse(bytes)?,
            LogFormat::Ulog => ulog::parse(bytes)?,
            LogFormat::Csv => csv_log::parse(bytes)?,
            LogFormat::DjiSrt => dji_srt::parse(bytes)?,
            LogFormat::GoPro => Self::from_gopro(&mut std::io::Cursor::new(bytes))?,
        };
        samples::tidy(&mut log.attitude, |s| s.time_s);
        samples::tidy(&mut log.gnss, |s| s.time_s);
        samples::tidy(&mut log.barometer, |s| s.time_s);
        if log.attitude.is_empty() {
            return Err(LogError::bare(format!(
                "no attitude in it (looked for {})",
                match format {
                    LogFormat::DataFlash => "ATT",
                    LogFormat::Tlog => "ATTITUDE",
                    LogFormat::Ulog => "vehicle_attitude",
                    LogFormat::Csv => "rows of time_s,roll_deg,pitch_deg,heading_deg",
                    LogFormat::DjiSrt => "gimbal angles",
                    LogFormat::GoPro => "ATTD, or GRAV with a moving GPS track",
                }
            )));
        }
        Ok(log)
    }

    /// The span of the attitude samples, seconds on the log's clock.
    pub fn span(&self) -> (f64, f64) {
        let first = self.attitude.first().map_or(0.0, |s| s.time_s);
        let last = self.attitude.last().map_or(0.0, |s| s.time_s);
        (first, last)
    }

    /// Attitude at `time_s`, slerped between the samples around it; `None`
    /// outside the log.
    pub fn attitude_at(&self, time_s: f64) -> Option<Attitude> {
        samples::slerp_at(&self.attitude, time_s)
    }

    /// The GNSS fix at `time_s`, between the fixes around it; `None`
    /// outside the log's fixes or across a gap in them.
    pub fn gnss_at(&self, time_s: f64) -> Option<GnssSample> {
        samples::gnss_at(&self.gnss, time_s)
    }

    /// The barometer's altitude at `time_s` (on its own zero: compare two
    /// readings, not one with a map); `None` outside its readings or across a gap.
    pub fn barometer_at(&self, time_s: f64) -> Option<f64> {
        samples::baro_at(&self.barometer, time_s)
    }

    /// Refuses frames from `first_s` to `last_s` (log clock) that the log
    /// does not cover, saying by how much.
    pub fn check_covers(&self, first_s: f64, last_s: f64) -> Result<(), LogError> {
        let (start, end) = self.span();
        let slack = samples::END_TOLERANCE_S;
        if first_s < start - slack {
            return Err(LogError::bare(format!(
                "the frames start {:.3} s before the log's attitude does ({first_s:.3} s against {start:.3} s on the log's clock): check the camera-to-log time offset",
                start - first_s
            )));
        }
        if last_s > end + slack {
            return Err(LogError::bare(format!(
                "the frames go on {:.3} s after the log's attitude ends ({last_s:.3} s against {end:.3} s on the log's clock): check the camera-to-log time offset",
                last_s - end
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod real_logs_tests;
