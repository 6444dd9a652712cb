//! Multi-object tracking of detector boxes, behind one interface (`Tracker`):
//! SORT, ByteTrack-style, each with camera-motion compensation from the IMU.

pub mod bytetrack;
pub mod cmc;
pub mod common;
pub mod kalman;
pub mod sort;

pub use bytetrack::{ByteParams, ByteTracker};
pub use cmc::CameraMotion;
pub use common::{TrackOutput, Tracker, TrackerInput};
pub use sort::{SortParams, SortTracker};
