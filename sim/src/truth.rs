//! Exact truth per frame: the pose, and each visible tower's box by the labeling
//! convention of method.md (top edge at the tower top, bottom edge through the
//! foot on the tower axis, so box height images the whole tower height).

use nalgebra::{Point3, Vector3};
use towernav_geometry::{PinholeCamera, PixelBox, Pose};
use towernav_protocol::TowerType;

use crate::world::{Distractor, SimTower, World};

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
    /// Share of the box hidden behind nearer objects' boxes, 0..1.
    pub occluded: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct FrameTruth {
    pub seq: u64,
    pub time_s: f64,
    pub pose: Pose,
    pub boxes: Vec<TruthBox>,
    /// Boxes of the distractors in view: where a real detector might fire falsely.
    pub distractors: Vec<PixelBox>,
}

/// Towers farther than this are never labelled: a few pixels tall at best.
pub const MAX_RANGE_M: f64 = 900.0;
/// Boxes shorter than this are not labelled.
pub const MIN_BOX_HEIGHT_PX: f64 = 4.0;

/// The truth box of one tower, or `None` if it is not in view.
pub fn truth_box(camera: &PinholeCamera, pose: &Pose, tower: &SimTower) -> Option<TruthBox> {
    truth_box_with(camera, pose, tower, &outline(tower))
}

/// A tower's distinct model points in the world frame: all a box must enclose.
pub fn outline(tower: &SimTower) -> Vec<Point3<f64>> {
    let world_from_tower = tower.world_from_tower();
    let mut points: Vec<Point3<f64>> = Vec::new();
    for v in tower.model().vertices() {
        let p = world_from_tower * v;
        if !points.iter().any(|q| (q - p).norm_squared() < 1e-12) {
            points.push(p);
        }
    }
    points
}

/// Every tower's outline, in world order: computed once per world, used every frame.
pub fn outlines(world: &World) -> Vec<Vec<Point3<f64>>> {
    world.towers.iter().map(outline).collect()
}

/// `truth_box` with the tower's `outline` already computed.
pub fn truth_box_with(
    camera: &PinholeCamera,
    pose: &Pose,
    tower: &SimTower,
    outline_in_world: &[Point3<f64>],
) -> Option<TruthBox> {
    let camera_from_world = camera.world_from_camera(pose).inverse();
    let foot = tower.foot_in_world;
    let top = foot + Vector3::new(0.0, 0.0, tower.height_m);
    let horizontal = (foot - pose.position_in_world).xy().norm();
    if horizontal > MAX_RANGE_M {
        return None;
    }
    let project = |p: Point3<f64>| camera.project(&(camera_from_world * p));
    let (top_px, foot_px) = (project(top)?, project(foot)?);
    // Horizontal extent: every point of the 3-D model, cross-arms included.
    let mut left = f64::INFINITY;
    let mut right = f64::NEG_INFINITY;
    for vertex in outline_in_world {
        let px = project(*vertex)?;
        left = left.min(px.x);
        right = right.max(px.x);
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
        occluded: 0.0,
    })
}

/// Image box of a distractor, with its horizontal distance; `None` out of view.
fn distractor_box(camera: &PinholeCamera, pose: &Pose, d: &Distractor) -> Option<(PixelBox, f64)> {
    let camera_from_world = camera.world_from_camera(pose).inverse();
    let corners: Option<Vec<_>> = d
        .bounding_corners()
        .iter()
        .map(|c| camera.project(&(camera_from_world * c)))
        .collect();
    let b = PixelBox::enclosing(corners?)?;
    let distance = (d.foot_in_world() - pose.position_in_world).xy().norm();
    Some((b, distance))
}

