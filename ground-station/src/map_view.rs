//! The map: towers by type with their ids, each UAV's estimated track with its
//! covariance ellipse, the simulator's true track, lines to the towers the
//! current fix uses, follow mode and a distance measure. The wheel zooms about
//! the pointer (as maps do; Follow keeps the zoom the operator set), drag
//! pans, double-click resets. The background is the
//! plot's metric grid, or local tiles when the operator gave a tile folder.

use egui::Color32;
use egui_plot::{
    Legend, Line, LineStyle, MarkerShape, Plot, PlotBounds, PlotPoint, PlotUi, Points, Polygon,
    Text,
};
use towernav_protocol::{NodeId, TowerType};

use crate::fleet::{Fleet, Link, Nav};
use crate::tiles::TileLayer;

/// A tower as the map draws it: east/north about the map datum.
#[derive(Debug, Clone, PartialEq)]
pub struct MapTower {
    pub id: String,
    pub tower_type: TowerType,
    pub en: [f64; 2],
}

#[derive(Debug, Default)]
pub struct MapState {
    /// Keep the selected UAV in the middle of the map.
    pub follow: bool,
    /// Clicks on the map place the measure's ends.
    pub measuring: bool,
    pub measure: Vec<[f64; 2]>,
    /// Half the width of the followed view, metres.
    follow_half_width_m: Option<f64>,
    /// Where the pointer is over the map (east, north), if it is.
    pub cursor: Option<[f64; 2]>,
    /// Whether the first view was fitted to the towers.
    fitted: bool,
}

/// The first view: the towers within [`crate::app::MAP_CORE_RADIUS_M`] of the
/// origin (the towers' median) with a margin, so one tower thousands of km
/// off does not zoom the map out to a continent. `None` without towers.
pub fn first_view(towers: &[MapTower]) -> Option<([f64; 2], [f64; 2])> {
    let core = towers
        .iter()
        .filter(|t| t.en[0].hypot(t.en[1]) <= crate::app::MAP_CORE_RADIUS_M);
    let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for t in core {
        for k in 0..2 {
            min[k] = min[k].min(t.en[k]);
            max[k] = max[k].max(t.en[k]);
        }
    }
    if !min[0].is_finite() {
        return None;
    }
    let half = (0.5 * (max[0] - min[0]).max(max[1] - min[1]) * 1.15).max(200.0);
    let centre = [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1])];
    Some((
        [centre[0] - half, centre[1] - half],
        [centre[0] + half, centre[1] + half],
    ))
}

/// The narrowest and widest followed views, half-widths in metres.
const MIN_FOLLOW_HALF_WIDTH_M: f64 = 20.0;
const MAX_FOLLOW_HALF_WIDTH_M: f64 = 50_000.0;

/// How much a wheel movement of `scroll_px` (up is positive) zooms in: a
/// factor above 1 zooms in, below 1 out; 100 px (about one notch) is 1.5x.
pub fn wheel_zoom(scroll_px: f64) -> f64 {
    (scroll_px / 100.0 * 1.5f64.ln()).exp()
}

/// The map's east/north point as latitude and longitude, for the readout under the pointer.
pub fn cursor_text(datum: &towernav_geometry::Datum, en: [f64; 2]) -> String {
    let g = datum.to_geodetic(&nalgebra::Point3::new(en[0], en[1], 0.0));
    format!("cursor {:.6}, {:.6}", g.lat_deg, g.lon_deg)
}

/// Points of the ellipse `sigmas` standard deviations out, of a 2x2 east/north covariance.
pub fn covariance_ellipse(center: [f64; 2], cov: [[f64; 2]; 2], sigmas: f64) -> Vec<[f64; 2]> {
    let (a, b, d) = (cov[0][0], cov[0][1], cov[1][1]);
    // Eigen-decomposition of the symmetric 2x2 matrix.
    let mean = 0.5 * (a + d);
    let spread = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = ((mean + spread).max(0.0), (mean - spread).max(0.0));
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    let (r1, r2) = (sigmas * l1.sqrt(), sigmas * l2.sqrt());
    let (c, s) = (angle.cos(), angle.sin());
    (0..=48)
        .map(|i| {
            let t = f64::from(i) / 48.0 * std::f64::consts::TAU;
            let (x, y) = (r1 * t.cos(), r2 * t.sin());
            [center[0] + c * x - s * y, center[1] + s * x + c * y]
        })
        .collect()
}

