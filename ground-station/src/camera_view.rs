//! The selected UAV's camera: the latest preview with its tracks' boxes, track
//! ids and bound tower ids, coloured by how sure the binding is. Clicking a box
//! opens the correction picker; sent corrections are listed with their state.

use egui::{Color32, Rect, Sense, Stroke, pos2, vec2};
use towernav_protocol::{NodeId, Track};

use crate::corrections::{ANSWER_TIMEOUT_S, Before, CorrectionState, Corrections};
use crate::events::DecodedPreview;
use crate::fleet::{Link, UavView};
use crate::map_view::MapTower;

/// A correction the operator is preparing.
#[derive(Debug, Clone, PartialEq)]
pub struct Picking {
    pub uav: NodeId,
    pub track_id: u64,
    /// The edge run the track's number belongs to (0: the edge did not say).
    pub session: u64,
    /// The track's binding when it was clicked.
    pub current: Option<String>,
    /// Whether that binding was an operator's pin.
    pub current_pinned: bool,
    pub search: String,
    pub choice: Option<String>,
}

#[derive(Default)]
pub struct CameraState {
    /// The uploaded preview: whose, which frame.
    texture: Option<(NodeId, u64, egui::TextureHandle)>,
    pub picking: Option<Picking>,
}

/// What the operator asked for.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraAction {
    Send {
        uav: NodeId,
        track_id: u64,
        /// The edge run of the picked track; 0: unknown.
        session: u64,
        tower: Option<String>,
        previous: Before,
    },
    Undo(u64),
    /// Send an unanswered correction again.
    Resend(u64),
    /// Stop waiting for a correction's answer.
    Cancel(u64),
}

/// Binding colour: blue when pinned by an operator, green to orange as the
/// edge grows less sure, grey when unbound.
pub fn binding_color(track: &Track) -> Color32 {
    if track.pinned {
        return Color32::from_rgb(80, 160, 255);
    }
    match (track.tower_id.as_ref(), track.confidence) {
        (None, _) => Color32::GRAY,
        (Some(_), Some(c)) if c >= 0.8 => Color32::from_rgb(60, 220, 90),
        (Some(_), Some(c)) if c >= 0.4 => Color32::from_rgb(240, 220, 60),
        (Some(_), _) => Color32::from_rgb(255, 140, 40),
    }
}

pub fn track_label(track: &Track) -> String {
    format!(
        "T{} {}",
        track.track_id,
        track.tower_id.as_deref().unwrap_or("?")
    )
}

/// The UAV the camera shows, as the fleet knows it now.
pub struct Shown<'a> {
    pub uav: &'a NodeId,
    pub view: &'a UavView,
    pub link: Link,
    pub now_s: f64,
}

