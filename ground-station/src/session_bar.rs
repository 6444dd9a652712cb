//! The toolbar's recording and replay controls: a recording shows its file
//! and running time only once the network side has it open, never overwrites
//! a file, and a replay can be paused, sought and sped up.

use std::path::PathBuf;

use egui::{Color32, RichText};

use crate::recording::ReplayPlayer;

/// What the operator asked of the recorder.
#[derive(Debug, Clone, PartialEq)]
pub enum RecordAction {
    Start(PathBuf),
    Stop,
}

/// "mm:ss" for a running time.
pub fn clock(seconds: f64) -> String {
    let s = seconds.max(0.0) as u64;
    format!("{:02}:{:02}", s / 60, s % 60)
}

/// Record to a file, or the running recording with its timer and Stop.
/// `recording` is what the network side reported (path, since when).
pub fn record_controls(
    ui: &mut egui::Ui,
    recording: Option<&(PathBuf, f64)>,
    waiting: bool,
    record_path: &mut String,
    now_s: f64,
) -> Option<RecordAction> {
    if let Some((path, since)) = recording {
        ui.label(
            RichText::new(format!("REC {} {}", clock(now_s - since), path.display()))
                .color(Color32::RED)
                .strong(),
        );
        return ui.button("Stop").clicked().then_some(RecordAction::Stop);
    }
    let name = ui.label("Record to");
    ui.add(egui::TextEdit::singleline(record_path).desired_width(160.0))
        .labelled_by(name.id);
    let path = PathBuf::from(record_path.trim());
    let exists = path.exists();
    if exists {
        ui.colored_label(Color32::YELLOW, "exists: pick a new name");
    }
    if waiting {
        ui.weak("opening...");
        return None;
    }
    let record = ui
        .add_enabled(
            !exists && !record_path.trim().is_empty(),
            egui::Button::new("Record"),
        )
        .on_hover_text("record every topic, and the landmarks, to MCAP");
    record.clicked().then_some(RecordAction::Start(path))
}

/// Pause or play, a position slider, and the speed; true when the operator
/// sought backwards (what was shown must be forgotten).
pub fn replay_controls(ui: &mut egui::Ui, player: &mut ReplayPlayer, name: &str) -> bool {
    ui.colored_label(Color32::LIGHT_BLUE, format!("replaying {name}"));
    let label = if player.paused { "Play" } else { "Pause" };
    if ui.button(label).clicked() {
        player.paused = !player.paused;
    }
    let mut at = player.position_s();
    let duration = player.duration_s();
    let text = format!("{} / {}", clock(at), clock(duration));
    let slider = ui.add(
        egui::Slider::new(&mut at, 0.0..=duration.max(0.001))
            .show_value(false)
            .text(text),
    );
    let mut back = false;
    if slider.changed() {
        back = player.seek(at);
    }
    egui::ComboBox::new("replay speed", "speed")
        .selected_text(format!("{}x", player.speed))
        .show_ui(ui, |ui| {
            for speed in [0.25, 0.5, 1.0, 2.0, 4.0, 10.0] {
                ui.selectable_value(&mut player.speed, speed, format!("{speed}x"));
            }
        });
    if player.finished() {
        ui.weak("end of recording");
    }
    back
}
