//! Where each frame's attitude comes from: the frame source (the simulator's
//! IMU), a CSV log, or the autopilot's MAVLink ATTITUDE messages.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::MavConnection;
use mavlink::dialects::common::MavMessage;
use towernav_geometry::{Attitude, wrap_angle};

#[derive(Debug, thiserror::Error)]
pub enum AttitudeError {
    #[error("attitude log {path}, line {line}: {reason}")]
    Log {
        path: PathBuf,
        line: u64,
        reason: String,
    },
    #[error("attitude log {path}: {reason}")]
    LogFile { path: PathBuf, reason: String },
    #[error("MAVLink attitude input {address}: {reason}")]
    Mavlink { address: String, reason: String },
}

/// A CSV attitude log: `time_s,roll_deg,pitch_deg,heading_deg` (heading
/// clockwise from north, as autopilots log it), sorted by time.
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudeLog {
    samples: Vec<(f64, Attitude)>,
}

#[derive(serde::Deserialize)]
struct Row {
    time_s: f64,
    roll_deg: f64,
    pitch_deg: f64,
    heading_deg: f64,
}

impl AttitudeLog {
    pub fn read(path: &Path) -> Result<Self, AttitudeError> {
        let file = std::fs::File::open(path).map_err(|e| AttitudeError::LogFile {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let mut samples: Vec<(f64, Attitude)> = Vec::new();
        for (i, row) in csv::Reader::from_reader(file)
            .deserialize::<Row>()
            .enumerate()
        {
            let line = i as u64 + 2;
            let bad = |reason: String| AttitudeError::Log {
                path: path.to_path_buf(),
                line,
                reason,
            };
            let r = row.map_err(|e| bad(e.to_string()))?;
            if ![r.time_s, r.roll_deg, r.pitch_deg, r.heading_deg]
                .iter()
                .all(|v| v.is_finite())
            {
                return Err(bad("a value is not a finite number".into()));
            }
            if samples.last().is_some_and(|(t, _)| r.time_s <= *t) {
                return Err(bad(format!("time {} does not increase", r.time_s)));
            }
            samples.push((
                r.time_s,
                Attitude::from_ned(
                    r.roll_deg.to_radians(),
                    r.pitch_deg.to_radians(),
                    r.heading_deg.to_radians(),
                ),
            ));
        }
        if samples.is_empty() {
            return Err(AttitudeError::LogFile {
                path: path.to_path_buf(),
                reason: "it has no rows (header: time_s,roll_deg,pitch_deg,heading_deg)".into(),
            });
        }
        Ok(Self { samples })
    }

    /// Attitude at `time_s`, interpolated (yaw the short way round); `None`
    /// outside the log.
    pub fn at(&self, time_s: f64) -> Option<Attitude> {
        let i = self.samples.partition_point(|(t, _)| *t < time_s);
        match (
            i.checked_sub(1).map(|j| self.samples[j]),
            self.samples.get(i),
        ) {
            (_, Some((t, a))) if *t == time_s => Some(*a),
            (Some((t0, a0)), Some((t1, a1))) => {
                let f = (time_s - t0) / (t1 - t0);
                Some(Attitude {
                    roll: a0.roll + f * (a1.roll - a0.roll),
                    pitch: a0.pitch + f * (a1.pitch - a0.pitch),
                    yaw: wrap_angle(a0.yaw + f * wrap_angle(a1.yaw - a0.yaw)),
                })
            }
            _ => None,
        }
    }
}

/// The latest ATTITUDE an autopilot sent, read on a thread of its own.
#[derive(Clone)]
pub struct MavlinkAttitude {
    latest: Arc<Mutex<Option<(Instant, Attitude)>>>,
}

impl MavlinkAttitude {
    /// Listen at `address` (e.g. `udpin:127.0.0.1:14551`).
    pub fn listen(address: &str) -> Result<Self, AttitudeError> {
        let conn = mavlink::connect::<MavMessage>(address).map_err(|e| AttitudeError::Mavlink {
            address: address.to_string(),
            reason: e.to_string(),
        })?;
        let latest = Arc::new(Mutex::new(None));
        let sink = latest.clone();
        let address = address.to_string();
        std::thread::Builder::new()
            .name("mavlink-attitude".into())
            .spawn(move || {
                loop {
                    match conn.recv() {
                        Ok((_, MavMessage::ATTITUDE(a))) => {
                            let attitude = Attitude::from_ned(
                                f64::from(a.roll),
                                f64::from(a.pitch),
                                f64::from(a.yaw),
                            );
                            *sink.lock().unwrap_or_else(|p| p.into_inner()) =
                                Some((Instant::now(), attitude));
                        }
                        Ok(_) => {}
                        Err(mavlink::error::MessageReadError::Io(e))
                            if e.kind() != std::io::ErrorKind::WouldBlock =>
                        {
                            tracing::warn!(%address, error = %e, "MAVLink attitude input closed");
                            return;
                        }
                        Err(_) => {}
                    }
                }
            })
            .map_err(|e| AttitudeError::Mavlink {
                address: "thread".into(),
                reason: e.to_string(),
            })?;
        Ok(Self { latest })
    }

    /// The latest attitude if it is younger than `max_age`.
    pub fn latest(&self, max_age: Duration) -> Option<Attitude> {
        let latest = *self.latest.lock().unwrap_or_else(|p| p.into_inner());
        latest.and_then(|(at, a)| (at.elapsed() <= max_age).then_some(a))
    }
}

/// The configured attitude input.
pub enum AttitudeSource {
    /// The frame source stamps each frame (the simulator).
    Frames,
    Log(AttitudeLog),
    Mavlink(MavlinkAttitude),
}

impl AttitudeSource {
    /// Attitude for a frame at `time_s`, given what the frame itself carries.
    pub fn attitude(&self, time_s: f64, from_frame: Option<Attitude>) -> Option<Attitude> {
        match self {
            Self::Frames => from_frame,
            Self::Log(log) => log.at(time_s),
            Self::Mavlink(m) => m.latest(Duration::from_millis(500)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_interpolates_and_converts_heading() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("att.csv");
        std::fs::write(
            &path,
            "time_s,roll_deg,pitch_deg,heading_deg\n0,0,0,350\n1,10,-4,10\n",
        )
        .expect("write");
        let log = AttitudeLog::read(&path).expect("reads");
        let mid = log.at(0.5).expect("inside");
        assert!((mid.roll.to_degrees() - 5.0).abs() < 1e-9);
        assert!((mid.pitch.to_degrees() + 2.0).abs() < 1e-9);
        assert!(
            mid.yaw_from_north().abs() < 1e-9,
            "350 to 10 passes through north"
        );
        assert!(log.at(1.5).is_none());
    }

    #[test]
    fn a_bad_log_line_is_named() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("att.csv");
        std::fs::write(
            &path,
            "time_s,roll_deg,pitch_deg,heading_deg\n0,0,0,0\n0,1,1,1\n",
        )
        .expect("write");
        let err = AttitudeLog::read(&path)
            .expect_err("time repeats")
            .to_string();
        assert!(
            err.contains("line 3") && err.contains("does not increase"),
            "{err}"
        );
        std::fs::write(&path, "time_s,roll_deg,pitch_deg,heading_deg\n0,x,0,0\n").expect("write");
        let err = AttitudeLog::read(&path)
            .expect_err("not a number")
            .to_string();
        assert!(err.contains("line 2"), "{err}");
    }
}
