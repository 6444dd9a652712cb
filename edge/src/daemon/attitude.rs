//! Where each frame's attitude comes from: the frame source (the simulator's
//! IMU), a flight log (ArduPilot `.bin`, MAVLink `.tlog`, PX4 `.ulg`, CSV)
//! on the camera's clock plus an offset, the autopilot's MAVLink
//! ATTITUDE messages, or PX4's `vehicle_attitude` over Zenoh.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::MavConnection;
use mavlink::dialects::common::MavMessage;
use towernav_geometry::Attitude;

#[derive(Debug, thiserror::Error)]
pub enum AttitudeError {
    #[error(transparent)]
    Log(#[from] towernav_flightlog::LogError),
    #[error("MAVLink attitude input {address}: {reason}")]
    Mavlink { address: String, reason: String },
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
    /// A flight log; a frame at camera time `t` takes the log's attitude
    /// at `t + offset_s`.
    Log {
        log: towernav_flightlog::FlightLog,
        offset_s: f64,
    },
    Mavlink(MavlinkAttitude),
    /// PX4's `vehicle_attitude` over the onboard Zenoh.
    Px4(super::ros2_out::Px4Attitude),
}

impl AttitudeSource {
    /// Attitude for a frame at `time_s`, given what the frame itself carries.
    pub fn attitude(&self, time_s: f64, from_frame: Option<Attitude>) -> Option<Attitude> {
        match self {
            Self::Frames => from_frame,
            Self::Log { log, offset_s } => log.attitude_at(time_s + offset_s),
            Self::Mavlink(m) => m.latest(Duration::from_millis(500)),
            Self::Px4(p) => p.latest(Duration::from_millis(500)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_log_on_the_camera_s_clock_is_shifted_by_the_offset() {
        let log = towernav_flightlog::FlightLog::parse(
            towernav_flightlog::LogFormat::Csv,
            b"time_s,roll_deg,pitch_deg,heading_deg\n100,0,0,350\n101,10,-4,10\n",
        )
        .expect("parses");
        let source = AttitudeSource::Log {
            log,
            offset_s: 100.0,
        };
        let mid = source.attitude(0.5, None).expect("inside");
        // Slerp couples the axes: about half the roll, within a fraction of a degree.
        assert!((mid.roll.to_degrees() - 5.0).abs() < 0.5, "{mid:?}");
        assert!(
            mid.yaw_from_north().to_degrees().abs() < 0.5,
            "350 to 10 passes through north"
        );
        assert!(source.attitude(1.5, None).is_none());
    }
}
