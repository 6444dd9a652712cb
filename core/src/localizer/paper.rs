//! The paper's localization by landmarks (LbL), as method.md restates it.
//!
//! Per tower: `D = f H / h` along the optical axis, `E = e H / h` to the right,
//! `p_uav = p_tower - R(yaw) (E, D)`. Several towers: the plain mean. The
//! camera is taken as level.
//!
//! The paper took the height from the foot's row as well; with the camera
//! pitched that gives heights from tens of metres below ground to over a
//! hundred above, which an autopilot must never get. The height comes from
//! outside instead ([`Height`]): the take-off point plus the barometer, or
//! marked unknown by a spread no one would fuse.

use nalgebra::{Matrix2, Matrix4, Point3, Vector2};
use towernav_geometry::{Cut, Intrinsics, PixelBox};

use super::{Fix, LocalizerParams, Observation};

/// The paper's range formula for one box of a tower `tower_height_m` tall:
/// `(D, E)`, metres along the optical axis and to its right, camera level.
pub fn paper_range(k: &Intrinsics, tower_height_m: f64, bbox: &PixelBox) -> (f64, f64) {
    let d = k.fy * tower_height_m / bbox.height();
    (d, (bbox.center_x() - k.cx) * d / k.fx)
}

/// The height the paper's fix reports, from a source other than its boxes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Height {
    /// Up, metres in the world frame.
    pub up_m: f64,
    /// 1-sigma, metres.
    pub sigma_m: f64,
}

impl Height {
    /// 1-sigma given to a height no source measured: far beyond any use, so
    /// the autopilot link flags the altitude as not given.
    pub const UNKNOWN_SIGMA_M: f64 = 1000.0;

    /// A placeholder height that says it is unknown.
    pub fn unknown(up_m: f64) -> Self {
        Self {
            up_m,
            sigma_m: Self::UNKNOWN_SIGMA_M,
        }
    }

    pub fn is_unknown(sigma_m: f64) -> bool {
        sigma_m >= 0.5 * Self::UNKNOWN_SIGMA_M
    }
}

