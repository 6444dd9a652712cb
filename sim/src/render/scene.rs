//! Towers, power lines and distractors as antialiased vector shapes, drawn far
//! to near so nearer objects hide farther ones.

use nalgebra::{Isometry3, Point2, Point3, Vector3};
use tiny_skia::{FillRule, LineCap, Paint, PathBuilder, Pixmap, Shader, Stroke, Transform};
use towernav_geometry::PinholeCamera;

use super::conditions::{Conditions, TowerPaint};
use crate::tower_model::MemberKind;
use crate::world::{Distractor, World};

/// Points closer than this to the camera plane are clipped away.
const NEAR_M: f64 = 0.5;

/// A tower's members in world coordinates, grouped by kind.
pub struct TowerGeometry {
    pub members: Vec<(MemberKind, Point3<f64>, Point3<f64>)>,
    pub axis_mid_in_world: Point3<f64>,
}

/// A conductor span between two towers, sampled along its sag.
pub struct Span {
    pub points_in_world: Vec<Point3<f64>>,
}

pub fn tower_geometry(world: &World) -> Vec<TowerGeometry> {
    world
        .towers
        .iter()
        .map(|t| {
            let world_from_tower = t.world_from_tower();
            let members = t
                .model()
                .members
                .iter()
                .map(|m| (m.kind, world_from_tower * m.a, world_from_tower * m.b))
                .collect();
            TowerGeometry {
                members,
                axis_mid_in_world: t.foot_in_world + Vector3::new(0.0, 0.0, t.height_m / 2.0),
            }
        })
        .collect()
}

/// Conductors hang between matching attachment points of neighbours on a line,
/// with a parabolic sag of 3 % of the span.
pub fn spans(world: &World) -> Vec<Span> {
    let mut out = Vec::new();
    for line in &world.lines {
        for pair in line.windows(2) {
            let (a, b) = (&world.towers[pair[0]], &world.towers[pair[1]]);
            let (ma, mb) = (a.model(), b.model());
            let (wa, wb) = (a.world_from_tower(), b.world_from_tower());
            for (pa, pb) in ma.attachments.iter().zip(&mb.attachments) {
                let (pa, pb) = (wa * pa, wb * pb);
                let sag = 0.03 * (pb - pa).norm();
                let points_in_world = (0..=12)
                    .map(|i| {
                        let s = f64::from(i) / 12.0;
                        pa + (pb - pa) * s - Vector3::new(0.0, 0.0, 4.0 * sag * s * (1.0 - s))
                    })
                    .collect();
                out.push(Span { points_in_world });
            }
        }
    }
    out
}

