//! The Labels tab: a labelled dataset reviewed frame by frame. The frame
//! fills the middle with its boxes (amber not yet judged, green accepted,
//! red rejected, white the one picked); the list beside it accepts or
//! rejects each. Dragging a box's edge or corner resizes it, dragging inside
//! moves it, dragging on open image draws a new box of the chosen class.
//! Leaving a frame writes its label file.
//!
//! Keys, while no text box has the focus: A accepts the picked box, R or
//! Delete rejects it, Enter accepts the rest and goes to the next frame not
//! yet reviewed, the arrow keys step.

use std::path::{Path, PathBuf};

use egui::{Color32, Pos2, Rect, Sense, Stroke, StrokeKind, pos2, vec2};
use towernav_geometry::PixelBox;

use crate::label_review::{Handle, LabelReview, ReviewError, Verdict, dragged, hit, spanned};

/// Frames wider than this are shrunk for the screen; boxes stay in the image's pixels.
const TEXTURE_MAX_WIDTH: u32 = 1600;
/// How close, in screen pixels, the pointer must come to an edge to take it.
const GRAB_PX: f32 = 6.0;

enum Drag {
    Edit {
        index: usize,
        handle: Handle,
        from: PixelBox,
        start: [f64; 2],
    },
    Draw {
        start: [f64; 2],
        now: [f64; 2],
    },
}

#[derive(Default)]
pub struct ReviewView {
    pub review: Option<LabelReview>,
    pub folder: String,
    /// The box picked in the list or on the frame.
    pub picked: Option<usize>,
    /// The class a drawn box gets.
    pub class: usize,
    pub message: Option<String>,
    texture: Option<(PathBuf, egui::TextureHandle)>,
    drag: Option<Drag>,
}

impl ReviewView {
    /// Opens the dataset at `dir`, after writing what was changed in the one
    /// open; a folder that is not one is said, not fatal.
    pub fn open(&mut self, dir: &Path) {
        self.save();
        self.folder = dir.display().to_string();
        match LabelReview::open(dir) {
            Ok(review) => {
                self.message = Some(format!(
                    "{}: {} frames, {} reviewed before",
                    dir.display(),
                    review.frames.len(),
                    review.reviewed()
                ));
                self.review = Some(review);
                self.picked = None;
                self.class = 0;
                self.texture = None;
            }
            Err(e) => self.message = Some(format!("not opened: {e}")),
        }
    }

    /// Writes the frame on show if it was changed: before another folder
    /// opens, and when the window closes.
    pub fn save(&mut self) {
        if let Some(review) = self.review.as_mut() {
            let r = review.save().map(|_| ());
            self.result(r);
        }
    }

    fn result(&mut self, r: Result<(), ReviewError>) {
        if let Err(e) = r {
            self.message = Some(format!("not saved: {e}"));
        }
    }
}

pub fn show(ui: &mut egui::Ui, view: &mut ReviewView) {
    egui::Panel::top("labels_bar").show(ui, |ui| {
        ui.horizontal(|ui| {
            let label = ui.label("Dataset folder");
            ui.add(egui::TextEdit::singleline(&mut view.folder).desired_width(420.0))
                .labelled_by(label.id);
            if ui.button("Open").clicked() {
                let dir = PathBuf::from(view.folder.trim());
                view.open(&dir);
            }
            if let Some(m) = &view.message {
                ui.separator();
                ui.label(m.as_str());
            }
        });
    });
    if view.review.is_none() {
        egui::CentralPanel::default().show(ui, |ui| {
            ui.label(
                "Open a labelled dataset: the folder `towernav-edge label --out` wrote \
                 (data.yaml, images/, labels/), or any images/ with labels/.",
            );
        });
        return;
    }
    keys(ui, view);
    egui::Panel::top("labels_steps").show(ui, |ui| steps(ui, view));
    egui::Panel::right("labels_list")
        .default_size(300.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| box_list(ui, view));
        });
    egui::CentralPanel::default().show(ui, |ui| frame(ui, view));
}

fn keys(ui: &egui::Ui, view: &mut ReviewView) {
    if ui.memory(|m| m.focused().is_some()) {
        return;
    }
    let pressed = |k| ui.input(|i| i.key_pressed(k));
    let Some(review) = view.review.as_mut() else {
        return;
    };
    if let Some(i) = view.picked {
        if pressed(egui::Key::A) {
            review.judge(i, Verdict::Accepted);
        }
        if pressed(egui::Key::R) || pressed(egui::Key::Delete) {
            review.judge(i, Verdict::Rejected);
        }
    }
    let step = if pressed(egui::Key::Enter) {
        review.accept_rest();
        Some(review.next_open())
    } else if pressed(egui::Key::ArrowRight) {
        Some(review.go(1))
    } else if pressed(egui::Key::ArrowLeft) {
        Some(review.go(-1))
    } else {
        None
    };
    if let Some(r) = step {
        view.picked = None;
        view.result(r);
    }
}