pub fn paper_lbl(
    observations: &[Observation<'_>],
    k: &Intrinsics,
    yaw: f64,
    height: Height,
    params: &LocalizerParams,
) -> Option<Fix> {
    let forward = Vector2::new(yaw.cos(), yaw.sin());
    let right = Vector2::new(yaw.sin(), -yaw.cos());
    let sigma_h = std::f64::consts::SQRT_2 * params.edge_sigma_px;
    let min_h = params.paper_min_box_height_px;
    let mut sum = Point3::origin().coords;
    let mut cov_sum = Matrix4::zeros();
    let mut used = Vec::new();
    for o in observations {
        let b = &o.bbox;
        let h = b.height();
        if h < min_h || Cut::in_frame(&o.raw, k).any() {
            continue;
        }
        let big_h = o.tower.height_m;
        let (d, e) = paper_range(k, big_h, b);
        let horizontal = o.tower.foot_in_world.xy().coords - (right * e + forward * d);
        sum += nalgebra::Vector3::new(horizontal.x, horizontal.y, 0.0);

        // First-order spread: sigma_D = D^2/(f H) sigma_h; E and height scale with D.
        let sigma_d = d * d / (k.fy * big_h) * sigma_h;
        let sigma_e =
            (e / d).abs() * sigma_d + d / k.fx * params.edge_sigma_px + d * params.yaw_sigma;
        let rot = Matrix2::from_columns(&[right, forward]);
        let cov_en =
            rot * Matrix2::new(sigma_e * sigma_e, 0.0, 0.0, sigma_d * sigma_d) * rot.transpose();
        let mut cov = Matrix4::zeros();
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&cov_en);
        cov_sum += cov;
        used.push(o.tower.id.clone());
    }
    if used.is_empty() {
        return None;
    }
    let n = used.len() as f64;
    let mut covariance = cov_sum / (n * n);
    covariance[(2, 2)] = height.sigma_m * height.sigma_m;
    covariance[(3, 3)] = params.yaw_sigma * params.yaw_sigma;
    let mut position = Point3::from(sum / n);
    position.z = height.up_m;
    Some(Fix {
        position_in_world: position,
        yaw,
        covariance,
        towers_used: used,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::tower;
    use crate::landmarks::MapTower;
    use proptest::prelude::*;
    use towernav_geometry::PixelBox;
    use towernav_geometry::{Attitude, PinholeCamera, Pose};

    /// The paper's labeling convention: top edge at the top, bottom edge at the foot on the axis.
    fn label(camera: &PinholeCamera, pose: &Pose, t: &MapTower) -> PixelBox {
        let cfw = camera.world_from_camera(pose).inverse();
        let foot = camera.project(&(cfw * t.foot_in_world)).expect("visible");
        let top = camera.project(&(cfw * t.top_in_world())).expect("visible");
        PixelBox::new(foot.x - 4.0, top.y, foot.x + 4.0, foot.y)
    }

    proptest! {
        /// With exact boxes and a level camera the paper's geometry is exact.
        #[test]
        fn exact_boxes_give_the_exact_position(x in -50.0f64..50.0, y in -50.0f64..50.0, z in 20.0f64..40.0, yaw in -3.1f64..3.1) {
            let camera = PinholeCamera::default_hd();
            let pose = Pose { position_in_world: Point3::new(x, y, z), attitude: Attitude::level(yaw) };
            let ahead = |dist: f64, side: f64| Point3::new(x, y, 0.0) + nalgebra::Vector3::new(yaw.cos(), yaw.sin(), 0.0) * dist
                + nalgebra::Vector3::new(yaw.sin(), -yaw.cos(), 0.0) * side;
            let a = ahead(150.0, 40.0);
            let b = ahead(220.0, -60.0);
            let towers = [tower("B1", a.x, a.y, 38.0), tower("B2", b.x, b.y, 45.0)];
            let obs: Vec<_> = towers.iter().map(|t| Observation::new(t, label(&camera, &pose, t), 0.9)).collect();
            let height = Height { up_m: z, sigma_m: 1.0 };
            let fix = paper_lbl(&obs, &camera.intrinsics, yaw, height, &LocalizerParams::default()).expect("fix");
            prop_assert!((fix.position_in_world - pose.position_in_world).norm() < 1e-6);
            prop_assert_eq!(fix.towers_used.len(), 2);
            prop_assert!(fix.covariance[(0, 0)] > 0.0 && fix.covariance[(1, 1)] > 0.0);
        }
    }

    #[test]
    fn small_or_cut_boxes_give_no_fix() {
        let k = PinholeCamera::default_hd().intrinsics;
        let t = tower("B1", 100.0, 0.0, 38.0);
        let tiny = Observation::new(&t, PixelBox::new(600.0, 300.0, 604.0, 310.0), 0.9);
        let cut = Observation::new(&t, PixelBox::new(600.0, 100.0, 640.0, 720.0), 0.9);
        assert!(
            paper_lbl(
                &[tiny, cut],
                &k,
                0.0,
                Height::unknown(30.0),
                &LocalizerParams::default()
            )
            .is_none()
        );
    }

    #[test]
    fn spread_grows_with_the_square_of_distance() {
        let camera = PinholeCamera::default_hd();
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let sigma_forward = |d: f64| {
            let t = tower("B1", d, 0.0, 38.0);
            let obs = [Observation::new(&t, label(&camera, &pose, &t), 0.9)];
            paper_lbl(
                &obs,
                &camera.intrinsics,
                0.0,
                Height::unknown(30.0),
                &LocalizerParams::default(),
            )
            .expect("fix")
            .covariance[(0, 0)]
                .sqrt()
        };
        let ratio = sigma_forward(200.0) / sigma_forward(100.0);
        assert!((ratio - 4.0).abs() < 0.01, "{ratio}");
    }
}
