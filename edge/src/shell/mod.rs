//! The imperative shell: Zenoh sessions, clocks and pacing around the pure core.

pub mod collector;
pub mod detector_eval_cmd;
pub mod error;
pub mod landmark_sync;
pub mod landmarks_source;
pub mod loc_eval_cmd;
pub mod loc_plots;
pub mod node;
pub mod onnx;
pub mod progress;
pub mod rendered_detector;
pub mod sim_flight;
pub mod tracking_eval_cmd;
pub mod yolo;

pub use error::ShellError;
