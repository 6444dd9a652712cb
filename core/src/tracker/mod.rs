//! Multi-object tracking of detector boxes, behind one interface (`Tracker`):
//! SORT, ByteTrack-style and DeepSORT, each with camera-motion compensation
//! from the IMU, and the paper's timeline correction on top of any of them.

pub mod appearance;
pub mod bytetrack;
pub mod cmc;
pub mod common;
pub mod deepsort;
pub mod kalman;
pub mod sort;
pub mod timeline;

pub use bytetrack::{ByteParams, ByteTracker};
pub use cmc::CameraMotion;
pub use common::{TrackOutput, Tracker, TrackerInput};
pub use deepsort::{DeepSortParams, DeepSortTracker};
pub use sort::{SortParams, SortTracker};
pub use timeline::{TimelineCorrection, TimelineParams};
