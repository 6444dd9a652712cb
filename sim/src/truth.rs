//! Exact truth per frame: the pose, and each visible tower's box by the labeling
//! convention of method.md (top edge at the tower top, bottom edge through the
//! foot on the tower axis, so box height images the whole tower height).

use nalgebra::{Point3, Vector3};
use towernav_geometry::{PinholeCamera, PixelBox, Pose};
use towernav_protocol::TowerType;

use crate::world::{SimTower, World};

#[derive(Debug, Clone, PartialEq)]
pub struct TruthBox {
    pub tower_id: String,
    pub tower_type: TowerType,
    /// The box as far as it lies inside the image.
    pub bbox: PixelBox,
    /// The image edge cuts the box.
    pub truncated: bool,
    /// Horizontal distance from the camera to the tower axis.
    pub distance_m: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct FrameTruth {
    pub seq: u64,
    pub time_s: f64,
    pub pose: Pose,
    pub boxes: Vec<TruthBox>,
}

/// Towers farther than this are never labelled: a few pixels tall at best.
pub const MAX_RANGE_M: f64 = 900.0;
/// Boxes shorter than this are not labelled.
pub const MIN_BOX_HEIGHT_PX: f64 = 4.0;

/// The truth box of one tower, or `None` if it is not in view.
pub fn truth_box(camera: &PinholeCamera, pose: &Pose, tower: &SimTower) -> Option<TruthBox> {
    let camera_from_world = camera.world_from_camera(pose).inverse();
    let foot = tower.foot_in_world;
    let top = foot + Vector3::new(0.0, 0.0, tower.height_m);
    let horizontal = (foot - pose.position_in_world).xy().norm();
    if horizontal > MAX_RANGE_M {
        return None;
    }
    let project = |p: Point3<f64>| camera.project(&(camera_from_world * p));
    let (top_px, foot_px) = (project(top)?, project(foot)?);
    // Horizontal extent: the lattice's square section, tapering to a third at the top.
    let mut left = f64::INFINITY;
    let mut right = f64::NEG_INFINITY;
    for (z, half) in [
        (0.0, tower.base_width_m / 2.0),
        (tower.height_m, tower.base_width_m / 6.0),
    ] {
        for (dx, dy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
            let corner = foot + Vector3::new(dx * half, dy * half, z);
            let px = project(corner)?;
            left = left.min(px.x);
            right = right.max(px.x);
        }
    }
    let full = PixelBox::new(left, top_px.y, right, foot_px.y);
    let k = &camera.intrinsics;
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let bbox = full.clipped(w, h);
    if bbox.width() <= 0.0 || bbox.height() < MIN_BOX_HEIGHT_PX {
        return None;
    }
    Some(TruthBox {
        tower_id: tower.id.clone(),
        tower_type: tower.tower_type,
        bbox,
        truncated: bbox != full,
        distance_m: horizontal,
    })
}

pub fn frame_truth(
    camera: &PinholeCamera,
    world: &World,
    seq: u64,
    time_s: f64,
    pose: Pose,
) -> FrameTruth {
    let boxes = world
        .towers
        .iter()
        .filter_map(|t| truth_box(camera, &pose, t))
        .collect();
    FrameTruth {
        seq,
        time_s,
        pose,
        boxes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_geometry::Attitude;

    fn tower_ahead(distance: f64) -> (PinholeCamera, Pose, SimTower) {
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(0.0),
        };
        let tower = SimTower {
            id: "A1".into(),
            tower_type: TowerType::A,
            foot_in_world: Point3::new(distance, 0.0, 0.0),
            height_m: 32.0,
            base_width_m: 6.0,
        };
        (PinholeCamera::default_hd(), pose, tower)
    }

    #[test]
    fn box_height_is_f_h_over_d_for_a_level_camera() {
        let (camera, pose, tower) = tower_ahead(200.0);
        let b = truth_box(&camera, &pose, &tower).expect("visible");
        let expected = camera.intrinsics.fy * 32.0 / 200.0;
        assert!(
            (b.bbox.height() - expected).abs() < 1e-9,
            "{} vs {expected}",
            b.bbox.height()
        );
        assert!((b.bbox.center_x() - camera.intrinsics.cx).abs() < 1e-9);
        assert!(!b.truncated);
    }

    #[test]
    fn towers_behind_or_beyond_range_are_not_labelled() {
        let (camera, pose, tower) = tower_ahead(-100.0);
        assert!(truth_box(&camera, &pose, &tower).is_none());
        let (camera, pose, tower) = tower_ahead(MAX_RANGE_M + 1.0);
        assert!(truth_box(&camera, &pose, &tower).is_none());
    }

    #[test]
    fn a_close_tower_is_cut_by_the_image_edge() {
        let (camera, pose, tower) = tower_ahead(20.0);
        let b = truth_box(&camera, &pose, &tower).expect("visible");
        assert!(b.truncated);
        assert!(b.bbox.bottom <= f64::from(camera.intrinsics.height));
    }
}