fn tower_marker(t: TowerType) -> MarkerShape {
    match t {
        TowerType::A => MarkerShape::Up,
        TowerType::B => MarkerShape::Square,
        TowerType::C => MarkerShape::Circle,
        TowerType::D => MarkerShape::Cross,
        _ => MarkerShape::Diamond,
    }
}

/// Distinct colours per UAV, stable across frames.
pub fn uav_color(index: usize) -> Color32 {
    const PALETTE: [Color32; 8] = [
        Color32::from_rgb(80, 200, 120),
        Color32::from_rgb(90, 160, 255),
        Color32::from_rgb(255, 170, 60),
        Color32::from_rgb(230, 90, 200),
        Color32::from_rgb(60, 220, 220),
        Color32::from_rgb(240, 230, 80),
        Color32::from_rgb(255, 110, 110),
        Color32::from_rgb(170, 140, 255),
    ];
    PALETTE[index % PALETTE.len()]
}

pub fn show(
    ui: &mut egui::Ui,
    state: &mut MapState,
    fleet: &Fleet,
    towers: &[MapTower],
    tiles: Option<&mut TileLayer>,
    selected: Option<&NodeId>,
    now_s: f64,
) {
    ui.horizontal(|ui| {
        ui.checkbox(&mut state.follow, "Follow")
            .on_hover_text("keep the selected UAV in the middle");
        if ui
            .toggle_value(&mut state.measuring, "Measure")
            .on_hover_text("click two points on the map")
            .changed()
        {
            state.measure.clear();
        }
        if let [a, b] = state.measure[..] {
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            ui.label(format!("distance {d:.1} m"));
        }
        if let Some(en) = state.cursor {
            ui.label(cursor_text(&fleet.datum, en));
        }
    });
    let followed = selected
        .filter(|_| state.follow)
        .and_then(|uav| fleet.uavs.get(uav))
        .and_then(|v| v.trail.back().copied());
    let response = Plot::new("map")
        .data_aspect(1.0)
        .legend(Legend::default())
        .x_axis_label("east (m)")
        .y_axis_label("north (m)")
        .allow_drag(!state.measuring)
        // The wheel zooms, below; it does not pan.
        .allow_scroll(false)
        .show(ui, |plot| {
            let wheel = if plot.response().hovered() {
                plot.ctx().input(|i| i.smooth_scroll_delta.y)
            } else {
                0.0
            };
            let zoom = wheel_zoom(f64::from(wheel));
            if let Some(layer) = tiles {
                layer.draw(plot);
            }
            draw_towers(plot, towers);
            draw_fleet(plot, fleet, towers, selected, now_s);
            if !state.fitted
                && let Some((min, max)) = first_view(towers)
            {
                plot.set_plot_bounds(PlotBounds::from_min_max(min, max));
                state.fitted = true;
            }
            if let Some(center) = followed {
                let half = state
                    .follow_half_width_m
                    .get_or_insert_with(|| 0.5 * plot.plot_bounds().width().max(200.0));
                // Following, the wheel sets the followed view's width.
                *half = (*half / zoom).clamp(MIN_FOLLOW_HALF_WIDTH_M, MAX_FOLLOW_HALF_WIDTH_M);
                let half = *half;
                plot.set_plot_bounds(PlotBounds::from_min_max(
                    [center[0] - half, center[1] - half],
                    [center[0] + half, center[1] + half],
                ));
            } else {
                state.follow_half_width_m = None;
                if zoom != 1.0 {
                    plot.zoom_bounds_around_hovered(egui::Vec2::splat(zoom as f32));
                }
            }
            if !state.measure.is_empty() {
                plot.line(
                    Line::new("measure", state.measure.clone())
                        .color(Color32::WHITE)
                        .style(LineStyle::dashed_dense()),
                );
                plot.points(
                    Points::new("measure", state.measure.clone())
                        .color(Color32::WHITE)
                        .radius(3.0),
                );
            }
            let pointer = plot.pointer_coordinate();
            let clicked = state.measuring && plot.response().clicked();
            (pointer, clicked)
        });
    let (pointer, clicked) = response.inner;
    state.cursor = pointer.map(|p| [p.x, p.y]);
    if let Some(p) = pointer.filter(|_| clicked) {
        if state.measure.len() == 2 {
            state.measure.clear();
        }
        state.measure.push([p.x, p.y]);
    }
}