enum Item<'a> {
    Tower(&'a TowerGeometry),
    Span(&'a Span),
    Distractor(&'a Distractor),
}

pub struct Scene<'a> {
    pub camera: &'a PinholeCamera,
    pub camera_from_world: Isometry3<f64>,
    pub conditions: &'a Conditions,
}

impl Scene<'_> {
    fn depth(&self, p: &Point3<f64>) -> f64 {
        (self.camera_from_world * p).z
    }

    fn pixel(&self, p_in_camera: &Point3<f64>) -> Option<Point2<f64>> {
        self.camera.project(p_in_camera)
    }

    /// Segment in the image, clipped to the near plane; `None` if wholly behind.
    fn segment(&self, a: &Point3<f64>, b: &Point3<f64>) -> Option<(Point2<f64>, Point2<f64>)> {
        let (mut a, mut b) = (self.camera_from_world * a, self.camera_from_world * b);
        if a.z < NEAR_M && b.z < NEAR_M {
            return None;
        }
        if a.z < NEAR_M {
            a = a + (b - a) * ((NEAR_M - a.z) / (b.z - a.z));
        } else if b.z < NEAR_M {
            b = b + (a - b) * ((NEAR_M - b.z) / (a.z - b.z));
        }
        Some((self.pixel(&a)?, self.pixel(&b)?))
    }

    /// A colour lit by the day and hazed by distance, as a tiny-skia paint.
    fn paint(&self, rgb: [f32; 3], distance_m: f64, alpha: f32) -> Paint<'static> {
        let keep = self.conditions.transmittance(distance_m);
        let haze = self.conditions.haze_colour();
        let light = self.conditions.daylight();
        let c = [0, 1, 2].map(|i| rgb[i] * light * keep + haze[i] * (1.0 - keep));
        let mut paint = Paint {
            anti_alias: true,
            ..Paint::default()
        };
        paint.shader = Shader::SolidColor(
            tiny_skia::Color::from_rgba(
                c[0].clamp(0.0, 1.0),
                c[1].clamp(0.0, 1.0),
                c[2].clamp(0.0, 1.0),
                alpha.clamp(0.0, 1.0),
            )
            .unwrap_or(tiny_skia::Color::BLACK),
        );
        paint
    }

    /// Stroke `segments` (pixels) of `width_m` at `depth_m`: thinner than a
    /// pixel becomes a one-pixel line with its coverage as alpha. Each segment
    /// is first clipped to the image and a band around it wider than the
    /// stroke: a member beside the camera projects hundreds of thousands of
    /// pixels out, and one whose near-plane clip leaves no length there has
    /// nothing to stroke (tiny-skia refuses such a path).
    fn stroke(
        &self,
        pixmap: &mut Pixmap,
        segments: impl IntoIterator<Item = (Point2<f64>, Point2<f64>)>,
        rgb: [f32; 3],
        width_m: f64,
        depth_m: f64,
        distance_m: f64,
    ) {
        let width_px = (width_m * self.camera.intrinsics.fx / depth_m.max(NEAR_M)) as f32;
        let (width, alpha) = if width_px < 1.0 {
            (1.0, width_px.max(0.12))
        } else {
            (width_px, 1.0)
        };
        let k = &self.camera.intrinsics;
        let band = f64::from(width) + 16.0;
        let view = ClipRect {
            left: -band,
            top: -band,
            right: f64::from(k.width) + band,
            bottom: f64::from(k.height) + band,
        };
        let mut pb = PathBuilder::new();
        for (a, b) in segments {
            if let Some((a, b)) = view.clip(&a, &b)
                && (b - a).norm() >= MIN_SEGMENT_PX
            {
                pb.move_to(a.x as f32, a.y as f32);
                pb.line_to(b.x as f32, b.y as f32);
            }
        }
        let Some(path) = pb.finish() else { return };
        let stroke = Stroke {
            width,
            line_cap: LineCap::Butt,
            ..Stroke::default()
        };
        let paint = self.paint(rgb, distance_m, alpha);
        pixmap.stroke_path(&path, &paint, &stroke, Transform::identity(), None);
    }

    fn draw_tower(&self, pixmap: &mut Pixmap, tower: &TowerGeometry) {
        let depth = self.depth(&tower.axis_mid_in_world);
        let distance = depth.max(1.0);
        let paint = self.conditions.tower_paint;
        let height = (2.0 * tower.axis_mid_in_world.z).max(1.0);
        let bands: u32 = if paint == TowerPaint::RedWhite { 2 } else { 1 };
        for kind in MemberKind::ALL {
            let galvanised = match kind {
                MemberKind::Leg => [0.52, 0.54, 0.56],
                MemberKind::Brace => [0.62, 0.64, 0.66],
                MemberKind::Arm => [0.58, 0.60, 0.62],
                MemberKind::Insulator => [0.20, 0.24, 0.30],
            };
            for parity in 0..bands {
                let band_of = |a: &Point3<f64>, b: &Point3<f64>| {
                    ((a.z + b.z) / 2.0 / height * 7.0).max(0.0) as u32
                };
                let segments = tower
                    .members
                    .iter()
                    .filter(|(k, a, b)| *k == kind && (bands == 1 || band_of(a, b) % 2 == parity))
                    .filter_map(|(_, a, b)| self.segment(a, b));
                let rgb = if kind == MemberKind::Insulator {
                    galvanised
                } else {
                    paint.colour(galvanised, parity)
                };
                self.stroke(
                    pixmap,
                    segments,
                    rgb,
                    kind.width_m(),
                    depth.max(2.0),
                    distance,
                );
            }
        }
    }

    /// Each piece of the sagging conductor gets the width its own depth gives:
    /// a span can run from beside the camera to hundreds of metres away.
    fn draw_span(&self, pixmap: &mut Pixmap, span: &Span) {
        for pair in span.points_in_world.windows(2) {
            let Some(piece) = self.segment(&pair[0], &pair[1]) else {
                continue;
            };
            let depth = self
                .depth(&nalgebra::center(&pair[0], &pair[1]))
                .max(NEAR_M);
            // Conductors are ~3 cm across: faint hairlines except close up.
            self.stroke(pixmap, [piece], [0.25, 0.25, 0.28], 0.03, depth, depth);
        }
    }

    fn draw_distractor(&self, pixmap: &mut Pixmap, d: &Distractor) {
        let depth = self.depth(&d.foot_in_world());
        if depth < NEAR_M {
            return;
        }
        if let Some(groups) = super::clutter::groups(d) {
            for g in groups {
                let segments = g.members.iter().filter_map(|(a, b)| self.segment(a, b));
                self.stroke(pixmap, segments, g.rgb, g.width_m, depth, depth);
            }
            return;
        }
        match *d {
            Distractor::Tree {
                foot_in_world,
                height_m,
                crown_radius_m,
            } => {
                let crown = foot_in_world + Vector3::new(0.0, 0.0, height_m - crown_radius_m);
                let trunk = self.segment(&foot_in_world, &crown);
                self.stroke(pixmap, trunk, [0.30, 0.22, 0.15], 0.4, depth, depth);
                let centre = self.camera_from_world * crown;
                if let Some(c) = self.pixel(&centre) {
                    let r = (crown_radius_m * self.camera.intrinsics.fx / centre.z) as f32;
                    if let Some(path) = PathBuilder::from_circle(c.x as f32, c.y as f32, r.max(0.5))
                    {
                        let paint = self.paint([0.16, 0.30, 0.12], depth, 1.0);
                        pixmap.fill_path(
                            &path,
                            &paint,
                            FillRule::Winding,
                            Transform::identity(),
                            None,
                        );
                    }
                }
            }
            Distractor::Building { .. } => {
                let corners = d.bounding_corners();
                let projected: Vec<Point2<f64>> = corners
                    .iter()
                    .filter_map(|p| {
                        let c = self.camera_from_world * p;
                        (c.z > NEAR_M).then(|| self.pixel(&c)).flatten()
                    })
                    .collect();
                if projected.len() < 8 {
                    return;
                }
                self.fill_hull(pixmap, &projected, [0.62, 0.58, 0.52], depth);
                self.fill_hull(pixmap, &projected[4..], [0.55, 0.30, 0.25], depth);
            }
            Distractor::Pole {
                foot_in_world,
                height_m,
            } => {
                let top = foot_in_world + Vector3::new(0.0, 0.0, height_m);
                // A cross-bar 0.6 m below the top, 1.6 m wide.
                let bar_centre = top - Vector3::new(0.0, 0.0, 0.6);
                let half_bar = Vector3::new(0.0, 0.8, 0.0);
                let pole = [
                    (foot_in_world, top),
                    (bar_centre - half_bar, bar_centre + half_bar),
                ]
                .into_iter()
                .filter_map(|(a, b)| self.segment(&a, &b));
                self.stroke(pixmap, pole, [0.42, 0.36, 0.30], 0.3, depth, depth);
            }
            _ => {}
        }
    }

    fn fill_hull(&self, pixmap: &mut Pixmap, points: &[Point2<f64>], rgb: [f32; 3], distance: f64) {
        let hull = convex_hull(points);
        let mut pb = PathBuilder::new();
        for (i, p) in hull.iter().enumerate() {
            if i == 0 {
                pb.move_to(p.x as f32, p.y as f32);
            } else {
                pb.line_to(p.x as f32, p.y as f32);
            }
        }
        pb.close();
        if let Some(path) = pb.finish() {
            let paint = self.paint(rgb, distance, 1.0);
            pixmap.fill_path(
                &path,
                &paint,
                FillRule::Winding,
                Transform::identity(),
                None,
            );
        }
    }

    /// Draw everything in front of the camera, farthest first.
    pub fn draw(
        &self,
        pixmap: &mut Pixmap,
        towers: &[TowerGeometry],
        spans: &[Span],
        distractors: &[Distractor],
    ) {
        let mut items: Vec<(f64, Item)> = Vec::with_capacity(towers.len() + spans.len());
        let eye = self.camera_from_world.inverse().translation.vector;
        let range = |p: &Point3<f64>| (p.coords - eye).xy().norm();
        items.extend(
            towers
                .iter()
                .map(|t| (range(&t.axis_mid_in_world), Item::Tower(t))),
        );
        items.extend(spans.iter().map(|s| {
            let mid = &s.points_in_world[s.points_in_world.len() / 2];
            // Wires hang in front of the towers they join from most viewpoints.
            (range(mid) - 1.0, Item::Span(s))
        }));
        if self.conditions.distractors {
            items.extend(
                distractors
                    .iter()
                    .map(|d| (range(&d.foot_in_world()), Item::Distractor(d))),
            );
        }
        items.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (_, item) in items {
            match item {
                Item::Tower(t) => self.draw_tower(pixmap, t),
                Item::Span(s) => self.draw_span(pixmap, s),
                Item::Distractor(d) => self.draw_distractor(pixmap, d),
            }
        }
    }
}

