//! The one home for towernav's geometry: frames and attitude, the pinhole
//! camera, pixel boxes and WGS84 geodesy.
//!
//! Conventions (see ARCHITECTURE.md): the world is east-north-up (ENU) about a
//! geodetic datum, the body is forward-left-up (FLU), the camera is the optical
//! frame (x right, y down, z forward). Transforms are named `a_from_b`.

pub mod camera;
pub mod frames;
pub mod geodesy;
pub mod pixel_box;

pub use camera::{CameraMount, Intrinsics, PinholeCamera, RayGrid};
pub use frames::{Attitude, Pose, wrap_angle};
pub use geodesy::{Datum, Geodetic};
pub use pixel_box::PixelBox;