fn steps(ui: &mut egui::Ui, view: &mut ReviewView) {
    let Some(review) = view.review.as_mut() else {
        return;
    };
    let mut step: Option<Result<(), ReviewError>> = None;
    ui.horizontal(|ui| {
        let n = review.frames.len();
        let name = review.frame().map(|f| f.name()).unwrap_or_default();
        let state = match review.frame() {
            Some(f) if f.dirty => "changed, written on leaving",
            Some(f) if f.reviewed => "reviewed",
            _ => "not reviewed",
        };
        ui.label(format!(
            "Frame {} of {n}: {name} ({state}); {} of {n} reviewed",
            review.current + 1,
            review.reviewed()
        ));
        ui.separator();
        if ui.button("Previous").clicked() {
            step = Some(review.go(-1));
        }
        if ui.button("Next").clicked() {
            step = Some(review.go(1));
        }
        if ui.button("Accept the rest, next").clicked() {
            review.accept_rest();
            step = Some(review.next_open());
        }
        if ui.button("Save").clicked() {
            step = Some(review.save().map(|_| ()));
        }
        ui.separator();
        let names = review.names.clone();
        egui::ComboBox::new("labels_class", "class of drawn boxes")
            .selected_text(names.get(view.class).cloned().unwrap_or_default())
            .show_ui(ui, |ui| {
                for (i, name) in names.iter().enumerate() {
                    ui.selectable_value(&mut view.class, i, name);
                }
            });
    });
    if let Some(r) = step {
        view.picked = None;
        view.result(r);
    }
}

fn class_name(names: &[String], class: usize) -> String {
    names
        .get(class)
        .cloned()
        .unwrap_or_else(|| format!("class {class}"))
}

fn box_list(ui: &mut egui::Ui, view: &mut ReviewView) {
    let Some(review) = view.review.as_mut() else {
        return;
    };
    let Some(f) = review.frame() else {
        ui.label("No frames.");
        return;
    };
    if f.size.is_none() {
        return;
    }
    ui.label(format!("{} boxes", f.boxes.len()));
    ui.small(
        "Keys: A accept, R reject the picked box; Enter accepts the rest and goes on; \
         arrows step. Drag an edge or corner to resize, inside to move, on open image to draw.",
    );
    let rows: Vec<(String, Verdict)> = f
        .boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let verdict = match b.verdict {
                Verdict::Open => "not judged",
                Verdict::Accepted => "accepted",
                Verdict::Rejected => "rejected",
            };
            (
                format!(
                    "Box {}: {} {:.0}x{:.0} px, {verdict}{}",
                    i + 1,
                    class_name(&review.names, b.class),
                    b.bbox.width(),
                    b.bbox.height(),
                    if b.edited { ", edited" } else { "" }
                ),
                b.verdict,
            )
        })
        .collect();
    let mut judged = None;
    for (i, (text, verdict)) in rows.iter().enumerate() {
        ui.separator();
        if ui
            .selectable_label(view.picked == Some(i), text.as_str())
            .clicked()
        {
            view.picked = Some(i);
        }
        ui.horizontal(|ui| {
            let accept = ui.add_enabled(
                *verdict != Verdict::Accepted,
                egui::Button::new(format!("Accept box {}", i + 1)),
            );
            if accept.clicked() {
                judged = Some((i, Verdict::Accepted));
            }
            let reject = ui.add_enabled(
                *verdict != Verdict::Rejected,
                egui::Button::new(format!("Reject box {}", i + 1)),
            );
            if reject.clicked() {
                judged = Some((i, Verdict::Rejected));
            }
        });
    }
    if let Some((i, v)) = judged {
        review.judge(i, v);
        view.picked = Some(i);
    }
}

/// Reads the current frame's image, learns its size and uploads it, once per frame.
fn upload(ui: &egui::Ui, view: &mut ReviewView) {
    let Some(review) = view.review.as_mut() else {
        return;
    };
    let Some(f) = review.frame_mut() else {
        return;
    };
    if view.texture.as_ref().is_some_and(|(p, _)| *p == f.image) {
        return;
    }
    let image = match image::open(&f.image) {
        Ok(image) => image,
        Err(e) => {
            view.message = Some(format!("{}: {e}", f.image.display()));
            view.texture = None;
            return;
        }
    };
    f.set_size(f64::from(image.width()), f64::from(image.height()));
    let image = if image.width() > TEXTURE_MAX_WIDTH {
        image.resize(
            TEXTURE_MAX_WIDTH,
            u32::MAX,
            image::imageops::FilterType::Triangle,
        )
    } else {
        image
    };
    let rgba = image.to_rgba8();
    let color = egui::ColorImage::from_rgba_unmultiplied(
        [rgba.width() as usize, rgba.height() as usize],
        rgba.as_raw(),
    );
    let tex = ui.ctx().load_texture(
        format!("label review {}", f.image.display()),
        color,
        egui::TextureOptions::LINEAR,
    );
    view.texture = Some((f.image.clone(), tex));
}

