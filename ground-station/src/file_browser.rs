//! A file dialog drawn by egui itself: it works the same on a bare X server,
//! under Xvfb and in headless tests, where no desktop portal answers.

use std::path::{Path, PathBuf};

pub struct FileBrowser {
    dir: PathBuf,
    name: String,
    entries: Vec<(String, bool)>,
    error: Option<String>,
}

impl FileBrowser {
    /// Opens at the folder of `start` (or the current folder).
    pub fn new(start: &str) -> Self {
        let start = Path::new(start.trim());
        let (dir, name) = if start.is_dir() {
            (start.to_path_buf(), String::new())
        } else {
            (
                start
                    .parent()
                    .filter(|p| p.is_dir())
                    .map(Path::to_path_buf)
                    .unwrap_or_else(|| {
                        std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."))
                    }),
                start
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
            )
        };
        let mut browser = Self {
            dir,
            name,
            entries: Vec::new(),
            error: None,
        };
        browser.refresh();
        browser
    }

    fn refresh(&mut self) {
        self.entries.clear();
        match std::fs::read_dir(&self.dir) {
            Ok(read) => {
                self.error = None;
                for entry in read.flatten() {
                    let name = entry.file_name().to_string_lossy().into_owned();
                    if name.starts_with('.') {
                        continue;
                    }
                    let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
                    self.entries.push((name, is_dir));
                }
                self.entries
                    .sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
            }
            Err(e) => self.error = Some(format!("{}: {e}", self.dir.display())),
        }
    }

    /// `Some(Some(path))` when a file was chosen, `Some(None)` when cancelled.
    pub fn show(&mut self, ctx: &egui::Context) -> Option<Option<PathBuf>> {
        let mut outcome = None;
        let mut go = None;
        egui::Window::new("Choose a file")
            .collapsible(false)
            .default_size([420.0, 360.0])
            .show(ctx, |ui| {
                ui.horizontal(|ui| {
                    if ui.button("Up").clicked() {
                        go = self.dir.parent().map(Path::to_path_buf);
                    }
                    ui.label(self.dir.display().to_string());
                });
                if let Some(e) = &self.error {
                    ui.colored_label(egui::Color32::RED, e);
                }
                egui::ScrollArea::vertical()
                    .max_height(240.0)
                    .show(ui, |ui| {
                        for (name, is_dir) in &self.entries {
                            let label = if *is_dir {
                                format!("{name}/")
                            } else {
                                name.clone()
                            };
                            if ui.selectable_label(self.name == *name, label).clicked() {
                                if *is_dir {
                                    go = Some(self.dir.join(name));
                                } else {
                                    self.name = name.clone();
                                }
                            }
                        }
                    });
                ui.horizontal(|ui| {
                    let label = ui.label("Name");
                    ui.text_edit_singleline(&mut self.name)
                        .labelled_by(label.id);
                });
                ui.horizontal(|ui| {
                    if ui
                        .add_enabled(!self.name.trim().is_empty(), egui::Button::new("Choose"))
                        .clicked()
                    {
                        outcome = Some(Some(self.dir.join(self.name.trim())));
                    }
                    if ui.button("Cancel").clicked() {
                        outcome = Some(None);
                    }
                });
            });
        if let Some(dir) = go {
            self.dir = dir;
            self.name.clear();
            self.refresh();
        }
        outcome
    }
}
