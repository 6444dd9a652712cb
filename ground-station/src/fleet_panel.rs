//! The fleet panel: which UAVs are online, their rate, latency, health and
//! dropped frames; a lost link as a red banner no one can miss, and every
//! figure of a UAV that stopped talking greyed as "last known"; picks the UAV
//! the camera view shows.

use egui::{Color32, RichText};
use towernav_protocol::{EdgeState, Health, NodeId, StatusHeartbeat};

use crate::fleet::{Fleet, Link, Nav, UavView};
use crate::map_view::uav_color;

/// How long the panel waits for a first edge before saying the link may be wrong.
pub const NOTHING_HEARD_S: f64 = 5.0;

pub fn show(
    ui: &mut egui::Ui,
    fleet: &Fleet,
    selected: &mut Option<NodeId>,
    listening_on: &str,
    now_s: f64,
) {
    ui.heading("Fleet");
    if let Some(e) = &fleet.network_error {
        banner(ui, &format!("NETWORK STOPPED: {e}"));
    }
    for uav in fleet.uavs.keys() {
        if let Link::Lost(age) = fleet.link(uav, now_s) {
            banner(ui, &format!("LINK LOST: {uav}{}", silent_for(age)));
        }
    }
    if fleet.uavs.is_empty() {
        if now_s > NOTHING_HEARD_S {
            ui.colored_label(
                Color32::YELLOW,
                format!(
                    "Nothing heard from any edge for {now_s:.0} s via {listening_on}: \
                     is the endpoint right, and is an edge running?"
                ),
            );
        } else {
            ui.label(format!("No UAV yet. Listening via {listening_on}"));
        }
    }
    for (i, (uav, view)) in fleet.uavs.iter().enumerate() {
        ui.separator();
        let link = fleet.link(uav, now_s);
        uav_header(ui, i, uav, view, link, selected);
        pose_lines(ui, view, link, fleet.nav(uav, now_s));
        if let Some(s) = &view.status {
            status_lines(ui, s, link.is_live());
        }
        if let Some(t) = view.tracks() {
            let bound = t.tracks.iter().filter(|t| t.tower_id.is_some()).count();
            let text = format!("{} tracks, {bound} bound", t.tracks.len());
            if link.is_live() {
                ui.label(text);
            } else {
                ui.weak(format!("last known: {text}"));
            }
        }
    }
    if !fleet.rejected.is_empty() {
        ui.separator();
        ui.colored_label(
            Color32::RED,
            format!("{} payloads rejected", fleet.rejected.len()),
        )
        .on_hover_text(
            fleet
                .rejected
                .iter()
                .rev()
                .take(5)
                .map(|(k, e)| format!("{k}: {e}"))
                .collect::<Vec<_>>()
                .join("\n"),
        );
    }
}

/// A full-width red bar in large type: a lost link must not look like a
/// small dot changing colour.
fn banner(ui: &mut egui::Ui, text: &str) {
    egui::Frame::new()
        .fill(Color32::from_rgb(170, 20, 20))
        .inner_margin(8.0)
        .corner_radius(4.0)
        .show(ui, |ui| {
            ui.set_min_width(ui.available_width());
            ui.label(
                RichText::new(text)
                    .color(Color32::WHITE)
                    .strong()
                    .size(18.0),
            );
        });
}

/// " (no data for 12 s)", or nothing when no pose ever came.
fn silent_for(age: Option<f64>) -> String {
    age.map(|a| format!(" (no data for {a:.0} s)"))
        .unwrap_or_default()
}