pub fn show(
    ui: &mut egui::Ui,
    state: &mut CameraState,
    shown: Shown<'_>,
    corrections: &Corrections,
    towers: &[MapTower],
) -> Option<CameraAction> {
    let Shown {
        uav,
        view,
        link,
        now_s,
    } = shown;
    let mut action = None;
    ui.heading(format!("Camera: {uav}"));
    match &view.preview {
        None => {
            ui.label("No preview yet.");
        }
        Some(preview) => {
            upload(ui, state, uav, preview);
            let live = link.is_live();
            let rect = frame(ui, state, preview, live);
            let scale = f64::from(rect.width()) / f64::from(preview.meta.frame_width.max(1));
            let shown = view.tracks_near(preview.meta.seq);
            let session = shown.map_or(0, |t| t.session);
            let tracks: Vec<&Track> = shown.iter().flat_map(|t| &t.tracks).collect();
            let boxes: Vec<Rect> = tracks.iter().map(|t| screen_box(t, rect, scale)).collect();
            let font = egui::FontId::proportional(12.0);
            let sizes: Vec<egui::Vec2> = tracks
                .iter()
                .map(|t| {
                    ui.painter()
                        .layout_no_wrap(track_label(t), font.clone(), Color32::WHITE)
                        .size()
                })
                .collect();
            let labels = place_labels(&boxes, &sizes);
            let picked = state
                .picking
                .as_ref()
                .filter(|p| &p.uav == uav)
                .map(|p| p.track_id);
            for ((track, r), at) in tracks.iter().zip(&boxes).zip(&labels) {
                let look = BoxLook {
                    live,
                    picked: picked == Some(track.track_id),
                    label_at: *at,
                };
                if track_box(ui, track, *r, look) {
                    state.picking = Some(Picking {
                        uav: uav.clone(),
                        track_id: track.track_id,
                        session,
                        current: track.tower_id.clone(),
                        current_pinned: track.pinned,
                        search: String::new(),
                        choice: None,
                    });
                }
            }
            if !live {
                frozen(ui, rect, link);
            }
        }
    }
    if let Some(pick) = state.picking.as_mut().filter(|p| &p.uav == uav) {
        ui.separator();
        // The chosen tower may be bound to another track, which sending unbinds.
        let holder = pick.choice.as_ref().and_then(|choice| {
            view.tracks()?
                .tracks
                .iter()
                .find(|t| t.tower_id.as_ref() == Some(choice) && t.track_id != pick.track_id)
                .map(|t| t.track_id)
        });
        let (send, cancel) = picker(ui, pick, towers, corrections, holder, link.is_live());
        let done = send.is_some() || cancel;
        if let Some(tower) = send {
            action = Some(CameraAction::Send {
                uav: pick.uav.clone(),
                track_id: pick.track_id,
                session: pick.session,
                tower,
                previous: Before {
                    tower: pick.current.clone(),
                    pinned: pick.current_pinned,
                },
            });
        }
        if done {
            state.picking = None;
        }
    }
    ui.separator();
    if let Some(asked) = history(ui, uav, corrections, now_s) {
        action = Some(asked);
    }
    action
}

/// Uploads the preview as a texture unless it is the one already shown.
fn upload(ui: &egui::Ui, state: &mut CameraState, uav: &NodeId, preview: &DecodedPreview) {
    let stale_texture = state
        .texture
        .as_ref()
        .is_none_or(|(u, seq, _)| u != uav || *seq != preview.meta.seq);
    if !stale_texture {
        return;
    }
    let image = egui::ImageData::Color(preview.image.clone());
    match state.texture.as_mut().filter(|(u, _, _)| u == uav) {
        Some((_, seq, tex)) => {
            tex.set(image, egui::TextureOptions::LINEAR);
            *seq = preview.meta.seq;
        }
        None => {
            let tex = ui.ctx().load_texture(
                format!("preview {uav}"),
                image,
                egui::TextureOptions::LINEAR,
            );
            state.texture = Some((uav.clone(), preview.meta.seq, tex));
        }
    }
}

/// Across a frame that is no longer live: what happened and how old it is.
fn frozen(ui: &mut egui::Ui, rect: Rect, link: Link) {
    let (text, color) = match link {
        Link::Lost(Some(age)) => (
            format!("LINK LOST\nnothing heard for {age:.0} s"),
            Color32::RED,
        ),
        Link::Lost(None) => ("LINK LOST".to_owned(), Color32::RED),
        Link::Stale(age) => (
            format!("STALE\nnothing heard for {age:.1} s"),
            Color32::ORANGE,
        ),
        Link::Live | Link::Waiting => return,
    };
    let painter = ui.painter();
    let band = Rect::from_center_size(rect.center(), vec2(rect.width(), 70.0));
    painter.rect_filled(band, 0.0, Color32::from_black_alpha(190));
    painter.text(
        band.center(),
        egui::Align2::CENTER_CENTER,
        &text,
        egui::FontId::proportional(26.0),
        color,
    );
    // Also for screen readers and tests: the overlay is painted, not a widget.
    ui.interact(band, ui.scope_id().with("frozen"), Sense::hover())
        .widget_info(|| {
            egui::WidgetInfo::labeled(egui::Role::Label, true, text.replace('\n', " "))
        });
}

/// Paints the preview at the panel's width, in the frame's aspect, greyed
/// when it is not live; returns where.
fn frame(ui: &mut egui::Ui, state: &CameraState, preview: &DecodedPreview, live: bool) -> Rect {
    let (fw, fh) = (
        f64::from(preview.meta.frame_width.max(1)),
        f64::from(preview.meta.frame_height.max(1)),
    );
    let width = ui.available_width().max(64.0);
    let height = width * (fh / fw) as f32;
    let (rect, _) = ui.allocate_exact_size(vec2(width, height), Sense::hover());
    if let Some((_, _, tex)) = &state.texture {
        ui.painter().image(
            tex.id(),
            rect,
            Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0)),
            if live {
                Color32::WHITE
            } else {
                Color32::from_gray(80)
            },
        );
    }
    rect
}

