//! The onboard pipeline.
//!
//! The core (`tracker`, `identity`, `localizer`, `filter`, `landmarks`, `pipeline`,
//! `sim_eval`, `wire`) is pure and deterministic: time comes in with each frame,
//! and it imports no tokio, zenoh or ort. `shell` drives it over Zenoh.

pub mod assignment;
pub mod autopilot;
pub mod detector;
pub mod filter;
pub mod identity;
pub mod landmarks;
pub mod loc_eval;
pub mod localizer;
pub mod mot_metrics;
pub mod pipeline;
pub mod replica;
pub mod report;
pub mod shell;
pub mod sim_eval;
pub mod tracker;
pub mod tracking_eval;
pub mod wire;

pub use landmarks::{LandmarkMap, MapTower};
pub use pipeline::{BoundTrack, FrameOutput, Pipeline, PipelineConfig};
