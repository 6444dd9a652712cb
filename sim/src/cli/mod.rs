//! The command-line shell around the simulator: files, images, progress bars.

pub mod contact_sheet;
pub mod dataset;
pub mod flight_cmd;
pub mod flight_dataset;
pub mod mot;
pub mod overlay;
pub mod photos;
pub mod progress;
pub mod tlog;
pub mod video;
