//! Camera-motion compensation from the IMU: when the camera turns, distant
//! towers move in the image although they stand still. Between two frames the
//! rotation `camera_now_from_camera_before` maps each pixel as a homography
//! (towers are far compared with how far the UAV moves in a frame).

use nalgebra::{Point2, Point3, UnitQuaternion};
use towernav_geometry::{Attitude, PinholeCamera, PixelBox, Pose};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMotion {
    camera: PinholeCamera,
    now_from_before: UnitQuaternion<f64>,
}

impl CameraMotion {
    pub fn between(camera: &PinholeCamera, before: &Attitude, now: &Attitude) -> Self {
        let rotation = |a: &Attitude| {
            camera
                .world_from_camera(&Pose {
                    position_in_world: Point3::origin(),
                    attitude: *a,
                })
                .rotation
        };
        Self {
            camera: *camera,
            now_from_before: rotation(now).inverse() * rotation(before),
        }
    }

    /// Where a pixel of the earlier frame appears now; `None` if it turned behind the camera.
    pub fn warp_point(&self, pixel: &Point2<f64>) -> Option<Point2<f64>> {
        let ray = self.now_from_before * self.camera.ray(pixel);
        self.camera.project(&Point3::from(ray))
    }

    /// A box of the earlier frame as it appears now: the box around its warped corners.
    pub fn warp_box(&self, b: &PixelBox) -> Option<PixelBox> {
        let corners = [
            Point2::new(b.left, b.top),
            Point2::new(b.right, b.top),
            Point2::new(b.left, b.bottom),
            Point2::new(b.right, b.bottom),
        ];
        let warped: Option<Vec<Point2<f64>>> = corners.iter().map(|c| self.warp_point(c)).collect();
        PixelBox::enclosing(warped?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turn_moves_a_distant_tower_where_the_camera_says() {
        let camera = PinholeCamera::default_hd();
        let before = Attitude::level(0.0);
        let now = Attitude::level(2f64.to_radians());
        let pose = |a: Attitude| Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: a,
        };
        let far = Point3::new(400.0, 30.0, 20.0);
        let px = |a: Attitude| {
            camera
                .project(&(camera.world_from_camera(&pose(a)).inverse() * far))
                .expect("ahead")
        };
        let (p0, p1) = (px(before), px(now));
        let warped = CameraMotion::between(&camera, &before, &now)
            .warp_point(&p0)
            .expect("ahead");
        // Turning left by 2 degrees moves the image about 32 px right.
        assert!((p1.x - p0.x) > 30.0);
        assert!((warped - p1).norm() < 1e-6, "{warped} vs {p1}");
        let still = CameraMotion::between(&camera, &before, &before);
        let b = PixelBox::new(100.0, 100.0, 130.0, 300.0);
        let same = still.warp_box(&b).expect("in view");
        assert!((same.left - b.left).abs() < 1e-9 && (same.bottom - b.bottom).abs() < 1e-9);
    }
}
