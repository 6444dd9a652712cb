//! Labels from a survey flight: where GNSS still works and the towers are in
//! the database, each tower's top and foot projected into every frame give
//! its box by the labelling convention (top of the tower to its foot) with no
//! one drawing it. Pure: a frame's camera pose and the towers in, labels out;
//! then each label is snapped to the detector's box where the two agree, so
//! a small pose error does not shift it, keeping the projection's height,
//! which a pose error hardly changes.

use nalgebra::{Point2, Point3, Vector3};
use towernav_geometry::{PinholeCamera, PixelBox, Pose};
use towernav_protocol::TowerType;

use crate::assignment::max_score_matching;

/// A surveyed tower as the labeller sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct SurveyTower {
    pub id: String,
    pub tower_type: TowerType,
    pub foot_in_world: Point3<f64>,
    pub height_m: f64,
    /// Width of the tower's silhouette, cross-arms included, metres.
    pub width_m: f64,
}

/// A tower's silhouette width when the database has no base width: lattice
/// towers' cross-arms span about a third of their height.
pub const WIDTH_PER_HEIGHT: f64 = 0.33;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelParams {
    /// Towers shorter than this in the image are not labelled.
    pub min_height_px: f64,
    /// The share of a box that nearer towers may cover before it is hidden.
    pub max_hidden: f64,
    /// The share of a box that must be inside the frame.
    pub min_in_frame: f64,
    /// A detector's box this close (IoU) to a projected one replaces it.
    pub snap_iou: f64,
    /// An unsnapped label takes its width from the same tower's snapped
    /// box at most this many seconds away in the flight.
    pub width_from_s: f64,
}

impl Default for LabelParams {
    fn default() -> Self {
        Self {
            min_height_px: 24.0,
            max_hidden: 0.75,
            min_in_frame: 0.5,
            snap_iou: 0.5,
            width_from_s: 20.0,
        }
    }
}

/// Why a tower in the database got no label in a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Dropped {
    /// Behind the camera, or outside the frame.
    OutOfView,
    /// Less than `min_in_frame` of it inside the frame.
    CutByFrame { in_frame: f64 },
    /// Shorter than `min_height_px`.
    TooSmall { height_px: f64 },
    /// Covered by nearer towers.
    Hidden { covered: f64 },
    /// At the frame's edge with no detector box to confirm it: a small pose
    /// error puts such a tower in or out of the frame.
    Unconfirmed,
}

/// One tower in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TowerLabel {
    pub tower: usize,
    /// Projected from the pose, clipped to the frame.
    pub projected: PixelBox,
    pub distance_m: f64,
    /// The box snapped to the detector's (its place and width, the
    /// projection's height), and its IoU with the projection.
    pub snapped: Option<(PixelBox, f64)>,
    /// Not snapped: the projection moved by the frame's median offset
    /// between the snapped labels and their projections (the pose error
    /// every projection of the frame shares).
    pub shifted: Option<PixelBox>,
    /// Not snapped: the flight time of the frame whose snapped box of the
    /// same tower lent its width to `shifted` (see [`borrow_widths`]).
    pub width_from_s: Option<f64>,
    pub dropped: Option<Dropped>,
}

impl TowerLabel {
    /// The box to write: snapped where a detector's box agreed, else the projection.
    pub fn label(&self) -> Option<PixelBox> {
        match (self.dropped, self.snapped) {
            (Some(_), _) => None,
            (None, Some((b, _))) => Some(b),
            (None, None) => Some(self.shifted.unwrap_or(self.projected)),
        }
    }
}

/// The tower's box in the ideal pinhole's image (its silhouette's corners:
/// the axis from foot to top and the width), its nearest depth and where
/// the middle of its axis is; `None`
/// when any of it is behind the camera. Projected ideal first: a lens model
/// is only valid over its frame, and points far outside it fold back in.
fn project(
    camera: &PinholeCamera,
    pose: &Pose,
    t: &SurveyTower,
) -> Option<(PixelBox, f64, Point2<f64>)> {
    let ideal = camera.ideal();
    let camera_from_world = camera.world_from_camera(pose).inverse();
    let middle = ideal.project(
        &(camera_from_world * (t.foot_in_world + Vector3::new(0.0, 0.0, t.height_m / 2.0))),
    )?;
    let half = t.width_m / 2.0;
    let (mut left, mut right) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut top, mut bottom) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut depth: f64 = f64::INFINITY;
    for z in [0.0, t.height_m] {
        for (dx, dy) in [
            (0.0, 0.0),
            (-half, -half),
            (half, -half),
            (-half, half),
            (half, half),
        ] {
            let p = camera_from_world * (t.foot_in_world + Vector3::new(dx, dy, z));
            if p.z <= 0.5 {
                return None;
            }
            depth = depth.min(p.z);
            let px = ideal.project(&p)?;
            left = left.min(px.x);
            right = right.max(px.x);
            // The convention's top and foot are the axis's: the footprint's
            // near corners sit lower in the image than the foot, by about a
            // tenth of the box for a near tower seen from above.
            if dx == 0.0 && dy == 0.0 {
                top = top.min(px.y);
                bottom = bottom.max(px.y);
            }
        }
    }
    Some((PixelBox::new(left, top, right, bottom), depth, middle))
}

