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
    /// Share of the tower's drawn structure (member length times width)
    /// inside the image: 1 unless `truncated`. A tower cut down to an arm tip
    /// keeps a box but is barely there to see.
    pub in_frame: f64,
    /// Horizontal distance from the camera to the tower axis.
    pub distance_m: f64,
    /// Share of the box hidden behind nearer objects' boxes, 0..1.
    pub occluded: f64,
}

impl TruthBox {
    /// Whether a detector is asked to find it (`MIN_IN_FRAME`).
    pub fn labelled(&self) -> bool {
        self.in_frame >= MIN_IN_FRAME
    }
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

/// Boxes shorter than this are not labelled. There is no range limit: the
/// renderer draws every tower, and a 50 m tower 1 km off is still 45 px tall.
pub const MIN_BOX_HEIGHT_PX: f64 = 4.0;
/// Distractors (trees, buildings, poles, about 10 m tall) farther than this
/// are a few pixels at most: neither false-positive bait nor blockers.
pub const DISTRACTOR_RANGE_M: f64 = 900.0;
/// Towers with less of their structure than this inside the image are not
/// labelled for a detector: an arm tip at the frame's edge is not a tower
/// anyone could find. The YOLO dataset leaves them out and the detector's
/// evaluation ignores them; truth keeps them for the oracle and the trackers.
pub const MIN_IN_FRAME: f64 = 0.25;

/// The truth box of one tower, or `None` if it is not in view.
pub fn truth_box(camera: &PinholeCamera, pose: &Pose, tower: &SimTower) -> Option<TruthBox> {
    truth_box_with(camera, pose, tower, &outline(tower))
}

/// What truth needs of one tower's 3-D model, in the world frame: computed
/// once per world, used every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Outline {
    /// Distinct member end points: all a box must enclose.
    pub vertices: Vec<Point3<f64>>,
    /// Points along every member, each weighted by the ink it stands for
    /// (member width times the length it samples): how much of the drawn
    /// tower a part of the image holds.
    pub ink: Vec<(Point3<f64>, f64)>,
}

/// Samples per member for `Outline::ink`.
const INK_SAMPLES: usize = 6;

pub fn outline(tower: &SimTower) -> Outline {
    let world_from_tower = tower.world_from_tower();
    let model = tower.model();
    let mut vertices: Vec<Point3<f64>> = Vec::new();
    for v in model.vertices() {
        let p = world_from_tower * v;
        if !vertices.iter().any(|q| (q - p).norm_squared() < 1e-12) {
            vertices.push(p);
        }
    }
    let mut ink = Vec::with_capacity(model.members.len() * INK_SAMPLES);
    for m in &model.members {
        let weight = m.kind.width_m() * (m.b - m.a).norm() / INK_SAMPLES as f64;
        for i in 0..INK_SAMPLES {
            let s = (i as f64 + 0.5) / INK_SAMPLES as f64;
            ink.push((world_from_tower * (m.a + (m.b - m.a) * s), weight));
        }
    }
    Outline { vertices, ink }
}

/// Every tower's outline, in world order.
pub fn outlines(world: &World) -> Vec<Outline> {
    world.towers.iter().map(outline).collect()
}

/// `truth_box` with the tower's `outline` already computed.
pub fn truth_box_with(
    camera: &PinholeCamera,
    pose: &Pose,
    tower: &SimTower,
    outline: &Outline,
) -> Option<TruthBox> {
    let camera_from_world = camera.world_from_camera(pose).inverse();
    let foot = tower.foot_in_world;
    let top = foot + Vector3::new(0.0, 0.0, tower.height_m);
    let horizontal = (foot - pose.position_in_world).xy().norm();
    let project = |p: Point3<f64>| camera.project(&(camera_from_world * p));
    let (top_px, foot_px) = (project(top)?, project(foot)?);
    // Horizontal extent: every point of the 3-D model, cross-arms included.
    let mut left = f64::INFINITY;
    let mut right = f64::NEG_INFINITY;
    for vertex in &outline.vertices {
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
    let truncated = bbox != full;
    let in_frame = if truncated {
        let inside = |p: &Point3<f64>| {
            project(*p).is_some_and(|px| (0.0..w).contains(&px.x) && (0.0..h).contains(&px.y))
        };
        let total: f64 = outline.ink.iter().map(|(_, weight)| weight).sum();
        let seen: f64 = outline
            .ink
            .iter()
            .filter(|(p, _)| inside(p))
            .map(|(_, weight)| weight)
            .sum();
        seen / total.max(f64::MIN_POSITIVE)
    } else {
        1.0
    };
    Some(TruthBox {
        tower_id: tower.id.clone(),
        tower_type: tower.tower_type,
        bbox,
        truncated,
        in_frame,
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
    outlines: &[Outline],
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
            (dist <= DISTRACTOR_RANGE_M
                && clipped.width() > 0.0
                && clipped.height() >= MIN_BOX_HEIGHT_PX)
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
    fn towers_behind_or_too_small_to_see_are_not_labelled() {
        let (camera, pose, tower) = tower_ahead(-100.0);
        assert!(truth_box(&camera, &pose, &tower).is_none());
        // 32 m at 1.2 km is still a tower to find; at 10 km it is 3 px.
        let (camera, pose, tower) = tower_ahead(1200.0);
        assert!(truth_box(&camera, &pose, &tower).is_some());
        let (camera, pose, tower) = tower_ahead(10_000.0);
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
            datum: World::paper_field().datum,
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
        assert!(0.0 < b.in_frame && b.in_frame < 1.0, "{}", b.in_frame);
    }

    #[test]
    fn a_tower_leaving_the_side_of_the_frame_keeps_less_and_less_of_itself_in_it() {
        let (camera, pose, tower) = tower_ahead(200.0);
        let mut boxes = Vec::new();
        for step in 0..400 {
            let moved = SimTower {
                foot_in_world: Point3::new(200.0, f64::from(step) * 0.5, 0.0),
                ..tower.clone()
            };
            match truth_box(&camera, &pose, &moved) {
                Some(b) => boxes.push(b),
                None if boxes.is_empty() => panic!("the tower ahead is in view"),
                None => break,
            }
        }
        let shares: Vec<f64> = boxes.iter().map(|b| b.in_frame).collect();
        assert_eq!(shares[0], 1.0);
        assert!(shares.windows(2).all(|w| w[1] <= w[0] + 1e-9), "{shares:?}");
        // The last boxes hold no more than an arm tip, and are not labelled.
        let last = boxes.last().expect("boxes");
        assert!(last.in_frame < 0.1, "{}", last.in_frame);
        assert!(!last.labelled());
        assert!(boxes[0].labelled());
    }
}