fn frame(ui: &mut egui::Ui, view: &mut ReviewView) {
    upload(ui, view);
    let (Some(review), Some((_, tex))) = (view.review.as_mut(), view.texture.as_ref()) else {
        return;
    };
    let Some([w, h]) = review.frame().and_then(|f| f.size) else {
        return;
    };
    let avail = ui.available_size();
    let scale = (f64::from(avail.x) / w)
        .min(f64::from(avail.y) / h)
        .max(0.05);
    let (rect, response) = ui.allocate_exact_size(
        vec2((w * scale) as f32, (h * scale) as f32),
        Sense::click_and_drag(),
    );
    response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "Frame"));
    let to_px = |p: Pos2| {
        [
            f64::from(p.x - rect.min.x) / scale,
            f64::from(p.y - rect.min.y) / scale,
        ]
    };
    let to_screen = |b: &PixelBox| {
        Rect::from_min_max(
            rect.min + vec2((b.left * scale) as f32, (b.top * scale) as f32),
            rect.min + vec2((b.right * scale) as f32, (b.bottom * scale) as f32),
        )
    };
    let tol = f64::from(GRAB_PX) / scale;
    // A drag is known once the pointer has moved a little: it starts where it was pressed.
    if response.drag_started()
        && let Some(p) = ui.input(|i| i.pointer.press_origin())
    {
        let at = to_px(p);
        let boxes = review.frame().map(|f| f.boxes.as_slice()).unwrap_or(&[]);
        view.drag = Some(match hit(boxes, at, tol) {
            Some((index, handle)) => {
                view.picked = Some(index);
                Drag::Edit {
                    index,
                    handle,
                    from: boxes[index].bbox,
                    start: at,
                }
            }
            None => Drag::Draw { start: at, now: at },
        });
    }
    if response.dragged()
        && let Some(p) = response.interact_pointer_pos()
    {
        let at = to_px(p);
        match &mut view.drag {
            Some(Drag::Edit {
                index,
                handle,
                from,
                start,
            }) => {
                let moved = dragged(from, *handle, [at[0] - start[0], at[1] - start[1]], [w, h]);
                review.reshape(*index, moved);
            }
            Some(Drag::Draw { now, .. }) => *now = at,
            None => {}
        }
    }
    if response.drag_stopped()
        && let Some(Drag::Draw { start, now }) = view.drag.take()
        && let Some(i) = review.draw(view.class, spanned(start, now, [w, h]))
    {
        view.picked = Some(i);
    }
    if response.clicked()
        && let Some(p) = response.interact_pointer_pos()
    {
        let boxes = review.frame().map(|f| f.boxes.as_slice()).unwrap_or(&[]);
        view.picked = hit(boxes, to_px(p), tol).map(|(i, _)| i);
    }
    let painter = ui.painter_at(rect);
    painter.image(
        tex.id(),
        rect,
        Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0)),
        Color32::WHITE,
    );
    let Some(f) = review.frame() else {
        return;
    };
    for (i, b) in f.boxes.iter().enumerate() {
        let color = match (view.picked == Some(i), b.verdict) {
            (true, _) => Color32::WHITE,
            (_, Verdict::Open) => Color32::from_rgb(255, 176, 0),
            (_, Verdict::Accepted) => Color32::from_rgb(40, 220, 80),
            (_, Verdict::Rejected) => Color32::from_rgb(230, 40, 40),
        };
        let r = to_screen(&b.bbox);
        let width = if view.picked == Some(i) { 2.5 } else { 1.5 };
        painter.rect_stroke(r, 0.0, Stroke::new(width, color), StrokeKind::Outside);
        if b.verdict == Verdict::Rejected {
            painter.line_segment([r.left_top(), r.right_bottom()], Stroke::new(1.0, color));
        }
        painter.text(
            r.left_top() - vec2(0.0, 2.0),
            egui::Align2::LEFT_BOTTOM,
            format!("{} {}", i + 1, class_name(&review.names, b.class)),
            egui::FontId::proportional(13.0),
            color,
        );
    }
    if let Some(Drag::Draw { start, now }) = &view.drag {
        let r = to_screen(&spanned(*start, *now, [w, h]));
        painter.rect_stroke(
            r,
            0.0,
            Stroke::new(1.5, Color32::LIGHT_BLUE),
            StrokeKind::Outside,
        );
    }
    if !response.dragged() {
        view.drag = None;
    }
}
