//! The ground station: owns the landmark database and shows the fleet live.
//!
//! The UI thread never touches the network: `net` runs Zenoh on its own thread
//! and hands decoded messages over a channel, waking the UI with `request_repaint`.
//! The state the UI draws (`fleet`, `corrections`) is pure and clock-free.

pub mod app;
pub mod camera_view;
pub mod corrections;
pub mod events;
pub mod file_browser;
pub mod fleet;
pub mod fleet_panel;
pub mod label_review;
pub mod label_review_view;
pub mod landmark_editor;
pub mod landmark_service;
pub mod map_view;
pub mod net;
pub mod recording;
pub mod session_bar;
pub mod survey_review;
pub mod survey_review_view;
#[cfg(any(test, feature = "test-support"))]
pub mod test_support;
pub mod tiles;