/// A track's box on screen, over the frame at `scale` screen px per frame px.
fn screen_box(track: &Track, frame: Rect, scale: f64) -> Rect {
    let b = &track.bbox;
    Rect::from_min_max(
        frame.min + vec2((b.left * scale) as f32, (b.top * scale) as f32),
        frame.min + vec2((b.right * scale) as f32, (b.bottom * scale) as f32),
    )
}

/// Where each box's label goes (its bottom-left corner): just above the box,
/// or, where that would print over a label already placed (towers bunched
/// near the horizon), stacked higher until it is clear.
/// The least horizontal gap between two labels on one row, pixels.
pub const LABEL_GAP_PX: f32 = 6.0;

pub fn place_labels(boxes: &[Rect], sizes: &[egui::Vec2]) -> Vec<egui::Pos2> {
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    // Lowest boxes first: the nearest towers keep their labels closest.
    order.sort_by(|&a, &b| boxes[b].top().total_cmp(&boxes[a].top()));
    let mut placed: Vec<Rect> = Vec::new();
    let mut at = vec![egui::Pos2::ZERO; boxes.len()];
    for i in order {
        let size = sizes.get(i).copied().unwrap_or(egui::Vec2::ZERO);
        let mut bottom_left = boxes[i].left_top() - vec2(0.0, 2.0);
        for _ in 0..boxes.len() {
            let label = Rect::from_min_size(bottom_left - vec2(0.0, size.y), size);
            // Labels side by side keep a gap, so "T16 C4" and "T4 A4" never
            // read as one "T16 C4T4 A4".
            let padded = label.expand2(vec2(LABEL_GAP_PX, 0.0));
            match placed.iter().find(|p| p.intersects(padded)) {
                Some(hit) => bottom_left.y = hit.top() - 1.0,
                None => break,
            }
        }
        placed.push(Rect::from_min_size(bottom_left - vec2(0.0, size.y), size));
        at[i] = bottom_left;
    }
    at
}

/// How a box is drawn.
struct BoxLook {
    /// Grey on a frame that is not live: no green "sure" box on old news.
    live: bool,
    /// The box the correction picker is open for: drawn white and thick.
    picked: bool,
    label_at: egui::Pos2,
}

/// One track's box and its label; true when the operator clicked it.
fn track_box(ui: &mut egui::Ui, track: &Track, r: Rect, look: BoxLook) -> bool {
    let BoxLook {
        live,
        picked,
        label_at,
    } = look;
    let color = if picked {
        Color32::WHITE
    } else if live {
        binding_color(track)
    } else {
        Color32::from_gray(140)
    };
    let label = track_label(track);
    let response = ui
        .interact(
            r,
            ui.scope_id().with(("track", track.track_id)),
            Sense::click(),
        )
        .on_hover_text(match track.confidence {
            Some(c) => format!("binding confidence {c:.2}; click to correct"),
            None => "unbound; click to bind".into(),
        });
    response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Button, true, &label));
    let stroke = if picked {
        4.0
    } else if response.hovered() {
        3.0
    } else {
        2.0
    };
    ui.painter().rect_stroke(
        r,
        0.0,
        Stroke::new(stroke, color),
        egui::StrokeKind::Outside,
    );
    // On a dark chip: each label reads as one, over sky or ground.
    let galley = ui
        .painter()
        .layout_no_wrap(label, egui::FontId::proportional(12.0), color);
    let chip = Rect::from_min_size(label_at - vec2(0.0, galley.size().y), galley.size());
    ui.painter().rect_filled(
        chip.expand2(vec2(2.0, 0.0)),
        2.0,
        Color32::from_black_alpha(160),
    );
    ui.painter().galley(chip.min, galley, color);
    response.clicked()
}

