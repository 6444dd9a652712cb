//! The operator's window: fleet list on the left, the map in the middle.

use std::sync::mpsc::Receiver;

use egui::{Color32, RichText};
use egui_plot::{Legend, Line, MarkerShape, Plot, PlotPoint, Points, Text};
use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{LandmarkRecord, TowerType};

use crate::fleet::{Fleet, NetEvent};

/// A pose older than this is drawn as stale.
const STALE_AFTER_S: f64 = 2.0;

struct MapTower {
    id: String,
    tower_type: TowerType,
    en: [f64; 2],
}

pub struct GsApp {
    fleet: Fleet,
    towers: Vec<MapTower>,
    events: Receiver<NetEvent>,
    /// What the operator is told about where the UAVs are expected.
    listening_on: String,
}

/// The map frame's origin: the towers' centroid, on the lowest foot.
pub fn map_datum(landmarks: &[LandmarkRecord]) -> Option<Datum> {
    if landmarks.is_empty() {
        return None;
    }
    let n = landmarks.len() as f64;
    Some(Datum::new(Geodetic {
        lat_deg: landmarks.iter().map(|l| l.lat_deg).sum::<f64>() / n,
        lon_deg: landmarks.iter().map(|l| l.lon_deg).sum::<f64>() / n,
        height_m: landmarks
            .iter()
            .map(|l| l.ground_elev_m)
            .fold(f64::INFINITY, f64::min),
    }))
}

impl GsApp {
    pub fn new(
        landmarks: &[LandmarkRecord],
        datum: Datum,
        events: Receiver<NetEvent>,
        listening_on: String,
    ) -> Self {
        let towers = landmarks
            .iter()
            .map(|l| {
                let p = datum.to_enu(&Geodetic {
                    lat_deg: l.lat_deg,
                    lon_deg: l.lon_deg,
                    height_m: l.ground_elev_m,
                });
                MapTower {
                    id: l.id.clone(),
                    tower_type: l.tower_type,
                    en: [p.x, p.y],
                }
            })
            .collect();
        Self {
            fleet: Fleet::new(datum),
            towers,
            events,
            listening_on,
        }
    }

    pub fn fleet(&self) -> &Fleet {
        &self.fleet
    }

    /// Draws one frame; `now_s` is the ground station's monotonic clock.
    pub fn show(&mut self, ui: &mut egui::Ui, now_s: f64) {
        while let Ok(event) = self.events.try_recv() {
            self.fleet.apply(event, now_s);
        }
        egui::Panel::left("fleet")
            .default_size(260.0)
            .show(ui, |ui| self.fleet_panel(ui, now_s));
        egui::CentralPanel::default().show(ui, |ui| self.map(ui, now_s));
    }

