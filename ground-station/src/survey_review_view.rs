//! The survey review tab: a `map-towers` GeoJSON opened, each proposal's
//! verdict beside its ellipse on a map of the current towers, and the
//! operator's accept, reject or edit.

use egui::Color32;
use egui_plot::{Legend, Line, MarkerShape, Plot, PlotPoint, Points, Text};
use towernav_geometry::{Datum, Geodetic};

use crate::map_view::{MapTower, covariance_ellipse};
use crate::survey_review::{Decision, ProposalStatus, SurveyReview};

#[derive(Debug, Default)]
pub struct SurveyView {
    pub path: String,
    pub review: Option<SurveyReview>,
    pub message: Option<(bool, String)>,
}

/// What the operator asked of the app.
#[derive(Debug, Clone, PartialEq)]
pub enum SurveyAction {
    Open(std::path::PathBuf),
    /// Take proposal `i` into the landmark form.
    Edit(usize),
    /// Write the accepted proposals to the database, as one import.
    Apply,
}

/// Ellipses are drawn at this many sigmas (about 86 % of the truth inside).
const ELLIPSE_SIGMAS: f64 = 2.0;

pub fn show(
    ui: &mut egui::Ui,
    view: &mut SurveyView,
    towers: &[MapTower],
    datum: &Datum,
) -> Option<SurveyAction> {
    let mut action = None;
    ui.horizontal(|ui| {
        let label = ui
            .label("Survey file")
            .on_hover_text("towers-mapped.geojson, as towernav-edge map-towers writes it");
        ui.add(egui::TextEdit::singleline(&mut view.path).desired_width(420.0))
            .labelled_by(label.id);
        if ui.button("Open survey").clicked() && !view.path.trim().is_empty() {
            action = Some(SurveyAction::Open(view.path.trim().into()));
        }
    });
    if let Some((ok, text)) = &view.message {
        let color = if *ok {
            Color32::LIGHT_GREEN
        } else {
            Color32::YELLOW
        };
        ui.colored_label(color, text);
    }
    let Some(review) = view.review.as_mut() else {
        ui.label("No survey open.");
        return action;
    };
    egui::Panel::left("survey proposals")
        .default_size(560.0)
        .show(ui, |ui| {
            ui.heading(format!(
                "{} proposals from {}",
                review.proposals.len(),
                review.file
            ));
            // Above the list, so a long survey does not push it out of sight.
            let n = review.count(Decision::Accept);
            let write = ui.add_enabled(
                n > 0,
                egui::Button::new(format!("Write {n} accepted towers")),
            );
            if write
                .on_hover_text(
                    "one import, under your name, live to every edge; Undo takes it back",
                )
                .clicked()
            {
                action = Some(SurveyAction::Apply);
            }
            ui.separator();
            egui::ScrollArea::vertical().show(ui, |ui| {
                for (i, p) in review.proposals.iter_mut().enumerate() {
                    ui.horizontal(|ui| {
                        ui.strong(&p.record.id);
                        ui.label(p.summary());
                    });
                    ui.horizontal(|ui| {
                        ui.label(format!(
                            "height {:.1} m, ±{:.1} m (1 sigma), {} views",
                            p.record.height_m, p.sigma_major_m, p.views
                        ));
                        ui.selectable_value(
                            &mut p.decision,
                            Decision::Accept,
                            format!("Accept {}", p.record.id),
                        );
                        ui.selectable_value(
                            &mut p.decision,
                            Decision::Reject,
                            format!("Reject {}", p.record.id),
                        );
                        if ui.button(format!("Edit {}", p.record.id)).clicked() {
                            action = Some(SurveyAction::Edit(i));
                        }
                        if p.decision == Decision::Edited {
                            ui.label("in the form");
                        }
                    });
                    ui.separator();
                }
                for (id, status, note) in &review.others {
                    ui.label(format!("{id}: {status} {note}"));
                }
            });
        });
    egui::CentralPanel::default().show(ui, |ui| {
        Plot::new("survey map")
            .data_aspect(1.0)
            .legend(Legend::default())
            .x_axis_label("east (m)")
            .y_axis_label("north (m)")
            .show(ui, |plot| {
                let now: Vec<[f64; 2]> = towers.iter().map(|t| t.en).collect();
                plot.points(
                    Points::new("towers in the database", now)
                        .shape(MarkerShape::Circle)
                        .color(Color32::GRAY)
                        .radius(4.0),
                );
                for p in &review.proposals {
                    let at = datum.to_enu(&Geodetic {
                        lat_deg: p.record.lat_deg,
                        lon_deg: p.record.lon_deg,
                        height_m: p.record.ground_elev_m,
                    });
                    let en = [at.x, at.y];
                    let color = match (p.decision, &p.status) {
                        (Decision::Reject, _) => Color32::DARK_GRAY,
                        (Decision::Accept, _) => Color32::LIGHT_GREEN,
                        (_, ProposalStatus::New) => Color32::from_rgb(255, 170, 0),
                        _ => Color32::LIGHT_BLUE,
                    };
                    plot.line(
                        Line::new(
                            "2-sigma ellipses",
                            covariance_ellipse(en, p.covariance_en(), ELLIPSE_SIGMAS),
                        )
                        .color(color),
                    );
                    plot.points(
                        Points::new("proposals", vec![en])
                            .shape(MarkerShape::Diamond)
                            .color(color)
                            .radius(5.0),
                    );
                    plot.text(Text::new(
                        "proposal ids",
                        PlotPoint::new(en[0], en[1] - 12.0),
                        p.record.id.as_str(),
                    ));
                }
            });
    });
    action
}
