//! Multi-object tracking of detector boxes.

pub mod kalman;
pub mod sort;

pub use sort::{SortParams, SortTracker, TrackOutput};
