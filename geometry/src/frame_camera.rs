//! The camera of one frame with roll and pitch fixed by the IMU and the
//! position and yaw left free: the projection a localizer fits, with its
//! analytic Jacobian with respect to (east, north, up, yaw).

use nalgebra::{Matrix2, Matrix3, Point3, RowVector4, UnitQuaternion, Vector2, Vector3};

use crate::{Attitude, Distortion, Intrinsics, PinholeCamera, Pose};

/// The camera for one frame with yaw left free: `camera_from_world = A * Rz(yaw)^T`.
#[derive(Debug, Clone, Copy)]
pub struct FrameCamera {
    pub k: Intrinsics,
    pub distortion: Distortion,
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
            distortion: camera.distortion,
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

    /// [`Self::project`] carried through the lens into the real image: the
    /// pixel the real camera sees the point at, with its Jacobians.
    pub fn project_through_lens(
        &self,
        point_in_world: &Point3<f64>,
        position: &Point3<f64>,
        yaw: f64,
    ) -> Option<Projected> {
        self.project(point_in_world, position, yaw)
            .map(|p| self.through_lens(&p))
    }

    /// An ideal projection moved into the real image, its Jacobians carried
    /// by the chain rule. Depth stays the ideal projection's.
    fn through_lens(&self, p: &Projected) -> Projected {
        if self.distortion.is_none() {
            return *p;
        }
        let k = &self.k;
        let real = self.distortion.distort(self.normalized(p.u, p.v));
        let j = self.lens_jacobian(p.u, p.v);
        Projected {
            u: k.cx + k.fx * real.x,
            v: k.cy + k.fy * real.y,
            du: p.du * j[(0, 0)] + p.dv * j[(0, 1)],
            dv: p.du * j[(1, 0)] + p.dv * j[(1, 1)],
            depth: p.depth,
        }
    }

    /// Real-image pixels per ideal-image pixel at the ideal pixel `(u, v)`:
    /// d(real)/d(ideal), the identity without a lens.
    fn lens_jacobian(&self, u: f64, v: f64) -> Matrix2<f64> {
        if self.distortion.is_none() {
            return Matrix2::identity();
        }
        let ideal = self.normalized(u, v);
        // By central differences: the lens models are smooth, and this
        // stays right for every model.
        const H: f64 = 1e-6;
        let column = |e: Vector2<f64>| {
            (self.distortion.distort(ideal + e * H) - self.distortion.distort(ideal - e * H))
                / (2.0 * H)
        };
        let j = Matrix2::from_columns(&[column(Vector2::x()), column(Vector2::y())]);
        let k = &self.k;
        Matrix2::new(
            j[(0, 0)],
            j[(0, 1)] * k.fx / k.fy,
            j[(1, 0)] * k.fy / k.fx,
            j[(1, 1)],
        )
    }

    fn normalized(&self, u: f64, v: f64) -> Vector2<f64> {
        Vector2::new((u - self.k.cx) / self.k.fx, (v - self.k.cy) / self.k.fy)
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

        /// Through a barrel or fisheye lens, the pixel is the camera module's
        /// and the Jacobian agrees with finite differences.
        #[test]
        fn through_a_lens_projection_and_jacobian_hold(
            x in -20.0f64..20.0, y in -20.0f64..20.0, yaw in -0.5f64..0.5,
            roll in -0.3f64..0.3, pitch in -0.3f64..0.3, fisheye in proptest::bool::ANY,
        ) {
            let mut camera = PinholeCamera::default_hd();
            camera.distortion = if fisheye {
                Distortion::Fisheye { k1: -0.02, k2: 0.01, k3: -0.004, k4: 0.0006 }
            } else {
                Distortion::RadialTangential { k1: -0.28, k2: 0.08, p1: 1e-3, p2: -2e-3, k3: -0.01 }
            };
            let attitude = Attitude { roll, pitch, yaw };
            let fc = FrameCamera::new(&camera, &Attitude { yaw: 0.0, ..attitude });
            let target = Point3::new(150.0, 60.0, 25.0);
            let pos = Point3::new(x, y, 30.0);
            let p = fc.project_through_lens(&target, &pos, yaw).expect("in front");
            let pose = Pose { position_in_world: pos, attitude };
            let expected = camera.project(&(camera.world_from_camera(&pose).inverse() * target)).expect("in front");
            prop_assert!((p.u - expected.x).abs() < 1e-6 && (p.v - expected.y).abs() < 1e-6);
            let h = 1e-5;
            for i in 0..4 {
                let (mut a, mut b) = (pos, pos);
                let (mut ya, mut yb) = (yaw, yaw);
                if i < 3 { a[i] -= h; b[i] += h; } else { ya -= h; yb += h; }
                let pa = fc.project_through_lens(&target, &a, ya).expect("a");
                let pb = fc.project_through_lens(&target, &b, yb).expect("b");
                prop_assert!(((pb.u - pa.u) / (2.0 * h) - p.du[i]).abs() < 1e-3 * (1.0 + p.du[i].abs()));
                prop_assert!(((pb.v - pa.v) / (2.0 * h) - p.dv[i]).abs() < 1e-3 * (1.0 + p.dv[i].abs()));
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
