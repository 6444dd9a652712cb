//! The binary's flags.

#[cfg(feature = "demo")]
pub mod detector_args;
#[cfg(feature = "demo")]
pub mod eval_command;
#[cfg(feature = "demo")]
pub mod label_command;
#[cfg(feature = "demo")]
pub mod map_towers_command;
#[cfg(feature = "demo")]
pub mod recording_args;
#[cfg(feature = "demo")]
pub mod replay_command;
pub mod run_args;