/// What Enter in the search box picks: the tower whose id is the text
/// (ignoring case), else the only one whose id contains it.
pub fn enter_pick(search: &str, towers: &[MapTower]) -> Option<String> {
    let needle = search.trim().to_lowercase();
    if needle.is_empty() {
        return None;
    }
    if let Some(t) = towers.iter().find(|t| t.id.to_lowercase() == needle) {
        return Some(t.id.clone());
    }
    let mut matches = towers
        .iter()
        .filter(|t| t.id.to_lowercase().contains(&needle));
    match (matches.next(), matches.next()) {
        (Some(only), None) => Some(only.id.clone()),
        _ => None,
    }
}

/// The tower chooser: search by id; returns (what to send, cancelled).
fn picker(
    ui: &mut egui::Ui,
    pick: &mut Picking,
    towers: &[MapTower],
    corrections: &Corrections,
    holder: Option<u64>,
    live: bool,
) -> (Option<Option<String>>, bool) {
    ui.label(format!(
        "Correct track {} (now {})",
        pick.track_id,
        pick.current.as_deref().unwrap_or("unbound")
    ));
    if corrections.pending_for(&pick.uav, pick.track_id).is_some() {
        ui.colored_label(Color32::YELLOW, "a correction of this track is pending");
    }
    if !live {
        ui.colored_label(
            Color32::RED,
            "this frame is old: the link is not live, so a correction waits for the \
             edge and may time out; check the track when it is back",
        );
    }
    ui.horizontal(|ui| {
        let name = ui.label("Tower id");
        let search = ui
            .add(egui::TextEdit::singleline(&mut pick.search).hint_text("search, Enter picks"))
            .labelled_by(name.id);
        if search.lost_focus()
            && ui.input(|i| i.key_pressed(egui::Key::Enter))
            && let Some(id) = enter_pick(&pick.search, towers)
        {
            pick.choice = Some(id);
        }
    });
    let needle = pick.search.to_lowercase();
    egui::ScrollArea::vertical()
        .max_height(120.0)
        .id_salt("tower picker")
        .show(ui, |ui| {
            for t in towers
                .iter()
                .filter(|t| t.id.to_lowercase().contains(&needle))
                .take(200)
            {
                let chosen = pick.choice.as_deref() == Some(t.id.as_str());
                if ui
                    .selectable_label(chosen, format!("{} ({})", t.id, t.tower_type))
                    .clicked()
                {
                    pick.choice = Some(t.id.clone());
                }
            }
        });
    if let (Some(id), Some(other)) = (&pick.choice, holder) {
        ui.colored_label(
            Color32::YELLOW,
            format!("{id} is bound to track {other}: sending unbinds it there"),
        );
    }
    let mut send = None;
    let mut cancel = false;
    ui.horizontal(|ui| {
        let label = match (&pick.choice, holder) {
            (Some(id), Some(other)) => format!("Send {id} (unbinds T{other})"),
            (Some(id), None) => format!("Send {id}"),
            (None, _) => "Send".into(),
        };
        if ui
            .add_enabled(pick.choice.is_some(), egui::Button::new(label))
            .clicked()
        {
            send = Some(pick.choice.clone());
        }
        if ui.button("Unbind").clicked() {
            send = Some(None);
        }
        cancel = ui.button("Cancel").clicked();
    });
    (send, cancel)
}