fn draw_towers(plot: &mut PlotUi<'_>, towers: &[MapTower]) {
    let mut types: Vec<TowerType> = towers.iter().map(|m| m.tower_type).collect();
    types.sort();
    types.dedup();
    for t in types {
        let pts: Vec<[f64; 2]> = towers
            .iter()
            .filter(|m| m.tower_type == t)
            .map(|m| m.en)
            .collect();
        if !pts.is_empty() {
            plot.points(
                Points::new(format!("towers {t}"), pts)
                    .shape(tower_marker(t))
                    .radius(5.0),
            );
        }
    }
    for m in towers {
        plot.text(Text::new(
            "tower ids",
            PlotPoint::new(m.en[0], m.en[1] + 12.0),
            m.id.as_str(),
        ));
    }
}

/// Points drawn per track at most: older points are thinned (every k-th kept),
/// the newest kept exactly. Long dense polylines cost tessellation and fill
/// rate, not information, at map scale.
const MAX_DRAWN_POINTS: usize = 1500;

pub fn thinned(points: &std::collections::VecDeque<[f64; 2]>) -> Vec<[f64; 2]> {
    let n = points.len();
    if n <= MAX_DRAWN_POINTS {
        return points.iter().copied().collect();
    }
    let stride = n.div_ceil(MAX_DRAWN_POINTS);
    let mut out: Vec<[f64; 2]> = points.iter().step_by(stride).copied().collect();
    if let Some(&last) = points.back() {
        out.push(last);
    }
    out
}

/// A trail's stretches between breaks (edge restarts, silences), each
/// thinned; no line is drawn across a break.
pub fn stretches(trail: &std::collections::VecDeque<[f64; 2]>) -> Vec<Vec<[f64; 2]>> {
    let mut out = Vec::new();
    let mut current = std::collections::VecDeque::new();
    for p in trail {
        if p[0].is_nan() || p[1].is_nan() {
            if !current.is_empty() {
                out.push(thinned(&std::mem::take(&mut current)));
            }
        } else {
            current.push_back(*p);
        }
    }
    if !current.is_empty() {
        out.push(thinned(&current));
    }
    out
}