/// Pieces shorter than this, pixels, have no direction to stroke across.
const MIN_SEGMENT_PX: f64 = 1e-3;

/// An axis-aligned rectangle in pixels that segments are clipped to.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ClipRect {
    left: f64,
    top: f64,
    right: f64,
    bottom: f64,
}

impl ClipRect {
    /// The part of segment `a`-`b` inside the rectangle (Liang-Barsky);
    /// `None` when none of it is.
    fn clip(&self, a: &Point2<f64>, b: &Point2<f64>) -> Option<(Point2<f64>, Point2<f64>)> {
        let d = b - a;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, q) in [
            (-d.x, a.x - self.left),
            (d.x, self.right - a.x),
            (-d.y, a.y - self.top),
            (d.y, self.bottom - a.y),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let t = q / p;
                if p < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        (t0 <= t1 && t0.is_finite() && t1.is_finite()).then(|| (a + d * t0, a + d * t1))
    }
}

/// Andrew's monotone chain: the convex hull, counter-clockwise.
fn convex_hull(points: &[Point2<f64>]) -> Vec<Point2<f64>> {
    let mut pts: Vec<Point2<f64>> = points.to_vec();
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: &Point2<f64>, a: &Point2<f64>, b: &Point2<f64>| {
        (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
    };
    let mut hull: Vec<Point2<f64>> = Vec::with_capacity(pts.len() * 2);
    let chain = |hull: &mut Vec<Point2<f64>>, p: &Point2<f64>, start: usize| {
        while hull.len() >= start + 2
            && cross(&hull[hull.len() - 2], &hull[hull.len() - 1], p) <= 0.0
        {
            hull.pop();
        }
        hull.push(*p);
    };
    for p in &pts {
        chain(&mut hull, p, 0);
    }
    hull.pop();
    let upper = hull.len();
    for p in pts.iter().rev() {
        chain(&mut hull, p, upper);
    }
    hull.pop();
    hull
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    const VIEW: ClipRect = ClipRect {
        left: -10.0,
        top: -10.0,
        right: 1290.0,
        bottom: 730.0,
    };

    fn inside(p: &Point2<f64>) -> bool {
        let e = 1e-6;
        p.x >= VIEW.left - e
            && p.x <= VIEW.right + e
            && p.y >= VIEW.top - e
            && p.y <= VIEW.bottom + e
    }

    #[test]
    fn a_segment_from_far_outside_is_cut_at_the_band() {
        let (a, b) = VIEW
            .clip(&Point2::new(98439.6, 360.0), &Point2::new(640.0, 360.0))
            .expect("crosses the view");
        assert!((a.x - VIEW.right).abs() < 1e-9 && (b.x - 640.0).abs() < 1e-12);
        assert_eq!(
            VIEW.clip(
                &Point2::new(98439.6, 64017.1),
                &Point2::new(85643.4, 64017.1)
            ),
            None,
            "wholly outside"
        );
    }

    proptest! {
        #[test]
        fn clipped_pieces_lie_inside_and_on_the_segment(
            ax in -5e5..5e5f64, ay in -5e5..5e5f64, bx in -5e5..5e5f64, by in -5e5..5e5f64,
        ) {
            let (a, b) = (Point2::new(ax, ay), Point2::new(bx, by));
            if let Some((p, q)) = VIEW.clip(&a, &b) {
                prop_assert!(inside(&p) && inside(&q));
                // Both ends are on the segment a-b.
                for x in [p, q] {
                    let along = (x - a).dot(&(b - a)) / (b - a).norm_squared().max(1e-300);
                    let off = (a + (b - a) * along - x).norm();
                    prop_assert!((-1e-9..=1.0 + 1e-9).contains(&along) && off < 1e-6 * (1.0 + (b - a).norm()));
                }
            } else {
                // Nothing of it is inside: its midpoint and ends are out.
                prop_assert!(!inside(&a) && !inside(&b) && !inside(&nalgebra::center(&a, &b)));
            }
        }
    }
}