/// A camera as the labeller uses it: with the part of the ideal image its
/// frame sees, found once (it takes a hundred undistortions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelCamera {
    pub camera: PinholeCamera,
    seen: PixelBox,
}

impl LabelCamera {
    pub fn new(camera: PinholeCamera) -> Self {
        Self {
            seen: seen_in_ideal(&camera),
            camera,
        }
    }
}

/// The part of the ideal image that the real frame sees: the box around
/// its undistorted border.
fn seen_in_ideal(camera: &PinholeCamera) -> PixelBox {
    let k = &camera.intrinsics;
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let frame = PixelBox::new(0.0, 0.0, w, h);
    if camera.distortion.is_none() {
        return frame;
    }
    let steps = 32;
    (0..=steps)
        .flat_map(|i| {
            let t = f64::from(i) / f64::from(steps);
            [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)]
        })
        .filter_map(|(x, y)| camera.undistort_pixel(&nalgebra::Point2::new(x, y)))
        .fold(frame, |b, p| b.union(&PixelBox::new(p.x, p.y, p.x, p.y)))
}

/// Every tower's label in one frame seen from `pose`, with the reason for
/// each one dropped.
pub fn project_labels(
    labeller: &LabelCamera,
    pose: &Pose,
    towers: &[SurveyTower],
    params: &LabelParams,
) -> Vec<TowerLabel> {
    let (camera, seen) = (&labeller.camera, labeller.seen);
    let k = &camera.intrinsics;
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let mut labels: Vec<TowerLabel> = towers
        .iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let (full, distance_m, middle) = project(camera, pose, t)?;
            let axis_seen = (seen.left..=seen.right).contains(&middle.x)
                && (seen.top..=seen.bottom).contains(&middle.y);
            let visible = PixelBox::new(
                full.left.max(seen.left),
                full.top.max(seen.top),
                full.right.min(seen.right),
                full.bottom.min(seen.bottom),
            );
            let in_view = visible.width() > 0.0 && visible.height() > 0.0;
            let real = if in_view {
                camera.distort_box(&visible).clipped(w, h)
            } else {
                PixelBox::new(0.0, 0.0, 0.0, 0.0)
            };
            let in_frame = if in_view && full.area() > 0.0 {
                visible.area() / full.area()
            } else {
                0.0
            };
            // A tower beside the camera spans the frame with its near
            // corners while the tower itself, its axis, is out of it.
            let dropped = if real.area() <= 0.0 || !axis_seen {
                Some(Dropped::OutOfView)
            } else if in_frame < params.min_in_frame {
                Some(Dropped::CutByFrame { in_frame })
            } else if real.height() < params.min_height_px {
                Some(Dropped::TooSmall {
                    height_px: real.height(),
                })
            } else {
                None
            };
            Some(TowerLabel {
                tower: i,
                projected: real,
                distance_m,
                snapped: None,
                shifted: None,
                width_from_s: None,
                dropped,
            })
        })
        .collect();
    labels.sort_by(|a, b| a.distance_m.total_cmp(&b.distance_m));
    // Nearer towers hide farther ones: the share of a box under a nearer
    // tower's body. A lattice tower's box is mostly sky between its arms; its
    // body, the middle third of the box, is what hides.
    for i in 0..labels.len() {
        if labels[i].dropped.is_some() {
            continue;
        }
        let b = labels[i].projected;
        let covered = labels[..i]
            .iter()
            // A tower the frame cuts has a box as wide as the frame's edge
            // lets it be; it hides what is at that edge, not mid-frame.
            .filter(|n| {
                !matches!(
                    n.dropped,
                    Some(Dropped::OutOfView | Dropped::CutByFrame { .. })
                )
            })
            .map(|n| b.intersection_area(&body(&n.projected)))
            .fold(0.0, f64::max)
            / b.area().max(1e-9);
        if covered > params.max_hidden {
            labels[i].dropped = Some(Dropped::Hidden { covered });
        }
    }
    labels
}