    fn fleet_panel(&self, ui: &mut egui::Ui, now_s: f64) {
        ui.heading("Fleet");
        if let Some(e) = &self.fleet.network_error {
            ui.colored_label(Color32::RED, format!("network stopped: {e}"));
        }
        if self.fleet.uavs.is_empty() {
            ui.label(format!("No UAV yet. Listening via {}", self.listening_on));
        }
        for (uav, view) in &self.fleet.uavs {
            ui.separator();
            ui.label(RichText::new(uav.as_str()).strong());
            match self.fleet.pose_age_s(uav, now_s) {
                Some(age) => {
                    let text = format!("last pose {age:.1} s ago");
                    if age > STALE_AFTER_S {
                        ui.colored_label(Color32::ORANGE, text);
                    } else {
                        ui.label(text);
                    }
                }
                None => {
                    ui.label("no pose yet");
                }
            }
            if let Some(p) = &view.last_pose {
                ui.label(format!(
                    "{:.6}, {:.6}  alt {:.1} m",
                    p.lat_deg, p.lon_deg, p.alt_m
                ));
                let sigma = (p.covariance[0][0] + p.covariance[1][1]).max(0.0).sqrt();
                ui.label(format!("±{sigma:.1} m from {}", p.towers_used.join(" ")));
            }
            if let Some(s) = &view.status {
                ui.label(format!("{:?}, {:.0} frames/s", s.state, s.frame_rate_hz));
            }
            if let Some(t) = &view.tracks {
                ui.label(format!("{} tracks", t.tracks.len()));
            }
        }
        ui.separator();
        ui.label(format!("Towers: {}", self.towers.len()));
        if !self.fleet.rejected.is_empty() {
            ui.colored_label(
                Color32::RED,
                format!("{} payloads rejected", self.fleet.rejected.len()),
            )
            .on_hover_text(
                self.fleet
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

    fn map(&self, ui: &mut egui::Ui, now_s: f64) {
        Plot::new("map")
            .data_aspect(1.0)
            .legend(Legend::default())
            .x_axis_label("east (m)")
            .y_axis_label("north (m)")
            .show(ui, |plot| {
                for t in TowerType::ALL {
                    let pts: Vec<[f64; 2]> = self
                        .towers
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
                for m in &self.towers {
                    plot.text(Text::new(
                        "tower ids",
                        PlotPoint::new(m.en[0], m.en[1] + 12.0),
                        m.id.as_str(),
                    ));
                }
                for (uav, view) in &self.fleet.uavs {
                    let trail: Vec<[f64; 2]> = view.trail.iter().copied().collect();
                    if let Some(&last) = trail.last() {
                        let stale = self
                            .fleet
                            .pose_age_s(uav, now_s)
                            .is_some_and(|a| a > STALE_AFTER_S);
                        plot.line(Line::new(uav.as_str(), trail));
                        plot.points(
                            Points::new(uav.as_str(), vec![last])
                                .shape(MarkerShape::Diamond)
                                .radius(7.0)
                                .color(if stale {
                                    Color32::GRAY
                                } else {
                                    Color32::LIGHT_GREEN
                                }),
                        );
                    }
                }
            });
    }
}

fn tower_marker(t: TowerType) -> MarkerShape {
    match t {
        TowerType::A => MarkerShape::Up,
        TowerType::B => MarkerShape::Square,
        TowerType::C => MarkerShape::Circle,
        TowerType::D => MarkerShape::Cross,
    }
}

#[cfg(test)]
mod tests {
    use crate::fleet::NetEvent;
    use crate::test_support::{app, pose};
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;
    use towernav_protocol::{EdgeState, Keys, NodeId, StatusHeartbeat, Topic};

    use super::GsApp;

    #[test]
    fn shows_each_uav_with_the_age_of_its_last_pose() {
        let (tx, app) = app();
        tx.send(NetEvent::Pose(pose("uav1", 30.5205, 114.3601, 30)))
            .expect("send");
        tx.send(NetEvent::Status(StatusHeartbeat {
            uav: NodeId::new("uav1").expect("valid"),
            time_s: 1.0,
            state: EdgeState::Localized,
            frames_processed: 30,
            frame_rate_hz: 30.0,
            landmarks_loaded: 2,
            datum_lat_deg: 30.52,
            datum_lon_deg: 114.36,
            datum_alt_m: 25.0,
            health: towernav_protocol::Health::Ok,
            frames_dropped: 0,
            frames_failed: 0,
            latency_p50_ms: 3.0,
            latency_p99_ms: 9.0,
            detector: "oracle".into(),
        }))
        .expect("send");
        let now = std::cell::Cell::new(0.0);
        let mut harness = Harness::new_ui_state(|ui, app: &mut GsApp| app.show(ui, now.get()), app);
        harness.run();
        // Once in the fleet list, once in the map's legend.
        assert_eq!(harness.get_all_by_label("uav1").count(), 2);
        harness.get_by_label("last pose 0.0 s ago");
        harness.get_by_label("±3.0 m from A1 B1");
        harness.get_by_label("Localized, 30 frames/s");
        harness.get_by_label("Towers: 2");
        assert_eq!(harness.state().fleet().uavs.len(), 1);

        // Time passes with no new pose: the age grows.
        now.set(4.0);
        harness.run();
        harness.get_by_label("last pose 4.0 s ago");
    }

    #[test]
    fn an_empty_fleet_says_where_it_listens_and_shows_rejections() {
        let (tx, app) = app();
        let key = Keys::new(NodeId::new("demo").expect("valid"))
            .uav(&NodeId::new("u").expect("valid"), Topic::Pose);
        tx.send(NetEvent::Rejected {
            key,
            error: "schema 2".into(),
        })
        .expect("send");
        let mut harness = Harness::new_ui_state(|ui, app: &mut GsApp| app.show(ui, 0.0), app);
        harness.run();
        harness.get_by_label("No UAV yet. Listening via tcp/127.0.0.1:7447");
        harness.get_by_label("1 payloads rejected");
    }
}
