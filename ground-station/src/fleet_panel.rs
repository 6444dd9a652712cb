//! The fleet panel: which UAVs are online, their rate, latency, health and
//! dropped frames, a warning when their data goes stale; picks the UAV the
//! camera view shows.

use egui::{Color32, RichText};
use towernav_protocol::{Health, NodeId, StatusHeartbeat};

use crate::fleet::{Fleet, UavView};
use crate::map_view::uav_color;

pub fn show(
    ui: &mut egui::Ui,
    fleet: &Fleet,
    selected: &mut Option<NodeId>,
    listening_on: &str,
    now_s: f64,
) {
    ui.heading("Fleet");
    if let Some(e) = &fleet.network_error {
        ui.colored_label(Color32::RED, format!("network stopped: {e}"));
    }
    if fleet.uavs.is_empty() {
        ui.label(format!("No UAV yet. Listening via {listening_on}"));
    }
    for (i, (uav, view)) in fleet.uavs.iter().enumerate() {
        ui.separator();
        uav_header(ui, i, uav, view, selected);
        pose_lines(ui, fleet, uav, view, now_s);
        if let Some(s) = &view.status {
            status_lines(ui, s);
        }
        if let Some(t) = view.tracks() {
            let bound = t.tracks.iter().filter(|t| t.tower_id.is_some()).count();
            ui.label(format!("{} tracks, {bound} bound", t.tracks.len()));
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

/// Presence dot, the UAV's name (click to select) and whether it is online.
fn uav_header(
    ui: &mut egui::Ui,
    i: usize,
    uav: &NodeId,
    view: &UavView,
    selected: &mut Option<NodeId>,
) {
    ui.horizontal(|ui| {
        let (dot, online) = match view.alive {
            Some(true) => (Color32::LIGHT_GREEN, "online"),
            Some(false) => (Color32::RED, "offline"),
            None => (Color32::GRAY, "presence unknown"),
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

/// Pose rate and age (or STALE), the last position with its 1-sigma, and the towers used.
fn pose_lines(ui: &mut egui::Ui, fleet: &Fleet, uav: &NodeId, view: &UavView, now_s: f64) {
    match fleet.pose_age_s(uav, now_s) {
        Some(age) if fleet.is_stale(uav, now_s) => {
            ui.colored_label(Color32::ORANGE, format!("STALE: no pose for {age:.1} s"));
        }
        Some(age) => {
            ui.label(format!(
                "{:.0} poses/s, last {age:.1} s ago",
                view.pose_rate_hz(now_s)
            ));
        }
        None => {
            ui.label("no pose yet");
        }
    }
    if let Some(p) = &view.last_pose {
        let sigma = (p.covariance[0][0] + p.covariance[1][1]).max(0.0).sqrt();
        ui.label(format!(
            "{:.6}, {:.6}  alt {:.1} m  ±{sigma:.1} m",
            p.lat_deg, p.lon_deg, p.alt_m
        ));
        if !p.towers_used.is_empty() {
            ui.label(format!("fix from {}", p.towers_used.join(" ")));
        }
    }
}

/// Health, state, rate, latency and the frames lost, from the edge's status.
fn status_lines(ui: &mut egui::Ui, s: &StatusHeartbeat) {
    let health = match s.health {
        Health::Ok => RichText::new("health ok").color(Color32::LIGHT_GREEN),
        Health::Degraded => RichText::new("degraded").color(Color32::YELLOW),
        Health::Failed => RichText::new("FAILED").color(Color32::RED),
    };
    ui.horizontal(|ui| {
        ui.label(health);
        ui.label(format!("{:?}, {:.0} frames/s", s.state, s.frame_rate_hz));
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
