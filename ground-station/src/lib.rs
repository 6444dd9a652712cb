//! The ground station: owns the landmark database and shows the fleet live.
//!
//! The UI thread never touches the network: `net` runs Zenoh on its own thread
//! and hands decoded messages over a channel, waking the UI with `request_repaint`.

pub mod app;
pub mod fleet;
pub mod landmark_service;
pub mod net;
#[cfg(test)]
mod test_support;
