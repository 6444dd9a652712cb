//! Rays to the top and foot of an upright object in a banked frame.
//!
//! A detector's box is upright in the image, but a tower in a rolled frame
//! leans: its apex sits at one end of the box's top row and its foot at the
//! other end of the bottom row, not at the centre column. A ray through the
//! centre column of the top row misses the apex by `h/2 * tan(roll)` pixels
//! sideways, which in a rolled camera is also up or down: the height read
//! from it errs by about `tan(roll) * sin(roll)` of itself (7 % at 15 degrees).
//! The apex and the foot lie in the vertical plane through the camera and
//! the box's centre, so each is taken where that plane crosses its row.

use nalgebra::{Point2, Vector3};

use crate::PinholeCamera;

impl PinholeCamera {
    /// The ray (camera frame, lens undone) to the pixel of image row `row`
    /// that lies in the vertical plane through the camera and the ray
    /// `through`, where `up_in_camera` is the world's up in the camera
    /// frame. The search starts at `start_column` (the box's centre column).
    /// `None` where the plane runs along the row (the camera looking straight
    /// up or down) or the search leaves the lens model's domain.
    pub fn ray_on_row_in_vertical_plane(
        &self,
        through: &Vector3<f64>,
        up_in_camera: &Vector3<f64>,
        row: f64,
        start_column: f64,
    ) -> Option<Vector3<f64>> {
        let normal = through.cross(up_in_camera);
        if normal.norm() < 1e-12 {
            return None;
        }
        let normal = normal.normalize();
        let off_plane = |u: f64| {
            let ray = self.ray(&Point2::new(u, row));
            normal.dot(&ray) / ray.norm()
        };
        // Newton's method on the column, with a central difference: the
        // lens makes the ray a smooth but not a closed-form function of it.
        let mut u = start_column;
        for _ in 0..12 {
            let step = 0.5;
            let slope = (off_plane(u + step) - off_plane(u - step)) / (2.0 * step);
            if !slope.is_finite() || slope.abs() < 1e-9 {
                return None;
            }
            let du = off_plane(u) / slope;
            if !du.is_finite() {
                return None;
            }
            u -= du;
            if du.abs() < 1e-4 {
                return Some(self.ray(&Point2::new(u, row)));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point2, Point3, Vector3};
    use proptest::prelude::*;

    use crate::camera::tests::lenses;
    use crate::{Attitude, Pose};

    proptest! {
        /// A tower in front of a banked, pitched camera: the rays found on
        /// its top and foot rows through its middle are the rays to its apex
        /// and foot, for each lens, while the box's centre column misses
        /// them once the frame is rolled.
        #[test]
        fn the_apex_and_foot_rays_lie_on_their_rows_in_the_towers_plane(
            roll in -0.5f64..0.5, pitch in -0.3f64..0.1, yaw in -3.0f64..3.0,
            range in 40.0f64..400.0, across in -0.3f64..0.3, height in 15.0f64..50.0,
        ) {
            for camera in lenses() {
                let attitude = Attitude { roll, pitch, yaw };
                let pose = Pose { position_in_world: Point3::new(0.0, 0.0, 30.0), attitude };
                let world_from_camera = camera.world_from_camera(&pose);
                let camera_from_world = world_from_camera.inverse();
                // The tower stands where the optical axis points, a little aside.
                let ahead = world_from_camera.rotation * Vector3::z();
                let bearing = ahead.y.atan2(ahead.x) + across;
                let foot = Point3::new(range * bearing.cos(), range * bearing.sin(), 0.0);
                let top = foot + Vector3::z() * height;
                let middle = foot + Vector3::z() * (height / 2.0);
                let in_camera = |p: &Point3<f64>| camera_from_world * p;
                let (Some(foot_px), Some(top_px), Some(mid_px)) = (
                    camera.project(&in_camera(&foot)),
                    camera.project(&in_camera(&top)),
                    camera.project(&in_camera(&middle)),
                ) else {
                    continue;
                };
                let up = camera_from_world.rotation * Vector3::z();
                let through = camera.ray(&mid_px);
                for (px, point) in [(top_px, top), (foot_px, foot)] {
                    let ray = camera
                        .ray_on_row_in_vertical_plane(&through, &up, px.y, mid_px.x)
                        .expect("a ray");
                    let truth = in_camera(&point).coords;
                    let angle = ray.angle(&truth);
                    prop_assert!(angle < 1e-6, "{:?}: off by {angle} rad", camera.distortion);
                }
                // The centre column's ray to the apex row, for comparison.
                let centre_top = camera.ray(&Point2::new(mid_px.x, top_px.y));
                let lean = (top_px.x - mid_px.x).abs();
                if lean > 5.0 {
                    prop_assert!(centre_top.angle(&in_camera(&top).coords) > 1e-3);
                }
            }
        }
    }
}
