//! What a box says about the pose, in pixels: the predicted rows of a tower's
//! top and foot and the column of its axis, with their Jacobians with respect to
//! (east, north, up, yaw), and the spread of each measured edge.
//!
//! Roll and pitch come from the IMU and are held fixed; the camera mount is
//! folded in with them, so the same code serves any attitude.

use nalgebra::{Matrix3, Point3, RowVector4, UnitQuaternion, Vector3};
use towernav_geometry::{Attitude, Intrinsics, PinholeCamera, Pose};

use super::{LocalizerParams, Observation, touches_edge};

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

/// One scalar measurement: its value, prediction, Jacobian row and spread.
#[derive(Debug, Clone, Copy)]
pub struct Residual {
    pub r: f64,
    pub jacobian: RowVector4<f64>,
    pub sigma: f64,
}

/// Which of a box's three numbers can be trusted: an edge that touches the
/// image border is where the image ends, not where the tower does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Usable {
    pub centre: bool,
    pub top: bool,
    pub bottom: bool,
}

impl Usable {
    pub fn of(o: &Observation<'_>, k: &Intrinsics) -> Self {
        const MARGIN: f64 = super::EDGE_MARGIN_PX;
        let b = &o.bbox;
        if !touches_edge(b, k) {
            return Self {
                centre: true,
                top: true,
                bottom: true,
            };
        }
        Self {
            centre: b.left > MARGIN && b.right < f64::from(k.width) - MARGIN,
            top: b.top > MARGIN,
            bottom: b.bottom < f64::from(k.height) - MARGIN,
        }
    }

    pub fn count(self) -> usize {
        usize::from(self.centre) + usize::from(self.top) + usize::from(self.bottom)
    }
}

/// Spread of one box edge: grows for small boxes and low scores.
pub fn edge_sigma(o: &Observation<'_>, params: &LocalizerParams) -> f64 {
    let h = o.bbox.height().max(1.0);
    let score = if o.score.is_finite() {
        o.score.clamp(0.0, 1.0)
    } else {
        0.0
    };
    params.edge_sigma_px * (1.0 + params.small_box_px / h) * (1.0 + 0.5 * (1.0 - score))
}

/// The usable residuals of one observation at state (position, yaw); `out` is cleared first.
/// Returns `false` when the tower is behind the camera at this state.
pub fn residuals(
    o: &Observation<'_>,
    usable: Usable,
    camera: &FrameCamera,
    position: &Point3<f64>,
    yaw: f64,
    params: &LocalizerParams,
    out: &mut Vec<Residual>,
) -> bool {
    out.clear();
    let (Some(top), Some(foot)) = (
        camera.project(&o.tower.top_in_world(), position, yaw),
        camera.project(&o.tower.foot_in_world, position, yaw),
    ) else {
        return false;
    };
    let k = &camera.k;
    let sigma_e = edge_sigma(o, params);
    let (sh, sv) = (o.tower.sigma_horizontal_m, o.tower.sigma_vertical_m);
    // A survey error moves the whole tower: sideways by sh, in range by sh, up by sv.
    let survey_v = |p: &Projected| {
        let range_share = (p.v - k.cy) / p.depth;
        (k.fy * sv / p.depth).powi(2) + (range_share * sh).powi(2)
    };
    if usable.centre {
        let predicted = 0.5 * (top.u + foot.u);
        let width_term = params.centre_width_share * o.bbox.width();
        let sigma2 =
            0.5 * sigma_e * sigma_e + width_term * width_term + (k.fx * sh / foot.depth).powi(2);
        out.push(Residual {
            r: o.bbox.center_x() - predicted,
            jacobian: 0.5 * (top.du + foot.du),
            sigma: sigma2.sqrt(),
        });
    }
    if usable.top {
        out.push(Residual {
            r: o.bbox.top - top.v,
            jacobian: top.dv,
            sigma: (sigma_e * sigma_e + survey_v(&top)).sqrt(),
        });
    }
    if usable.bottom {
        out.push(Residual {
            r: o.bbox.bottom - foot.v,
            jacobian: foot.dv,
            sigma: (sigma_e * sigma_e + survey_v(&foot)).sqrt(),
        });
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
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