/// Presence dot, the UAV's name (click to select) and its link.
fn uav_header(
    ui: &mut egui::Ui,
    i: usize,
    uav: &NodeId,
    view: &UavView,
    link: Link,
    selected: &mut Option<NodeId>,
) {
    ui.horizontal(|ui| {
        let (dot, online) = match (link, view.alive) {
            (Link::Lost(_), _) => (
                Color32::RED,
                RichText::new("LINK LOST").color(Color32::RED).strong(),
            ),
            (Link::Stale(_), _) => (
                Color32::ORANGE,
                RichText::new("late").color(Color32::ORANGE),
            ),
            (_, Some(true)) => (Color32::LIGHT_GREEN, RichText::new("online")),
            // Messages flow but no presence token was seen (a replay records
            // none, a router may hold it back): it is heard, so say that.
            (Link::Live, _) => (Color32::LIGHT_GREEN, RichText::new("heard")),
            (_, _) => (Color32::GRAY, RichText::new("presence unknown")),
        };
        let (r, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
        ui.painter().circle_filled(r.center(), 4.0, dot);
        let name = RichText::new(uav.as_str()).strong().color(uav_color(i));
        if ui
            .selectable_label(selected.as_ref() == Some(uav), name)
            .clicked()
        {
            *selected = Some(uav.clone());
        }
        ui.label(online);
    });
}

/// The link (LINK LOST, STALE: nothing heard) or, while the UAV is heard,
/// its navigation: the fix with its pose rate, COASTING (on current
/// predictions, or on none) or NO FIX with the age of the last pose. Then the last position with its 1-sigma, heading
/// and height above the ellipsoid, and the towers used.
fn pose_lines(ui: &mut egui::Ui, view: &UavView, link: Link, nav: Nav) {
    let last_pose = |age: Option<f64>| {
        age.map_or_else(
            || "no pose yet".to_owned(),
            |a| format!("last pose {a:.0} s ago"),
        )
    };
    match (link, nav) {
        (Link::Lost(Some(age)), _) => {
            ui.colored_label(
                Color32::RED,
                format!("LINK LOST: nothing heard for {age:.1} s"),
            );
        }
        (Link::Lost(None), _) => {
            ui.colored_label(Color32::RED, "LINK LOST before anything was heard");
        }
        (Link::Stale(age), _) => {
            ui.colored_label(
                Color32::ORANGE,
                format!("STALE: nothing heard for {age:.1} s"),
            );
        }
        (_, Nav::Fix(age)) => {
            ui.label(format!(
                "FIX: {:.0} poses/s, last {age:.1} s ago",
                view.pose_rate_hz()
            ));
        }
        (_, Nav::Predicting { coast_s }) => {
            ui.colored_label(
                Color32::ORANGE,
                format!(
                    "COASTING: no tower fix for {coast_s:.1} s, {:.0} predicted poses/s",
                    view.pose_rate_hz()
                ),
            );
        }
        (_, Nav::Coasting(age)) => {
            ui.colored_label(
                Color32::ORANGE,
                format!("COASTING: no tower in sight, {}", last_pose(age)),
            );
        }
        (_, Nav::NoFix(age)) => {
            ui.colored_label(
                Color32::YELLOW,
                format!("NO FIX (link up): {}", last_pose(age)),
            );
        }
        (_, Nav::Unknown) => {
            ui.label("no pose yet");
        }
    }
    // A position is current only while the UAV is heard and has a fix or a
    // current prediction.
    let current = link.is_live() && nav.is_current();
    if let Some(p) = &view.last_pose {
        let sigma = (p.covariance[0][0] + p.covariance[1][1]).max(0.0).sqrt();
        // The pose's yaw is counter-clockwise from east; a compass heading is
        // clockwise from north.
        let heading = (90.0 - p.yaw_rad.to_degrees()).rem_euclid(360.0);
        let speed = view
            .speed_mps
            .map(|v| format!(", {v:.1} m/s"))
            .unwrap_or_default();
        let text = format!(
            "{:.6}, {:.6}  ±{sigma:.1} m (1-sigma)\nheight {:.1} m above the WGS84 ellipsoid\nheading {heading:.0} deg{speed}",
            p.lat_deg, p.lon_deg, p.alt_m
        );
        if current {
            ui.label(text);
        } else {
            ui.weak(format!("last known: {text}"));
        }
        if !p.towers_used.is_empty() && current {
            let n = p.towers_used.len();
            let towers = if n == 1 { "tower" } else { "towers" };
            ui.label(format!(
                "fix from {n} {towers}: {}",
                p.towers_used.join(" ")
            ));
        }
    }
}

/// The edge's state as an operator says it.
pub fn state_name(state: EdgeState) -> &'static str {
    match state {
        EdgeState::Initializing => "starting, no fix yet",
        EdgeState::Localized => "localized",
        EdgeState::Coasting => "coasting (no tower in sight)",
        EdgeState::NoFix => "no fix",
    }
}

/// Health, state, rate, latency and the frames lost, from the edge's status;
/// greyed as "last known" when the link is not live (a green "health ok"
/// from a UAV that stopped talking would be a lie).
fn status_lines(ui: &mut egui::Ui, s: &StatusHeartbeat, live: bool) {
    if !live {
        ui.weak(format!(
            "last known: health {:?}, {}, {:.0} frames/s",
            s.health,
            state_name(s.state),
            s.frame_rate_hz
        ));
        return;
    }
    let health = match s.health {
        Health::Ok => RichText::new("health ok").color(Color32::LIGHT_GREEN),
        Health::Degraded => RichText::new("degraded").color(Color32::YELLOW),
        Health::Failed => RichText::new("FAILED").color(Color32::RED),
    };
    ui.horizontal(|ui| {
        ui.label(health);
        ui.label(format!(
            "{}, {:.0} frames/s",
            state_name(s.state),
            s.frame_rate_hz
        ));
    });
    ui.label(format!(
        "latency p50 {:.0} ms, p99 {:.0} ms",
        s.latency_p50_ms, s.latency_p99_ms
    ));
    let dropped = format!(
        "{} dropped, {} failed frames; {}",
        s.frames_dropped, s.frames_failed, s.detector
    );
    if s.frames_dropped + s.frames_failed > 0 {
        ui.colored_label(Color32::YELLOW, dropped);
    } else {
        ui.label(dropped);
    }
}
