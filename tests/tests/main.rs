//! The cross-crate tests, one module per concern, in one binary.

mod aarch64;
mod autopilot_link;
mod coco_start;
mod debian_package;
mod detector;
mod edge_daemon;
mod fleet;
mod fleet_attacks;
mod fleet_security;
mod flight_logs;
mod flight_replay;
mod gopro_telemetry;
mod ground_station_net;
mod invariants;
mod landmark_import;
mod landmark_sync;
mod lens;
mod localization;
mod onnx_reid;
mod pipeline;
mod real_data;
mod replay;
mod sim_source;
mod tracking;
mod training_mix;
mod video_source;