/// The middle third of a tower's box: its body, without the arms' span.
fn body(b: &PixelBox) -> PixelBox {
    let third = b.width() / 3.0;
    PixelBox::new(b.left + third, b.top, b.right - third, b.bottom)
}

/// How well a detector's box `d` explains a projected one `p`: the IoU of
/// their shapes once centred on each other, discounted by how far apart the
/// centres are in units of the projected height. A pose error moves every
/// projection by tens of pixels; it does not change the shapes.
fn agreement(p: &PixelBox, d: &PixelBox) -> f64 {
    let (dx, dy) = (d.center_x() - p.center_x(), d.center_y() - p.center_y());
    let moved = PixelBox::new(p.left + dx, p.top + dy, p.right + dx, p.bottom + dy);
    let offset = dx.hypot(dy) / p.height().max(1.0);
    if offset > MAX_OFFSET {
        return 0.0;
    }
    moved.iou(d) * (1.0 - offset / MAX_OFFSET).sqrt()
}

/// A detection whose centre is farther than this many projected heights
/// from a projection is another tower's.
const MAX_OFFSET: f64 = 0.6;

/// Snaps each kept label to the detector's box that best agrees with it in
/// shape and place (one to one; shape IoU at least `snap_iou`); moves the
/// others by the frame's offset, and drops those of them at the edge of a
/// `width` x `height` frame.
pub fn snap(
    labels: &mut [TowerLabel],
    detections: &[PixelBox],
    params: &LabelParams,
    (width, height): (f64, f64),
) {
    let kept: Vec<usize> = (0..labels.len())
        .filter(|&i| labels[i].dropped.is_none())
        .collect();
    for (r, c) in max_score_matching(
        kept.len(),
        detections.len(),
        |r, c| agreement(&labels[kept[r]].projected, &detections[c]),
        params.snap_iou * 0.5,
    ) {
        let p = labels[kept[r]].projected;
        let (dx, dy) = (
            detections[c].center_x() - p.center_x(),
            detections[c].center_y() - p.center_y(),
        );
        let shape =
            PixelBox::new(p.left + dx, p.top + dy, p.right + dx, p.bottom + dy).iou(&detections[c]);
        if shape >= params.snap_iou {
            let b = snapped_box(&p, &detections[c], (width, height));
            labels[kept[r]].snapped = Some((b, p.iou(&b)));
        }
    }
    shift_the_rest(labels);
    for l in labels
        .iter_mut()
        .filter(|l| l.dropped.is_none() && l.snapped.is_none())
    {
        let b = l.shifted.unwrap_or(l.projected);
        let at_edge = b.left <= EDGE_PX
            || b.top <= EDGE_PX
            || b.right >= width - EDGE_PX
            || b.bottom >= height - EDGE_PX;
        if at_edge {
            l.dropped = Some(Dropped::Unconfirmed);
        }
    }
}

/// A label's box within this many pixels of the frame's edge may be cut by it.
const EDGE_PX: f64 = 2.0;

/// The box a snapped label writes: the detector's across, and the
/// projection's height centred where the detector put the tower. A pose
/// error moves a projection by tens of pixels but scales it by a percent
/// or two (1.5 m of GNSS error 100 m off), while a detector's top and foot
/// each err by a few percent of the box: the projection's height is the
/// better of the two. Where the frame cuts either box, the detector's whole.
fn snapped_box(projected: &PixelBox, detected: &PixelBox, (width, height): (f64, f64)) -> PixelBox {
    let whole = |b: &PixelBox| b.top > EDGE_PX && b.bottom < height - EDGE_PX;
    if !whole(projected) || !whole(detected) {
        return *detected;
    }
    let (cy, half) = (detected.center_y(), projected.height() / 2.0);
    if cy - half <= 0.0 || cy + half >= height {
        return *detected;
    }
    PixelBox::new(
        detected.left.max(0.0),
        cy - half,
        detected.right.min(width),
        cy + half,
    )
}

/// Moves the unsnapped labels by the median offset of the snapped ones.
fn shift_the_rest(labels: &mut [TowerLabel]) {
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let offsets: Vec<(f64, f64)> = labels
        .iter()
        .filter_map(|l| {
            let (d, _) = l.snapped?;
            Some((
                d.center_x() - l.projected.center_x(),
                d.center_y() - l.projected.center_y(),
            ))
        })
        .collect();
    if offsets.is_empty() {
        return;
    }
    let dx = median(offsets.iter().map(|o| o.0).collect());
    let dy = median(offsets.iter().map(|o| o.1).collect());
    for l in labels
        .iter_mut()
        .filter(|l| l.dropped.is_none() && l.snapped.is_none())
    {
        let p = l.projected;
        l.shifted = Some(PixelBox::new(
            p.left + dx,
            p.top + dy,
            p.right + dx,
            p.bottom + dy,
        ));
    }
}

