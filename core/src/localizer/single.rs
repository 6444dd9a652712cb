//! The paper's single-tower geometry with attitude: rays through the box's top
//! and bottom are rotated into the world by the IMU attitude and camera mount,
//! so a pitched or rolled camera no longer biases range and offset.
//! Used to start the multi-tower solver and as a per-tower measurement.

use nalgebra::{Point2, Point3};
use towernav_geometry::{Attitude, PinholeCamera, Pose};

use super::Observation;

/// Where the camera must be for this one tower's box, given the full attitude
/// (yaw included). `None` when the rays do not bracket a tower of positive height.
pub fn single_tower_position(
    o: &Observation<'_>,
    camera: &PinholeCamera,
    attitude: &Attitude,
) -> Option<Point3<f64>> {
    let pose = Pose {
        position_in_world: Point3::origin(),
        attitude: *attitude,
    };
    let world_from_camera = camera.world_from_camera(&pose).rotation;
    // The real image's box through the real camera's rays: the lens undone
    // at its top and foot.
    let b = &o.raw;
    let u = b.center_x();
    let to_top = world_from_camera * camera.ray(&Point2::new(u, b.top));
    let to_foot = world_from_camera * camera.ray(&Point2::new(u, b.bottom));
    let (top_h, foot_h) = (to_top.xy().norm(), to_foot.xy().norm());
    if top_h < 1e-9 || foot_h < 1e-9 {
        return None;
    }
    // Elevation tangents: the tower spans H between them at horizontal range D.
    let spread = to_top.z / top_h - to_foot.z / foot_h;
    if spread.is_nan() || spread <= 1e-9 {
        return None;
    }
    let range = o.tower.height_m / spread;
    let bearing = (to_top.xy() / top_h + to_foot.xy() / foot_h).normalize();
    let foot = o.tower.foot_in_world;
    Some(Point3::new(
        foot.x - range * bearing.x,
        foot.y - range * bearing.y,
        foot.z - range * to_foot.z / foot_h,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::landmarks::MapTower;
    use towernav_geometry::PixelBox;
    use towernav_protocol::TowerType;

    #[test]
    fn a_pitched_camera_no_longer_biases_the_range() {
        let camera = PinholeCamera::default_hd();
        let tower = MapTower {
            id: "A1".into(),
            tower_type: TowerType::A,
            foot_in_world: Point3::new(150.0, 0.0, 0.0),
            height_m: 32.0,
            sigma_horizontal_m: 0.0,
            sigma_vertical_m: 0.0,
        };
        let attitude = Attitude {
            roll: 0.0,
            pitch: -8f64.to_radians(),
            yaw: 0.0,
        };
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude,
        };
        let cfw = camera.world_from_camera(&pose).inverse();
        let top = camera.project(&(cfw * tower.top_in_world())).expect("top");
        let foot = camera.project(&(cfw * tower.foot_in_world)).expect("foot");
        let o = Observation::new(
            &tower,
            PixelBox::new(top.x - 5.0, top.y, top.x + 5.0, foot.y),
            0.9,
        );
        let ours = single_tower_position(&o, &camera, &attitude).expect("fix");
        assert!((ours - pose.position_in_world).norm() < 1e-6, "{ours}");
        // The paper's level-camera geometry on the same box is off in range
        // (its height now comes from outside, so only the range is judged).
        let seed = super::super::paper_lbl(
            &[o],
            &camera.intrinsics,
            0.0,
            super::super::Height::unknown(30.0),
            &super::super::LocalizerParams::default(),
        )
        .expect("seed fix");
        let range_error = (seed.position_in_world.x - pose.position_in_world.x).abs();
        assert!(range_error > 0.5, "{range_error}");
    }
}