/// Fill in each box's occluded share: the fraction of a 16x32 grid of points in
/// it that fall inside the box of a nearer tower or distractor.
fn mark_occlusion(boxes: &mut [TruthBox], blockers: &[(PixelBox, f64)]) {
    const NX: usize = 16;
    const NY: usize = 32;
    let towers: Vec<(PixelBox, f64)> = boxes.iter().map(|b| (b.bbox, b.distance_m)).collect();
    for b in boxes.iter_mut() {
        let nearer: Vec<&PixelBox> = towers
            .iter()
            .chain(blockers)
            .filter(|(_, d)| *d < b.distance_m - 1e-6)
            .map(|(bb, _)| bb)
            .filter(|bb| bb.iou(&b.bbox) > 0.0)
            .collect();
        if nearer.is_empty() {
            continue;
        }
        let mut hidden = 0;
        for i in 0..NX {
            for j in 0..NY {
                let x = b.bbox.left + b.bbox.width() * (i as f64 + 0.5) / NX as f64;
                let y = b.bbox.top + b.bbox.height() * (j as f64 + 0.5) / NY as f64;
                if nearer
                    .iter()
                    .any(|n| (n.left..=n.right).contains(&x) && (n.top..=n.bottom).contains(&y))
                {
                    hidden += 1;
                }
            }
        }
        b.occluded = f64::from(hidden) / (NX * NY) as f64;
    }
}

/// Truth for one frame; `outlines` as `outlines(world)` gives them.
pub fn frame_truth(
    camera: &PinholeCamera,
    world: &World,
    outlines: &[Vec<Point3<f64>>],
    seq: u64,
    time_s: f64,
    pose: Pose,
) -> FrameTruth {
    let mut boxes: Vec<TruthBox> = world
        .towers
        .iter()
        .zip(outlines)
        .filter_map(|(t, o)| truth_box_with(camera, &pose, t, o))
        .collect();
    let (w, h) = (
        f64::from(camera.intrinsics.width),
        f64::from(camera.intrinsics.height),
    );
    let in_view: Vec<(&Distractor, PixelBox, f64)> = world
        .distractors
        .iter()
        .filter_map(|d| {
            let (b, dist) = distractor_box(camera, &pose, d)?;
            let clipped = b.clipped(w, h);
            (dist <= MAX_RANGE_M && clipped.width() > 0.0 && clipped.height() >= MIN_BOX_HEIGHT_PX)
                .then_some((d, clipped, dist))
        })
        .collect();
    let blockers: Vec<(PixelBox, f64)> = in_view
        .iter()
        .filter(|(d, _, _)| matches!(d, Distractor::Building { .. } | Distractor::Tree { .. }))
        .map(|&(_, b, dist)| (b, dist))
        .collect();
    mark_occlusion(&mut boxes, &blockers);
    let distractors = in_view.iter().map(|&(_, b, _)| b).collect();
    FrameTruth {
        seq,
        time_s,
        pose,
        boxes,
        distractors,
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
            line_yaw: 0.0,
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
        // The cross-arm stands across the line, symmetric about the axis.
        assert!((b.bbox.center_x() - camera.intrinsics.cx).abs() < 1e-6);
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
    fn a_tower_behind_a_nearer_one_is_marked_occluded() {
        let (camera, pose, near) = tower_ahead(150.0);
        let far = SimTower {
            id: "C1".into(),
            foot_in_world: Point3::new(300.0, 0.0, 0.0),
            ..near.clone()
        };
        let world = World {
            datum: World::seed_field().datum,
            towers: vec![near, far],
            lines: Vec::new(),
            distractors: Vec::new(),
        };
        let truth = frame_truth(&camera, &world, &outlines(&world), 0, 0.0, pose);
        let (near, far) = (&truth.boxes[0], &truth.boxes[1]);
        assert_eq!(near.occluded, 0.0);
        assert!(far.occluded > 0.9, "{}", far.occluded);
    }

    #[test]
    fn a_close_tower_is_cut_by_the_image_edge() {
        let (camera, pose, tower) = tower_ahead(20.0);
        let b = truth_box(&camera, &pose, &tower).expect("visible");
        assert!(b.truncated);
        assert!(b.bbox.bottom <= f64::from(camera.intrinsics.height));
    }
}
