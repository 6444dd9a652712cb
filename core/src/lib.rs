//! The edge's pure core, in the manner of quinn-proto and str0m: everything
//! between a frame's pixels and the messages that leave the UAV, with time
//! passed in and no I/O. Detector pre- and post-processing (`detector`), the
//! trackers (`tracker`), tower identity (`identity`), the localizers
//! (`localizer`) and the filter (`filter`), chained per frame by `pipeline`;
//! the landmark replica (`replica`), the messages the daemon sends (`wire`,
//! `autopilot`), and the daemon's logic between frames (`daemon`).
//!
//! Its `Cargo.toml` has no tokio, zenoh, ort, simulator, SQLite or plotting
//! dependency: the shells in `towernav-onnx` and `towernav-edge` do the I/O.

pub mod assignment;
pub mod autopilot;
pub mod autopilot_link;
pub mod daemon;
pub mod detector;
pub mod filter;
pub mod fix_keeper;
pub mod flight_record;
pub mod identity;
pub mod landmarks;
pub mod localizer;
pub mod log_limit;
pub mod optical_flow;
pub mod pipeline;
pub mod replica;
pub mod ros_link;
pub mod survey_labels;
pub mod tower_map;
pub mod tracker;
pub mod unix_clock;
pub mod wire;

#[cfg(test)]
mod fixtures;
#[cfg(test)]
mod pipeline_tests;

pub use landmarks::{LandmarkMap, MapTower, TypeMatch, TypeMismatch, match_types};
pub use pipeline::{BoundTrack, FrameOutput, Pipeline, PipelineConfig};
