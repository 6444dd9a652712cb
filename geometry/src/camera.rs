//! The pinhole camera: intrinsics, mount on the body, projection and rays.
//!
//! Camera frame is optical: x right, y down, z forward along the optical axis.

use nalgebra::{Isometry3, Matrix3, Point2, Point3, Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::frames::Pose;

/// Pinhole intrinsics in pixels; no distortion (frames are undistorted upstream).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// Square pixels, principal point at the image centre, from a horizontal field of view.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Self {
        let f = f64::from(width) / 2.0 / (hfov_deg.to_radians() / 2.0).tan();
        Self {
            width,
            height,
            fx: f,
            fy: f,
            cx: f64::from(width) / 2.0,
            cy: f64::from(height) / 2.0,
        }
    }

    /// The same camera at `factor` times the resolution (0.5: half size).
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            width: ((f64::from(self.width) * factor).ceil() as u32).max(1),
            height: ((f64::from(self.height) * factor).ceil() as u32).max(1),
            fx: self.fx * factor,
            fy: self.fy * factor,
            cx: self.cx * factor,
            cy: self.cy * factor,
        }
    }

    pub fn contains(&self, pixel: &Point2<f64>) -> bool {
        pixel.x >= 0.0
            && pixel.y >= 0.0
            && pixel.x <= f64::from(self.width)
            && pixel.y <= f64::from(self.height)
    }
}

/// How the camera sits on the body: tilt up (positive) or down about the body's left axis.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct CameraMount {
    pub pitch: f64,
}

impl CameraMount {
    pub fn body_from_camera(&self) -> UnitQuaternion<f64> {
        // Columns: the camera's right, down and forward axes written in FLU.
        let optical_in_flu = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        let base =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(optical_in_flu));
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -self.pitch) * base
    }
}

/// See [`PinholeCamera::ray_grid`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayGrid {
    pub at_origin: Vector3<f64>,
    pub per_u: Vector3<f64>,
    pub per_v: Vector3<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PinholeCamera {
    pub intrinsics: Intrinsics,
    pub mount: CameraMount,
}

impl PinholeCamera {
    /// The paper's camera: 1280x720 with a 70 degree horizontal field of view, level mount.
    pub fn default_hd() -> Self {
        Self {
            intrinsics: Intrinsics::from_hfov(1280, 720, 70.0),
            mount: CameraMount::default(),
        }
    }

    pub fn world_from_camera(&self, pose: &Pose) -> Isometry3<f64> {
        let world_from_body = pose.world_from_body();
        Isometry3::from_parts(
            world_from_body.translation,
            world_from_body.rotation * self.mount.body_from_camera(),
        )
    }

    /// Pixel of a point in the camera frame; `None` behind or on the image plane.
    pub fn project(&self, point_in_camera: &Point3<f64>) -> Option<Point2<f64>> {
        if point_in_camera.z <= 1e-6 {
            return None;
        }
        let k = &self.intrinsics;
        Some(Point2::new(
            k.cx + k.fx * point_in_camera.x / point_in_camera.z,
            k.cy + k.fy * point_in_camera.y / point_in_camera.z,
        ))
    }

    /// Ray through a pixel in the camera frame, scaled so that z = 1.
    pub fn ray(&self, pixel: &Point2<f64>) -> Vector3<f64> {
        let k = &self.intrinsics;
        Vector3::new((pixel.x - k.cx) / k.fx, (pixel.y - k.cy) / k.fy, 1.0)
    }

    /// World-frame rays for every pixel at once: `ray(u, v) = at_origin + u * per_u + v * per_v`
    /// (unnormalised, the camera-frame ray with z = 1 rotated into the world).
    /// Renderers step along a row by adding `per_u`, with no per-pixel matrix product.
    pub fn ray_grid(&self, world_from_camera: &Isometry3<f64>) -> RayGrid {
        let k = &self.intrinsics;
        let r = world_from_camera.rotation.to_rotation_matrix();
        let m = r.matrix();
        let per_u: Vector3<f64> = m.column(0) / k.fx;
        let per_v: Vector3<f64> = m.column(1) / k.fy;
        RayGrid {
            at_origin: m.column(2) - per_u * k.cx - per_v * k.cy,
            per_u,
            per_v,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::Attitude;
    use proptest::prelude::*;

    #[test]
    fn level_camera_looks_along_body_forward() {
        let cam = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(std::f64::consts::FRAC_PI_2),
        };
        let world_from_camera = cam.world_from_camera(&pose);
        let axis = world_from_camera.rotation * Vector3::z();
        assert!(
            (axis - Vector3::y()).norm() < 1e-12,
            "optical axis must point north"
        );
        let down = world_from_camera.rotation * Vector3::y();
        assert!(
            (down + Vector3::z()).norm() < 1e-12,
            "image down must be world down"
        );
    }

    #[test]
    fn point_ahead_projects_to_principal_point() {
        let cam = PinholeCamera::default_hd();
        let px = cam.project(&Point3::new(0.0, 0.0, 50.0)).expect("in front");
        assert!((px.x - 640.0).abs() < 1e-9 && (px.y - 360.0).abs() < 1e-9);
        assert!(cam.project(&Point3::new(0.0, 0.0, -5.0)).is_none());
    }

    proptest! {
        #[test]
        fn ray_inverts_projection(x in -50.0f64..50.0, y in -50.0f64..50.0, z in 1.0f64..500.0) {
            let cam = PinholeCamera::default_hd();
            let p = Point3::new(x, y, z);
            let px = cam.project(&p).expect("z > 0");
            let back = cam.ray(&px) * z;
            prop_assert!((back - p.coords).norm() < 1e-6);
        }
    }

    proptest! {
        #[test]
        fn ray_grid_matches_the_per_pixel_ray(
            u in 0.0f64..1280.0, v in 0.0f64..720.0,
            roll in -0.5f64..0.5, pitch in -0.5f64..0.5, yaw in -3.1f64..3.1,
        ) {
            let cam = PinholeCamera::default_hd();
            let pose = Pose {
                position_in_world: Point3::new(1.0, 2.0, 30.0),
                attitude: Attitude { roll, pitch, yaw },
            };
            let world_from_camera = cam.world_from_camera(&pose);
            let grid = cam.ray_grid(&world_from_camera);
            let direct = world_from_camera.rotation * cam.ray(&Point2::new(u, v));
            let stepped = grid.at_origin + grid.per_u * u + grid.per_v * v;
            prop_assert!((direct - stepped).norm() < 1e-9);
        }
    }
}
