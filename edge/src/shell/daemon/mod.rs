//! The onboard daemon: a frame source on its own thread, a bounded queue that
//! drops the oldest frame when the pipeline falls behind, the detector and the
//! pure pipeline on a blocking worker thread, and a tokio task that publishes
//! on Zenoh, talks MAVLink, logs, and takes corrections and landmark changes.

pub mod attitude;
pub mod config;
pub mod mavlink_out;
pub mod queue;
pub mod run;
pub mod source;
pub mod worker;