fn draw_fleet(
    plot: &mut PlotUi<'_>,
    fleet: &Fleet,
    towers: &[MapTower],
    selected: Option<&NodeId>,
    now_s: f64,
) {
    for (i, (uav, view)) in fleet.uavs.iter().enumerate() {
        let color = uav_color(i);
        if !view.truth_trail.is_empty() {
            plot.line(
                Line::new("true tracks", thinned(&view.truth_trail))
                    .color(Color32::WHITE.gamma_multiply(0.5))
                    .width(1.0),
            );
        }
        let Some(&last) = view.trail.back() else {
            continue;
        };
        let width = if selected == Some(uav) { 2.5 } else { 1.5 };
        for stretch in stretches(&view.trail) {
            plot.line(Line::new(uav.as_str(), stretch).color(color).width(width));
        }
        let link = fleet.link(uav, now_s);
        let nav = fleet.nav(uav, now_s);
        if let Some(p) = view
            .last_pose
            .as_ref()
            .filter(|_| link.is_live() && nav.is_current())
        {
            // A prediction's ellipse is drawn in amber: where the UAV
            // should be, not where towers put it.
            let color = if nav.is_fix() { color } else { Color32::ORANGE };
            let cov = [
                [p.covariance[0][0], p.covariance[0][1]],
                [p.covariance[1][0], p.covariance[1][1]],
            ];
            plot.polygon(
                Polygon::new(format!("{uav} 2-sigma"), covariance_ellipse(last, cov, 2.0))
                    .fill_color(color.gamma_multiply(0.15))
                    .stroke(egui::Stroke::new(1.0, color)),
            );
            for id in &p.towers_used {
                if let Some(t) = towers.iter().find(|t| &t.id == id) {
                    plot.line(
                        Line::new("sightlines", vec![last, t.en])
                            .color(color.gamma_multiply(0.35))
                            .width(1.0),
                    );
                }
            }
        }
        // A UAV that stopped talking keeps its last place, greyed, without the
        // ellipse and sightlines that would say it still sees towers.
        // A UAV heard but without a fix keeps its last fix, amber, named so.
        let (marker, name) = match (link, nav) {
            (Link::Lost(_), _) => (Color32::RED, format!("{uav}: LINK LOST, last known")),
            (Link::Stale(_), _) => (Color32::GRAY, format!("{uav} (late)")),
            (_, Nav::Predicting { coast_s }) => (
                Color32::ORANGE,
                format!("{uav}: coasting {coast_s:.0} s, predicted"),
            ),
            (_, Nav::Coasting(_)) => (Color32::ORANGE, format!("{uav}: coasting, last fix")),
            (_, Nav::NoFix(_)) => (Color32::YELLOW, format!("{uav}: NO FIX, last fix")),
            (Link::Live | Link::Waiting, _) => (color, uav.to_string()),
        };
        plot.points(
            Points::new(name, vec![last])
                .shape(if link.is_lost() {
                    MarkerShape::Cross
                } else {
                    MarkerShape::Diamond
                })
                .radius(7.0)
                .color(marker),
        );
        // Where it points: a line along the last pose's heading.
        if let Some(p) = &view.last_pose {
            plot.line(
                Line::new(uav.as_str(), heading_line(last, p.yaw_rad))
                    .color(marker)
                    .width(2.0),
            );
        }
    }
}

/// Length of the heading line on the map, metres.
const HEADING_LINE_M: f64 = 60.0;

