//! The onboard daemon: a frame source on its own thread, a bounded queue that
//! drops the oldest frame when the detector falls behind, the detector on a
//! blocking worker thread, and a tokio loop (`run.rs`) that feeds the core's
//! `DaemonCore` with detected frames, the operator's corrections, landmark
//! changes and its timer, and sends what it returns over Zenoh and MAVLink.

pub mod attitude;
pub mod config;
pub mod frame_times;
pub mod jsonl_log;
pub mod mavlink_out;
pub mod queue;
pub mod ros2_config;
pub mod ros2_out;
pub mod run;
#[cfg(feature = "demo")]
pub mod sim_source;
pub mod source;
pub mod worker;
