//! The onboard daemon: the thin tokio, Zenoh and ONNX Runtime shell around
//! `towernav-core`. Frame sources, the detector worker, the Zenoh node, the
//! landmark sync, MAVLink out, and the loop that drives the core's
//! `DaemonCore` with frames, commands and its timer.
//!
//! Behind the `demo` feature: the simulated source, the demo's pose collector
//! and report, and the eval commands.

pub mod coco_import;
pub mod daemon;
pub mod edge_cmd;
pub mod error;
pub mod landmark_sync;
pub mod map_towers;
#[cfg(not(feature = "demo"))]
pub mod no_sim;
pub mod node;
pub mod peak_rss;
pub mod replay;
pub mod survey;

#[cfg(feature = "demo")]
pub mod collector;
#[cfg(feature = "demo")]
pub mod demo;

pub use error::ShellError;