/// This UAV's corrections, newest first, with their state: undo for an
/// accepted one, resend and cancel for one still waiting or unanswered.
fn history(
    ui: &mut egui::Ui,
    uav: &NodeId,
    corrections: &Corrections,
    now_s: f64,
) -> Option<CameraAction> {
    let mut asked = None;
    ui.label("Corrections");
    let mine: Vec<_> = corrections
        .sent
        .iter()
        .rev()
        .filter(|c| &c.message.uav == uav)
        .take(20)
        .collect();
    if mine.is_empty() {
        ui.weak("none sent; click a box to correct its tower");
    }
    for c in mine {
        ui.horizontal(|ui| {
            let m = &c.message;
            ui.label(format!(
                "#{} T{} -> {}",
                c.number,
                m.track_id,
                m.tower_id.as_deref().unwrap_or("unbound")
            ))
            .on_hover_text(format!("request id {} by {}", m.request_id, m.issued_by));
            match &c.state {
                CorrectionState::Pending => {
                    ui.colored_label(
                        Color32::YELLOW,
                        format!("pending {:.0} s", (now_s - c.sent_at_s).max(0.0)),
                    );
                    if ui.small_button("Cancel").clicked() {
                        asked = Some(CameraAction::Cancel(m.request_id));
                    }
                }
                CorrectionState::NoAnswer => {
                    ui.colored_label(
                        Color32::RED,
                        format!("no answer after {ANSWER_TIMEOUT_S:.0} s"),
                    );
                    if ui.small_button("Resend").clicked() {
                        asked = Some(CameraAction::Resend(m.request_id));
                    }
                    if ui.small_button("Cancel").clicked() {
                        asked = Some(CameraAction::Cancel(m.request_id));
                    }
                }
                CorrectionState::Cancelled => {
                    ui.weak("cancelled");
                }
                CorrectionState::Accepted => {
                    ui.colored_label(Color32::LIGHT_GREEN, "accepted");
                    if !c.undone && ui.small_button("Undo").clicked() {
                        asked = Some(CameraAction::Undo(m.request_id));
                    }
                }
                CorrectionState::Rejected(reason) => {
                    ui.colored_label(Color32::RED, format!("rejected: {reason}"));
                }
                CorrectionState::RunEnded => {
                    ui.colored_label(
                        Color32::ORANGE,
                        "not applied: the edge restarted and its track numbers \
                         started again; pick the track again",
                    );
                }
            }
        });
    }
    asked
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rectangles of labels placed at `at` (bottom-left corners).
    fn label_rects(at: &[egui::Pos2], sizes: &[egui::Vec2]) -> Vec<Rect> {
        at.iter()
            .zip(sizes)
            .map(|(p, s)| Rect::from_min_size(*p - vec2(0.0, s.y), *s))
            .collect()
    }

    #[test]
    fn labels_of_bunched_boxes_are_stacked_clear_of_each_other() {
        // Three towers side by side near the horizon, boxes overlapping.
        let boxes = [
            Rect::from_min_max(pos2(100.0, 200.0), pos2(110.0, 230.0)),
            Rect::from_min_max(pos2(104.0, 201.0), pos2(114.0, 231.0)),
            Rect::from_min_max(pos2(300.0, 200.0), pos2(310.0, 230.0)),
        ];
        let sizes = [vec2(40.0, 14.0); 3];
        let at = place_labels(&boxes, &sizes);
        let rects = label_rects(&at, &sizes);
        assert!(!rects[0].intersects(rects[1]), "{rects:?}");
        // The lone box keeps its label just above it.
        assert_eq!(at[2], pos2(300.0, 198.0));
        assert!(
            at[0].y <= 199.0 && at[1].y <= 199.0,
            "above their boxes: {at:?}"
        );
    }

    #[test]
    fn labels_on_one_row_keep_a_gap() {
        // Two boxes whose labels, left-aligned over them, would touch end to end.
        let boxes = [
            Rect::from_min_max(pos2(100.0, 200.0), pos2(110.0, 230.0)),
            Rect::from_min_max(pos2(142.0, 200.0), pos2(152.0, 230.0)),
        ];
        let sizes = [vec2(40.0, 14.0); 2];
        let at = place_labels(&boxes, &sizes);
        let rects = label_rects(&at, &sizes);
        let same_row = (rects[0].top() - rects[1].top()).abs() < 1.0;
        let gap = (rects[1].left() - rects[0].right()).max(rects[0].left() - rects[1].right());
        assert!(
            !same_row || gap >= LABEL_GAP_PX,
            "labels run together: {rects:?}"
        );
    }

    #[test]
    fn enter_picks_the_exact_id_or_the_only_match() {
        let tower = |id: &str| MapTower {
            id: id.into(),
            tower_type: towernav_protocol::TowerType::A,
            en: [0.0, 0.0],
        };
        let towers = [tower("A1"), tower("A12"), tower("B4")];
        assert_eq!(enter_pick("a1", &towers).as_deref(), Some("A1"));
        assert_eq!(enter_pick("b", &towers).as_deref(), Some("B4"));
        assert_eq!(enter_pick("A", &towers), None, "two match: no guess");
        assert_eq!(enter_pick("  ", &towers), None);
    }
}