/// The heading line from `at`, for a yaw counter-clockwise from east (ENU).
pub fn heading_line(at: [f64; 2], yaw_rad: f64) -> Vec<[f64; 2]> {
    vec![
        at,
        [
            at[0] + HEADING_LINE_M * yaw_rad.cos(),
            at[1] + HEADING_LINE_M * yaw_rad.sin(),
        ],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_tower_thousands_of_km_off_moves_neither_origin_nor_first_view() {
        let mut records = crate::test_support::towers();
        records.extend(crate::test_support::towers().into_iter().map(|mut r| {
            r.id = format!("{}x", r.id);
            r.lon_deg += 0.002;
            r
        }));
        let good = crate::app::map_datum(&records).expect("datum");
        let mut typo = records[0].clone();
        typo.id = "T9".into();
        typo.lat_deg = 4.52; // a digit short: about 2,900 km south
        typo.ground_elev_m = -400.0;
        records.push(typo);
        let datum = crate::app::map_datum(&records).expect("datum");
        let moved = good.to_enu(&datum.origin);
        assert!(moved.x.hypot(moved.y) < 200.0, "origin moved {moved:?}");
        assert!((datum.origin.height_m - 25.0).abs() < 1e-9);
        let towers: Vec<MapTower> = records
            .iter()
            .map(|r| MapTower {
                id: r.id.clone(),
                tower_type: r.tower_type,
                en: {
                    let p = datum.to_enu(&towernav_geometry::Geodetic {
                        lat_deg: r.lat_deg,
                        lon_deg: r.lon_deg,
                        height_m: 0.0,
                    });
                    [p.x, p.y]
                },
            })
            .collect();
        let (min, max) = first_view(&towers).expect("a view");
        assert!(max[0] - min[0] < 2_000.0, "{min:?} {max:?}");
        assert!(max[1] - min[1] < 2_000.0, "{min:?} {max:?}");
    }
    use proptest::prelude::*;

    #[test]
    fn the_heading_line_points_where_the_uav_heads() {
        // Yaw 90 degrees counter-clockwise from east: north.
        let line = heading_line([10.0, 20.0], std::f64::consts::FRAC_PI_2);
        assert!((line[1][0] - 10.0).abs() < 1e-9);
        assert!((line[1][1] - (20.0 + HEADING_LINE_M)).abs() < 1e-9);
    }

    #[test]
    fn a_wheel_notch_zooms_by_half_and_back() {
        assert!((wheel_zoom(100.0) - 1.5).abs() < 1e-12);
        assert!((wheel_zoom(100.0) * wheel_zoom(-100.0) - 1.0).abs() < 1e-12);
        assert_eq!(wheel_zoom(0.0), 1.0);
    }

    #[test]
    fn the_cursor_reads_as_the_latitude_and_longitude_under_it() {
        let datum = towernav_geometry::Datum::new(towernav_geometry::Geodetic {
            lat_deg: 30.52,
            lon_deg: 114.36,
            height_m: 25.0,
        });
        // 111.3 m north is about 0.001 deg of latitude here.
        assert_eq!(
            cursor_text(&datum, [0.0, 0.0]),
            "cursor 30.520000, 114.360000"
        );
        assert_eq!(
            cursor_text(&datum, [0.0, 110.85]),
            "cursor 30.521000, 114.360000"
        );
    }

    #[test]
    fn long_tracks_are_thinned_keeping_the_newest_point() {
        let trail: std::collections::VecDeque<[f64; 2]> =
            (0..5000).map(|i| [f64::from(i), 0.0]).collect();
        let drawn = thinned(&trail);
        assert!(drawn.len() <= MAX_DRAWN_POINTS + 1, "{}", drawn.len());
        assert_eq!(drawn.first(), Some(&[0.0, 0.0]));
        assert_eq!(drawn.last(), Some(&[4999.0, 0.0]));
        let short: std::collections::VecDeque<[f64; 2]> =
            (0..10).map(|i| [f64::from(i), 1.0]).collect();
        assert_eq!(thinned(&short).len(), 10);
    }

    #[test]
    fn a_break_in_a_trail_splits_it_into_stretches_drawn_apart() {
        let mut trail: std::collections::VecDeque<[f64; 2]> =
            (0..3).map(|i| [f64::from(i), 0.0]).collect();
        trail.push_back(crate::fleet::TRAIL_BREAK);
        trail.extend((0..2).map(|i| [500.0 + f64::from(i), 0.0]));
        let parts = stretches(&trail);
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].last(), Some(&[2.0, 0.0]));
        assert_eq!(parts[1].first(), Some(&[500.0, 0.0]));
        assert!(parts.iter().flatten().all(|p| p[0].is_finite()));
    }

    #[test]
    fn the_ellipse_of_a_diagonal_covariance_has_its_sigmas_on_the_axes() {
        let pts = covariance_ellipse([10.0, 20.0], [[9.0, 0.0], [0.0, 4.0]], 2.0);
        assert!((pts[0][0] - 16.0).abs() < 1e-9 && (pts[0][1] - 20.0).abs() < 1e-9);
        assert!((pts[12][0] - 10.0).abs() < 1e-9 && (pts[12][1] - 24.0).abs() < 1e-9);
    }

    proptest! {
        /// Every point of the 1-sigma ellipse has Mahalanobis distance 1.
        #[test]
        fn ellipse_points_are_one_sigma_away(
            sx in 0.1f64..30.0, sy in 0.1f64..30.0, rho in -0.95f64..0.95,
        ) {
            let cov = [[sx * sx, rho * sx * sy], [rho * sx * sy, sy * sy]];
            let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
            for p in covariance_ellipse([0.0, 0.0], cov, 1.0) {
                let (x, y) = (p[0], p[1]);
                let m = (cov[1][1] * x * x - 2.0 * cov[0][1] * x * y + cov[0][0] * y * y) / det;
                prop_assert!((m - 1.0).abs() < 1e-6, "{}", m);
            }
        }
    }
}
