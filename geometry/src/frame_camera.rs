//! The camera of one frame with roll and pitch fixed by the IMU and the
//! position and yaw left free: the projection a localizer fits, with its
//! analytic Jacobian with respect to (east, north, up, yaw).

use nalgebra::{Matrix3, Point3, RowVector4, UnitQuaternion, Vector3};

use crate::{Attitude, Intrinsics, PinholeCamera, Pose};

/// The camera for one frame with yaw left free: `camera_from_world = A * Rz(yaw)^T`.
#[derive(Debug, Clone, Copy)]
pub struct FrameCamera {
    pub k: Intrinsics,
    /// Camera-from-level rotation: the mount, roll and pitch together.
    camera_from_level: Matrix3<f64>,
}

impl FrameCamera {
    pub fn new(camera: &PinholeCamera, imu: &Attitude) -> Self {
        let level = Pose {
            position_in_world: Point3::origin(),
            attitude: Attitude { yaw: 0.0, ..*imu },
        };
        let world_from_camera: UnitQuaternion<f64> = camera.world_from_camera(&level).rotation;
        Self {
            k: camera.intrinsics,
            camera_from_level: world_from_camera
                .inverse()
                .to_rotation_matrix()
                .into_inner(),
        }
    }

    /// Pixel of a world point for state (position, yaw), with d(u)/d(state) and
    /// d(v)/d(state), and the point's depth. `None` behind the camera.
    pub fn project(
        &self,
        point_in_world: &Point3<f64>,
        position: &Point3<f64>,
        yaw: f64,
    ) -> Option<Projected> {
        let d = point_in_world - position;
        let (s, c) = yaw.sin_cos();
        let w = Vector3::new(c * d.x + s * d.y, -s * d.x + c * d.y, d.z);
        let p = self.camera_from_level * w;
        if p.z < 0.5 {
            return None;
        }
        let k = &self.k;
        let (iz, iz2) = (1.0 / p.z, 1.0 / (p.z * p.z));
        // d(u, v)/d(camera point).
        let du_dp = Vector3::new(k.fx * iz, 0.0, -k.fx * p.x * iz2);
        let dv_dp = Vector3::new(0.0, k.fy * iz, -k.fy * p.y * iz2);
        // d(camera point)/d(position) = -A Rz^T; d/d(yaw) = A (w.y, -w.x, 0).
        let rz_t = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
        let dp_dpos = -(self.camera_from_level * rz_t);
        let dp_dyaw = self.camera_from_level * Vector3::new(w.y, -w.x, 0.0);
        let row = |g: &Vector3<f64>| {
            let pos = g.transpose() * dp_dpos;
            RowVector4::new(pos[0], pos[1], pos[2], g.dot(&dp_dyaw))
        };
        Some(Projected {
            u: k.cx + k.fx * p.x * iz,
            v: k.cy + k.fy * p.y * iz,
            du: row(&du_dp),
            dv: row(&dv_dp),
            depth: p.z,
        })
    }
}

#[derive(Debug, Clone, Copy)]
pub struct Projected {
    pub u: f64,
    pub v: f64,
    pub du: RowVector4<f64>,
    pub dv: RowVector4<f64>,
    pub depth: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Attitude, PinholeCamera, Pose};
    use proptest::prelude::*;

    proptest! {
        /// The analytic Jacobian agrees with finite differences.
        #[test]
        fn jacobian_matches_finite_differences(
            x in -20.0f64..20.0, y in -20.0f64..20.0, z in 10.0f64..60.0, yaw in -0.3f64..0.3,
            roll in -0.3f64..0.3, pitch in -0.3f64..0.3,
        ) {
            let camera = PinholeCamera::default_hd();
            let fc = FrameCamera::new(&camera, &Attitude { roll, pitch, yaw: 0.0 });
            let target = Point3::new(150.0, 20.0, 25.0);
            let pos = Point3::new(x, y, z);
            let p = fc.project(&target, &pos, yaw).expect("in front");
            let h = 1e-6;
            for i in 0..4 {
                let mut a = pos;
                let mut b = pos;
                let (mut ya, mut yb) = (yaw, yaw);
                if i < 3 { a[i] -= h; b[i] += h; } else { ya -= h; yb += h; }
                let (pa, pb) = (fc.project(&target, &a, ya).expect("a"), fc.project(&target, &b, yb).expect("b"));
                prop_assert!(((pb.u - pa.u) / (2.0 * h) - p.du[i]).abs() < 1e-4 * (1.0 + p.du[i].abs()));
                prop_assert!(((pb.v - pa.v) / (2.0 * h) - p.dv[i]).abs() < 1e-4 * (1.0 + p.dv[i].abs()));
            }
        }

        /// Projection agrees with the camera module's, for any attitude.
        #[test]
        fn projection_matches_the_camera_module(yaw in -3.1f64..3.1, roll in -0.3f64..0.3, pitch in -0.3f64..0.3) {
            let camera = PinholeCamera::default_hd();
            let attitude = Attitude { roll, pitch, yaw };
            let pose = Pose { position_in_world: Point3::new(3.0, -4.0, 30.0), attitude };
            let ahead = Point3::new(3.0 + 200.0 * yaw.cos(), -4.0 + 200.0 * yaw.sin(), 10.0);
            let expected = camera.project(&(camera.world_from_camera(&pose).inverse() * ahead)).expect("ahead");
            let p = FrameCamera::new(&camera, &attitude).project(&ahead, &pose.position_in_world, yaw).expect("ahead");
            prop_assert!((p.u - expected.x).abs() < 1e-6 && (p.v - expected.y).abs() < 1e-6);
        }
    }
}
