//! Estimates to the autopilot over MAVLink (UDP, or serial), at a set rate.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mavlink::dialects::common::MavMessage;
use mavlink::{MavConnection, MavHeader};
use towernav_geometry::Attitude;
use towernav_protocol::{EdgeState, PoseEstimate};

use super::config::{MavlinkMessages, MavlinkSection};
use towernav_core::autopilot::{gps_input, odometry};

#[derive(Debug, thiserror::Error)]
#[error("MAVLink output {address}: {reason}")]
pub struct MavlinkError {
    pub address: String,
    pub reason: String,
}

pub struct MavlinkOut {
    conn: Box<dyn MavConnection<MavMessage> + Send + Sync>,
    address: String,
    messages: MavlinkMessages,
    every: Duration,
    last: Option<Instant>,
    header: MavHeader,
    pub sent: u64,
}

impl MavlinkOut {
    pub fn open(config: &MavlinkSection) -> Result<Self, MavlinkError> {
        let conn = mavlink::connect::<MavMessage>(&config.address).map_err(|e| MavlinkError {
            address: config.address.clone(),
            reason: e.to_string(),
        })?;
        Ok(Self {
            conn: Box::new(conn),
            address: config.address.clone(),
            messages: config.messages,
            every: Duration::from_secs_f64(1.0 / config.rate_hz),
            last: None,
            // A companion computer's component id (MAV_COMP_ID_ONBOARD_COMPUTER).
            header: MavHeader {
                system_id: config.system_id.into(),
                component_id: 191,
                sequence: 0,
            },
            sent: 0,
        })
    }

    /// Send `pose` if the rate allows; returns whether it went out.
    pub fn offer(
        &mut self,
        pose: &PoseEstimate,
        state: EdgeState,
        attitude: &Attitude,
    ) -> Result<bool, MavlinkError> {
        if self.last.is_some_and(|t| t.elapsed() < self.every) {
            return Ok(false);
        }
        self.last = Some(Instant::now());
        let now_us = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as u64);
        let mut out = Vec::with_capacity(2);
        if matches!(
            self.messages,
            MavlinkMessages::GpsInput | MavlinkMessages::Both
        ) {
            out.push(MavMessage::GPS_INPUT(gps_input(pose, state, now_us)));
        }
        if matches!(
            self.messages,
            MavlinkMessages::Odometry | MavlinkMessages::Both
        ) {
            out.push(MavMessage::ODOMETRY(odometry(pose, attitude, now_us)));
        }
        for message in &out {
            self.header.sequence = self.header.sequence.wrapping_add(1);
            self.conn
                .send(&self.header, message)
                .map_err(|e| MavlinkError {
                    address: self.address.clone(),
                    reason: e.to_string(),
                })?;
            self.sent += 1;
        }
        Ok(true)
    }
}
