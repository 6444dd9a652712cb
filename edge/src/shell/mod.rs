//! The imperative shell: Zenoh sessions, clocks and pacing around the pure core.

pub mod annotate;
pub mod collector;
pub mod daemon;
pub mod demo_plots;
pub mod detector_eval_cmd;
pub mod edge_cmd;
pub mod error;
pub mod flight_record;
pub mod landmark_sync;
pub mod loc_eval_cmd;
pub mod loc_plots;
pub mod node;
pub mod onnx;
pub mod progress;
pub mod tracking_eval_cmd;
pub mod type_classifier;
pub mod yolo;

pub use error::ShellError;