/// One labelled frame of a flight: its time, seconds, and its labels.
pub type FrameLabels = (f64, Vec<TowerLabel>);

/// Gives each unsnapped label the width of the same tower's snapped box in
/// the nearest frame within `width_from_s`, scaled by the two heights. The
/// projection knows the tower's height but not its arms' span or which way
/// they face (the database holds neither), so its width errs by up to half;
/// the detector's box in a nearby frame saw the tower from about the same
/// side. Its place and height stay the projection's (moved by the frame's
/// offset).
pub fn borrow_widths(frames: &mut [FrameLabels], params: &LabelParams) {
    let mut snapped: std::collections::HashMap<usize, Vec<(f64, f64)>> = Default::default();
    for (t, labels) in frames.iter() {
        for l in labels.iter().filter(|l| l.dropped.is_none()) {
            if let Some((b, _)) = l.snapped
                && b.height() > 0.0
            {
                snapped
                    .entry(l.tower)
                    .or_default()
                    .push((*t, b.width() / b.height()));
            }
        }
    }
    for (t, labels) in frames.iter_mut() {
        for l in labels
            .iter_mut()
            .filter(|l| l.dropped.is_none() && l.snapped.is_none())
        {
            let Some(&(from, aspect)) = snapped.get(&l.tower).and_then(|v| {
                v.iter()
                    .filter(|(s, _)| (s - *t).abs() <= params.width_from_s)
                    .min_by(|a, b| (a.0 - *t).abs().total_cmp(&(b.0 - *t).abs()))
            }) else {
                continue;
            };
            let b = l.shifted.unwrap_or(l.projected);
            let half = aspect * b.height() / 2.0;
            l.shifted = Some(PixelBox::new(
                b.center_x() - half,
                b.top,
                b.center_x() + half,
                b.bottom,
            ));
            l.width_from_s = Some(from);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_geometry::{Attitude, CameraMount, Intrinsics};

    fn tower(id: &str, east: f64, north: f64) -> SurveyTower {
        SurveyTower {
            id: id.into(),
            tower_type: TowerType::A,
            foot_in_world: Point3::new(east, north, 0.0),
            height_m: 30.0,
            width_m: 10.0,
        }
    }

    fn setup() -> (PinholeCamera, Pose) {
        let camera = PinholeCamera::pinhole(
            Intrinsics::from_hfov(1280, 720, 70.0),
            CameraMount::default(),
        );
        // 30 m up, looking north.
        let pose = Pose {
            position_in_world: Point3::new(0.0, 0.0, 30.0),
            attitude: Attitude::level(std::f64::consts::FRAC_PI_2),
        };
        (camera, pose)
    }

    #[test]
    fn a_tower_ahead_is_labelled_top_to_foot_and_the_rest_say_why_not() {
        let (camera, pose) = setup();
        let towers = [
            tower("ahead", 0.0, 100.0),
            tower("behind", 0.0, -100.0),
            tower("far", 0.0, 3000.0),
            tower("hidden", 0.5, 300.0),
            tower("aside", 400.0, 100.0),
        ];
        let labels = project_labels(
            &LabelCamera::new(camera),
            &pose,
            &towers,
            &LabelParams::default(),
        );
        let of = |id: &str| labels.iter().find(|l| towers[l.tower].id == id);
        let ahead = of("ahead").expect("labelled");
        assert!(ahead.dropped.is_none());
        // The convention's foot and top, on the tower's axis: the foot 30 m
        // below the camera at 100 m, the top level with it. Not the
        // footprint's near corners, 5 m nearer and 15 px lower.
        let f = camera.intrinsics.fy;
        let cy = camera.intrinsics.cy;
        assert!(
            (ahead.projected.bottom - (cy + f * 30.0 / 100.0)).abs() < 0.5,
            "{ahead:?}"
        );
        assert!((ahead.projected.top - cy).abs() < 0.5, "{ahead:?}");
        // As wide as the footprint's nearest corners.
        let half_width = f * 5.0 / 95.0;
        assert!(
            (ahead.projected.width() - 2.0 * half_width).abs() < 0.5,
            "{ahead:?}"
        );
        assert!(of("behind").is_none(), "behind the camera: not projected");
        assert!(matches!(
            of("far").and_then(|l| l.dropped),
            Some(Dropped::TooSmall { .. })
        ));
        assert!(matches!(
            of("hidden").and_then(|l| l.dropped),
            Some(Dropped::Hidden { .. })
        ));
        assert!(matches!(
            of("aside").and_then(|l| l.dropped),
            Some(Dropped::OutOfView)
        ));
    }

    #[test]
    fn a_label_takes_the_detector_s_box_where_they_agree() {
        let (camera, pose) = setup();
        let towers = [tower("ahead", 0.0, 100.0), tower("left", -40.0, 120.0)];
        let mut labels = project_labels(
            &LabelCamera::new(camera),
            &pose,
            &towers,
            &LabelParams::default(),
        );
        let ahead = labels.iter().position(|l| l.tower == 0).expect("ahead");
        let p = labels[ahead].projected;
        let detected = PixelBox::new(p.left + 3.0, p.top - 2.0, p.right + 3.0, p.bottom + 1.0);
        let elsewhere = PixelBox::new(1100.0, 10.0, 1120.0, 60.0);
        snap(
            &mut labels,
            &[elsewhere, detected],
            &LabelParams::default(),
            (1280.0, 720.0),
        );
        // The detector's box across and where it is; the projection's height.
        let written = labels[ahead].label().expect("kept");
        assert_eq!(
            (written.left, written.right),
            (detected.left, detected.right)
        );
        assert!((written.center_y() - detected.center_y()).abs() < 1e-9);
        assert!((written.height() - p.height()).abs() < 1e-9, "{written:?}");
        let left = labels.iter().find(|l| l.tower == 1).expect("left");
        assert!(left.snapped.is_none(), "no detector box agrees");
        // It moves with the frame's offset: the snapped label's centre shift.
        let q = left.projected;
        let moved = PixelBox::new(q.left + 3.0, q.top - 0.5, q.right + 3.0, q.bottom - 0.5);
        let got = left.label().expect("kept");
        assert!(
            (got.left - moved.left).abs() < 1e-9 && (got.top - moved.top).abs() < 1e-9,
            "{got:?} against {moved:?}"
        );
    }

    #[test]
    fn an_unsnapped_label_borrows_the_nearest_snapped_width_of_its_tower() {
        let (camera, pose) = setup();
        let towers = [tower("ahead", 0.0, 100.0), tower("left", -40.0, 120.0)];
        let labeller = LabelCamera::new(camera);
        let frame = || project_labels(&labeller, &pose, &towers, &LabelParams::default());
        let ahead = |labels: &[TowerLabel]| labels.iter().position(|l| l.tower == 0).unwrap();
        let p = {
            let l = frame();
            l[ahead(&l)].projected
        };
        // Seen at 0 s and 30 s with the detector's boxes, 0.45 and 0.3 times
        // as wide as they are tall (the projection: 0.35); at 10 s and 51 s
        // with none.
        let snapped_at = |aspect: f64| {
            let mut labels = frame();
            let half = aspect * p.height() / 2.0;
            let b = PixelBox::new(p.center_x() - half, p.top, p.center_x() + half, p.bottom);
            snap(&mut labels, &[b], &LabelParams::default(), (1280.0, 720.0));
            let i = ahead(&labels);
            assert!(labels[i].snapped.is_some(), "{:?} snaps", labels[i]);
            labels
        };
        let mut flight: Vec<FrameLabels> = vec![
            (0.0, snapped_at(0.45)),
            (10.0, frame()),
            (30.0, snapped_at(0.3)),
            (51.0, frame()),
        ];
        borrow_widths(&mut flight, &LabelParams::default());
        let at = |k: usize| {
            let l = &flight[k].1[ahead(&flight[k].1)];
            (l.label().unwrap(), l.width_from_s)
        };
        let (b, from) = at(1);
        assert_eq!(from, Some(0.0), "the nearest frame in time");
        assert!((b.width() - 0.45 * p.height()).abs() < 1e-9, "{b:?}");
        assert!(
            (b.height() - p.height()).abs() < 1e-9 && (b.center_x() - p.center_x()).abs() < 1e-9
        );
        // 21 s from the nearest snapped frame: its own projection's width.
        let (b, from) = at(3);
        assert_eq!(from, None);
        assert!((b.width() - p.width()).abs() < 1e-9, "{b:?}");
        // A tower never snapped keeps its projected width.
        let left = flight[1].1.iter().find(|l| l.tower == 1).unwrap();
        assert!(left.width_from_s.is_none() && left.label().unwrap().width() > 0.0);
    }
}
