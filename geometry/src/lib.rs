//! The one home for towernav's geometry: frames and attitude, the camera
//! (pinhole intrinsics, lens distortion, calibration files, mount), pixel boxes, WGS84 geodesy and the EGM96 geoid, the index of points within a radius and
//! Web Mercator map tiles.
//!
//! Conventions (see ARCHITECTURE.md): the world is east-north-up (ENU) about a
//! geodetic datum, the body is forward-left-up (FLU), the camera is the optical
//! frame (x right, y down, z forward). Transforms are named `a_from_b`.

pub mod calibration;
pub mod camera;
pub mod distortion;
pub mod frame_camera;
pub mod frames;
pub mod geodesy;
pub mod geoid;
pub mod image_edge;
pub mod pixel_box;
pub mod spatial;
pub mod undistorted_view;
pub mod vertical_plane;
pub mod web_mercator;

pub use calibration::{Calibration, CalibrationError};
pub use camera::{CameraMount, Intrinsics, PinholeCamera, RayGrid};
pub use distortion::Distortion;
pub use frame_camera::{FrameCamera, Projected};
pub use frames::{Attitude, Pose, wrap_angle};
pub use geodesy::{Datum, Geodetic};
pub use geoid::{GeoidCache, geoid_height_m, msl_from_ellipsoid_m};
pub use image_edge::{Cut, EDGE_MARGIN_PX};
pub use pixel_box::PixelBox;
pub use spatial::GeoIndex;
pub use undistorted_view::UndistortedView;
