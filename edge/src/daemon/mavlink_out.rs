//! The MAVLink link's I/O (UDP, or serial): sends what the core's
//! `AutopilotLink` queues, and hands what the autopilot sends back to the loop.

use std::sync::Arc;

use mavlink::dialects::common::MavMessage;
use mavlink::{MavConnection, MavHeader};
use tokio::sync::mpsc;

use super::config::MavlinkSection;

#[derive(Debug, thiserror::Error)]
#[error("MAVLink link {address}: {reason}")]
pub struct MavlinkError {
    pub address: String,
    pub reason: String,
}

type Connection = Arc<dyn MavConnection<MavMessage> + Send + Sync>;

/// A message from the link, with its sender's system and component id.
pub type Received = ((u8, u8), MavMessage);

pub struct MavlinkOut {
    conn: Connection,
    address: String,
    header: MavHeader,
    pub sent: u64,
}

impl MavlinkOut {
    /// Opens the link; the autopilot's messages arrive on the returned channel
    /// (read on a thread of its own, as the connection blocks).
    pub fn open(config: &MavlinkSection) -> Result<(Self, mpsc::Receiver<Received>), MavlinkError> {
        let conn = mavlink::connect::<MavMessage>(&config.address).map_err(|e| MavlinkError {
            address: config.address.clone(),
            reason: e.to_string(),
        })?;
        let conn: Connection = Arc::new(conn);
        let (tx, rx) = mpsc::channel(64);
        let reader = conn.clone();
        std::thread::Builder::new()
            .name("mavlink-in".into())
            .spawn(move || read_loop(reader, tx))
            .map_err(|e| MavlinkError {
                address: config.address.clone(),
                reason: format!("starting its reader: {e}"),
            })?;
        Ok((
            Self {
                conn,
                address: config.address.clone(),
                header: MavHeader {
                    system_id: config.system_id.into(),
                    component_id: config.component_id,
                    sequence: 0,
                },
                sent: 0,
            },
            rx,
        ))
    }

    /// Sends one message with the next sequence number.
    pub fn send(&mut self, message: &MavMessage) -> Result<(), MavlinkError> {
        self.conn
            .send(&self.header, message)
            .map_err(|e| MavlinkError {
                address: self.address.clone(),
                reason: e.to_string(),
            })?;
        self.header.sequence = self.header.sequence.wrapping_add(1);
        self.sent += 1;
        Ok(())
    }
}

/// Forwards the autopilot's messages until the loop stops listening. Bad
/// frames (CRC, unknown ids) are skipped as the parser resynchronises; a
/// link that keeps failing is told once, not per frame.
fn read_loop(conn: Connection, tx: mpsc::Sender<Received>) {
    let mut failures = 0u64;
    loop {
        match conn.recv() {
            Ok((header, message)) => {
                failures = 0;
                // MAVLink system ids are one byte on the wire.
                let from = (
                    u8::try_from(header.system_id).unwrap_or(0),
                    header.component_id,
                );
                // Full: the loop is behind; dropping an old TIMESYNC is harmless.
                match tx.try_send((from, message)) {
                    Ok(()) | Err(mpsc::error::TrySendError::Full(_)) => {}
                    Err(mpsc::error::TrySendError::Closed(_)) => return,
                }
            }
            Err(e) => {
                failures += 1;
                if failures == 100 {
                    tracing::warn!(error = %e, "MAVLink input keeps failing");
                }
                if tx.is_closed() {
                    return;
                }
                if failures > 100 {
                    std::thread::sleep(std::time::Duration::from_millis(100));
                }
            }
        }
    }
}
