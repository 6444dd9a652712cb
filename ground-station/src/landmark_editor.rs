//! The landmark editor: a table that sorts and filters, a form that adds and
//! edits with validation shown beside each field (and a check on positions
//! far from every other tower), delete behind a confirmation dialog and with
//! undo, import and export by path or file browser, and the edit history with
//! who and when. It only proposes changes ([`EditorAction`]); the app writes
//! them to the database.

use std::collections::BTreeSet;

use egui::{Color32, RichText};
use towernav_geometry::Datum;
use towernav_landmark_db::{HistoryEntry, validate};
use towernav_protocol::{LandmarkChangeOp, LandmarkRecord, TowerType};

use crate::file_browser::FileBrowser;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileFormat {
    Csv,
    GeoJson,
    Osm,
}

impl FileFormat {
    pub const ALL: [FileFormat; 3] = [FileFormat::Csv, FileFormat::GeoJson, FileFormat::Osm];

    pub fn label(self) -> &'static str {
        match self {
            FileFormat::Csv => "CSV",
            FileFormat::GeoJson => "GeoJSON",
            FileFormat::Osm => "OSM XML",
        }
    }
}

/// What the operator asked the database for.
#[derive(Debug, Clone, PartialEq)]
pub enum EditorAction {
    /// Save a record, expecting the stored one as it was when the form was
    /// filled (a new id: none), so a concurrent writer's edit is not overwritten.
    Upsert(Box<LandmarkRecord>, towernav_landmark_db::Expect),
    Delete(String),
    /// Take back the last step of [`EditorState::undo`]: a delete or an import.
    Undo,
    /// Import a file; `true`: the operator saw its warnings and imports anyway.
    Import(std::path::PathBuf, FileFormat, bool),
    /// Export to a file; `true`: replace it if it exists (the operator said so).
    Export(std::path::PathBuf, FileFormat, bool),
}

/// How many deletes and imports can be taken back.
pub const UNDO_DEPTH: usize = 20;

/// A change the operator can take back as a whole.
#[derive(Debug, Clone, PartialEq)]
pub enum UndoStep {
    /// The tower a delete removed, as it was.
    Delete(LandmarkRecord),
    /// An import: every tower it wrote, as it was before (`None`: it was new).
    Import {
        file: String,
        before: Vec<(String, Option<LandmarkRecord>)>,
    },
}

impl UndoStep {
    pub fn label(&self) -> String {
        match self {
            UndoStep::Delete(record) => format!("Undo delete of {}", record.id),
            UndoStep::Import { file, before } => {
                format!("Undo import of {file} ({} towers)", before.len())
            }
        }
    }

    fn hint(&self) -> &'static str {
        match self {
            UndoStep::Delete(_) => "put the tower back as it was, live to every edge",
            UndoStep::Import { .. } => {
                "put every tower the import wrote back as it was (removing the new ones), in one transaction, live to every edge"
            }
        }
    }
}

/// An import held back until the operator confirms it: towers in it look
/// wrong (far from every other, or on top of another), as the form would ask.
#[derive(Debug, Clone, PartialEq)]
pub struct PendingImport {
    pub path: std::path::PathBuf,
    pub format: FileFormat,
    pub warnings: Vec<String>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Column {
    Id,
    Type,
    Lat,
    Lon,
    Elev,
    Height,
    Line,
    Revision,
}

/// The form's fields as typed, so a half-typed number is kept and flagged, not lost.
#[derive(Debug, Clone, PartialEq)]
pub struct Form {
    pub id: String,
    /// The design's name as the line's owner calls it (A to D in the demo).
    pub tower_type: String,
    pub lat: String,
    pub lon: String,
    pub elev: String,
    pub height: String,
    pub line_name: String,
    pub survey_source: String,
    pub notes: String,
}

impl Default for Form {
    fn default() -> Self {
        Self {
            id: String::new(),
            tower_type: TowerType::A.to_string(),
            lat: String::new(),
            lon: String::new(),
            elev: String::new(),
            height: String::new(),
            line_name: String::new(),
            survey_source: String::new(),
            notes: String::new(),
        }
    }
}

/// A field that is wrong, and why, for display beside it.
pub type FieldErrors = Vec<(&'static str, String)>;

impl Form {
    pub fn from_record(r: &LandmarkRecord) -> Self {
        Self {
            id: r.id.clone(),
            tower_type: r.tower_type.to_string(),
            lat: r.lat_deg.to_string(),
            lon: r.lon_deg.to_string(),
            elev: r.ground_elev_m.to_string(),
            height: r.height_m.to_string(),
            line_name: r.line_name.clone().unwrap_or_default(),
            survey_source: r.survey_source.clone().unwrap_or_default(),
            notes: r.notes.clone(),
        }
    }

    /// The record, or every field that is wrong (numbers that do not parse,
    /// then the database's own validation).
    pub fn record(&self, base: Option<&LandmarkRecord>) -> Result<LandmarkRecord, FieldErrors> {
        let mut errors = FieldErrors::new();
        let tower_type = match TowerType::new(&self.tower_type) {
            Ok(t) => t,
            Err(e) => {
                errors.push(("tower_type", e.to_string()));
                TowerType::A
            }
        };
        let mut number = |field: &'static str, text: &str| match text.trim().parse::<f64>() {
            Ok(v) => v,
            Err(_) => {
                let why = if text.trim().is_empty() {
                    "is required".to_owned()
                } else {
                    format!("{text:?} is not a number")
                };
                errors.push((field, why));
                f64::NAN
            }
        };
        let lat = number("lat_deg", &self.lat);
        let lon = number("lon_deg", &self.lon);
        let elev = number("ground_elev_m", &self.elev);
        let height = number("height_m", &self.height);
        if !errors.is_empty() {
            return Err(errors);
        }
        let optional = |s: &str| (!s.trim().is_empty()).then(|| s.trim().to_owned());
        let mut record = base.cloned().unwrap_or_else(|| {
            LandmarkRecord::new(self.id.trim(), tower_type, lat, lon, elev, height)
        });
        record.id = self.id.trim().to_owned();
        record.tower_type = tower_type;
        record.lat_deg = lat;
        record.lon_deg = lon;
        record.ground_elev_m = elev;
        record.height_m = height;
        record.line_name = optional(&self.line_name);
        record.survey_source = optional(&self.survey_source);
        record.notes = self.notes.trim().to_owned();
        validate(&record).map_err(|e| vec![(e.field, e.reason)])?;
        Ok(record)
    }
}

pub struct EditorState {
    pub filter: String,
    sort: (Column, bool),
    pub form: Form,
    /// The record being edited (its id as stored), `None` when adding.
    pub editing: Option<String>,
    /// Its revision when the form was filled from it.
    pub editing_revision: Option<u64>,
    /// The tower the delete dialog asks about.
    pub confirm_delete: Option<String>,
    /// Deletes and imports that can be taken back, the last one last.
    pub undo: Vec<UndoStep>,
    /// Fields typed into since the form was (re)filled: an empty one is
    /// flagged "required" only after the operator has been in it.
    pub touched: BTreeSet<&'static str>,
    /// The outcome of the last action, for the operator: (ok, text).
    pub message: Option<(bool, String)>,
    pub io_path: String,
    pub io_format: FileFormat,
    browser: Option<FileBrowser>,
    /// An import waiting for "Import anyway".
    pub pending_import: Option<PendingImport>,
    /// An export onto an existing file, waiting for "Overwrite".
    pub pending_overwrite: Option<(std::path::PathBuf, FileFormat)>,
}

impl Default for EditorState {
    fn default() -> Self {
        Self {
            filter: String::new(),
            sort: (Column::Id, true),
            form: Form::default(),
            editing: None,
            editing_revision: None,
            confirm_delete: None,
            undo: Vec::new(),
            touched: BTreeSet::new(),
            message: None,
            io_path: String::new(),
            io_format: FileFormat::Csv,
            browser: None,
            pending_import: None,
            pending_overwrite: None,
        }
    }
}

fn cmp_f64(a: f64, b: f64) -> std::cmp::Ordering {
    a.total_cmp(&b)
}

/// The rows the table shows: filtered by id, type, line or source, then sorted.
fn rows<'a>(state: &EditorState, records: &'a [LandmarkRecord]) -> Vec<&'a LandmarkRecord> {
    let needle = state.filter.to_lowercase();
    let mut rows: Vec<&LandmarkRecord> = records
        .iter()
        .filter(|r| {
            needle.is_empty()
                || r.id.to_lowercase().contains(&needle)
                || r.tower_type.as_str().eq_ignore_ascii_case(&needle)
                || r.line_name
                    .as_deref()
                    .is_some_and(|l| l.to_lowercase().contains(&needle))
                || r.survey_source
                    .as_deref()
                    .is_some_and(|l| l.to_lowercase().contains(&needle))
        })
        .collect();
    let (column, ascending) = state.sort;
    rows.sort_by(|a, b| {
        let o = match column {
            Column::Id => a.id.cmp(&b.id),
            Column::Type => a.tower_type.cmp(&b.tower_type),
            Column::Lat => cmp_f64(a.lat_deg, b.lat_deg),
            Column::Lon => cmp_f64(a.lon_deg, b.lon_deg),
            Column::Elev => cmp_f64(a.ground_elev_m, b.ground_elev_m),
            Column::Height => cmp_f64(a.height_m, b.height_m),
            Column::Line => a.line_name.cmp(&b.line_name),
            Column::Revision => a.revision.cmp(&b.revision),
        };
        if ascending { o } else { o.reverse() }
    });
    rows
}

pub fn show(
    ui: &mut egui::Ui,
    state: &mut EditorState,
    records: &[LandmarkRecord],
) -> Option<EditorAction> {
    let mut action = None;
    egui::Panel::right("landmark form")
        .default_size(330.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                action = form(ui, state, records).or(action.take());
                ui.separator();
                action = files(ui, state).or(action.take());
            });
        });
    egui::CentralPanel::default().show(ui, |ui| {
        ui.horizontal(|ui| {
            let name = ui.label("Filter");
            ui.add(
                egui::TextEdit::singleline(&mut state.filter).hint_text("id, type, line or source"),
            )
            .labelled_by(name.id);
            ui.label(format!("{} towers", records.len()));
        });
        table(ui, state, records);
    });
    action
}

fn table(ui: &mut egui::Ui, state: &mut EditorState, records: &[LandmarkRecord]) {
    let shown = rows(state, records);
    egui::ScrollArea::both()
        .id_salt("landmark table")
        .show(ui, |ui| {
            egui::Grid::new("landmarks")
                .striped(true)
                .num_columns(8)
                .show(ui, |ui| {
                    for (column, name) in [
                        (Column::Id, "Id"),
                        (Column::Type, "Type"),
                        (Column::Lat, "Lat"),
                        (Column::Lon, "Lon"),
                        (Column::Elev, "Ground (m)"),
                        (Column::Height, "Height (m)"),
                        (Column::Line, "Line"),
                        (Column::Revision, "Rev"),
                    ] {
                        let arrow = match state.sort {
                            (c, true) if c == column => " ^",
                            (c, false) if c == column => " v",
                            _ => "",
                        };
                        if ui.button(format!("{name}{arrow}")).clicked() {
                            state.sort = match state.sort {
                                (c, asc) if c == column => (c, !asc),
                                _ => (column, true),
                            };
                        }
                    }
                    ui.end_row();
                    let mut chosen = None;
                    for r in shown {
                        let editing = state.editing.as_deref() == Some(r.id.as_str());
                        if ui.selectable_label(editing, &r.id).clicked() {
                            chosen = Some(r);
                        }
                        ui.label(r.tower_type.as_str());
                        ui.label(format!("{:.6}", r.lat_deg));
                        ui.label(format!("{:.6}", r.lon_deg));
                        ui.label(format!("{:.1}", r.ground_elev_m));
                        ui.label(format!("{:.1}", r.height_m));
                        ui.label(r.line_name.as_deref().unwrap_or(""));
                        ui.label(r.revision.to_string()).on_hover_text(format!(
                            "by {} at unix {}",
                            r.updated_by, r.updated_at_unix_s
                        ));
                        ui.end_row();
                    }
                    if let Some(r) = chosen {
                        state.form = Form::from_record(r);
                        state.editing = Some(r.id.clone());
                        state.editing_revision = Some(r.revision);
                        state.confirm_delete = None;
                        state.touched.clear();
                        state.message = None;
                    }
                });
        });
}

/// One row of the form: the label, a box, and what its number means.
struct Field<'a> {
    key: &'static str,
    label: &'static str,
    unit: &'static str,
    text: &'a mut String,
}

/// The row, and its error on the row below. The box's id is its field's name,
/// not its place: an error line appearing above it must not hand the focus to
/// another box (egui's automatic ids count widgets, so the rows below would
/// take new ids and the box being typed into would lose its keystrokes).
fn field(
    ui: &mut egui::Ui,
    f: Field<'_>,
    errors: &[(&'static str, String)],
    touched: &mut BTreeSet<&'static str>,
) {
    let name = ui.label(f.label);
    let response = ui
        .add(
            egui::TextEdit::singleline(f.text)
                .id_salt(("landmark field", f.key))
                .desired_width(150.0),
        )
        .labelled_by(name.id);
    if response.changed() {
        touched.insert(f.key);
    }
    ui.label(RichText::new(f.unit).weak());
    ui.end_row();
    let error = errors.iter().find(|(k, _)| *k == f.key).map(|(_, e)| e);
    // An untouched empty box is not yet an error: the form just opened.
    if let Some(e) = error.filter(|e| touched.contains(f.key) || e.as_str() != "is required") {
        ui.label("");
        ui.colored_label(Color32::RED, e);
        ui.end_row();
    }
}

/// How far a tower may stand from every other one before the form asks
/// whether its position was typed right (a line's towers are 0.2-0.5 km apart).
pub const FAR_FROM_OTHERS_M: f64 = 20_000.0;

/// A check on a record that is valid but looks wrong: far from every other
/// tower (a dropped digit puts it hundreds of kilometres away).
pub fn position_check(record: &LandmarkRecord, records: &[LandmarkRecord]) -> Option<String> {
    let here = Datum::new(record.foot());
    let (nearest, d) = records
        .iter()
        .filter(|r| r.id != record.id)
        .map(|r| (r, here.to_enu(&r.foot()).xy().coords.norm()))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    (d > FAR_FROM_OTHERS_M).then(|| {
        format!(
            "check: {:.0} km from the nearest tower ({}); is the position right?",
            d / 1000.0,
            nearest.id
        )
    })
}

fn form(
    ui: &mut egui::Ui,
    state: &mut EditorState,
    records: &[LandmarkRecord],
) -> Option<EditorAction> {
    let base = state
        .editing
        .as_deref()
        .and_then(|id| records.iter().find(|r| r.id == id));
    ui.heading(match base {
        Some(r) => format!("Edit {} (rev {})", r.id, r.revision),
        None => "Add a tower".into(),
    });
    let result = state.form.record(base);
    let errors = result.as_ref().err().cloned().unwrap_or_default();
    let editing = state.editing.is_some();
    let before = state.form.clone();
    form_fields(
        ui,
        &mut state.form,
        &mut state.touched,
        editing,
        records,
        &errors,
    );
    if state.form != before {
        // The last outcome was about the form as it was.
        state.message = None;
    }
    // Errors on fields the form has no box for (e.g. base width) still show.
    for (f, e) in errors.iter().filter(|(f, _)| !boxed(f)) {
        ui.colored_label(Color32::RED, format!("{f} {e}"));
    }
    let check = result
        .as_ref()
        .ok()
        .and_then(|r| position_check(r, records));
    if let Some(check) = &check {
        ui.colored_label(Color32::YELLOW, check);
    }
    let action = form_buttons(ui, state, records, &result, check.is_some());
    if let Some((ok, text)) = &state.message {
        ui.colored_label(
            if *ok {
                Color32::LIGHT_GREEN
            } else {
                Color32::RED
            },
            text,
        );
    }
    if let Some(step) = state.undo.last()
        && ui.button(step.label()).on_hover_text(step.hint()).clicked()
    {
        return Some(EditorAction::Undo);
    }
    action.or_else(|| delete_dialog(ui, state, records))
}

/// Whether the form has a box for `field` (its errors show beside it): every
/// required column, and the optional text ones.
fn boxed(field: &str) -> bool {
    towernav_landmark_db::fields::REQUIRED.contains(&field)
        || ["line_name", "survey_source", "notes"].contains(&field)
}

fn form_fields(
    ui: &mut egui::Ui,
    f: &mut Form,
    touched: &mut BTreeSet<&'static str>,
    editing: bool,
    records: &[LandmarkRecord],
    errors: &[(&'static str, String)],
) {
    egui::Grid::new("landmark fields")
        .num_columns(3)
        .show(ui, |ui| {
            if editing {
                // An id is the tower's identity on the edges: renaming is delete + add.
                ui.label("Id");
                ui.label(RichText::new(&f.id).strong());
                ui.end_row();
            } else {
                let (key, label, unit, text) = ("id", "Id", "", &mut f.id);
                field(
                    ui,
                    Field {
                        key,
                        label,
                        unit,
                        text,
                    },
                    errors,
                    touched,
                );
            }
            let key = "tower_type";
            let text = &mut f.tower_type;
            field(
                ui,
                Field {
                    key,
                    label: "Type",
                    unit: "design name",
                    text,
                },
                errors,
                touched,
            );
            known_types(ui, &mut f.tower_type, records);
            let rows = [
                ("lat_deg", "Latitude (deg)", "WGS84, north +", &mut f.lat),
                ("lon_deg", "Longitude (deg)", "WGS84, east +", &mut f.lon),
                (
                    "ground_elev_m",
                    "Ground elevation (m)",
                    "above the WGS84 ellipsoid, not MSL",
                    &mut f.elev,
                ),
                ("height_m", "Height (m)", "foot to top", &mut f.height),
                ("line_name", "Line", "optional", &mut f.line_name),
                (
                    "survey_source",
                    "Survey source",
                    "optional",
                    &mut f.survey_source,
                ),
                ("notes", "Notes", "", &mut f.notes),
            ];
            for (key, label, unit, text) in rows {
                field(
                    ui,
                    Field {
                        key,
                        label,
                        unit,
                        text,
                    },
                    errors,
                    touched,
                );
            }
        });
}

/// The types already in the database, one click away from the type's box.
fn known_types(ui: &mut egui::Ui, tower_type: &mut String, records: &[LandmarkRecord]) {
    let mut known: Vec<TowerType> = records.iter().map(|r| r.tower_type).collect();
    known.sort();
    known.dedup();
    if known.is_empty() {
        return;
    }
    ui.label("");
    egui::ComboBox::new("known tower types", "known types")
        .selected_text(tower_type.as_str())
        .show_ui(ui, |ui| {
            for t in known {
                if ui
                    .selectable_label(tower_type == t.as_str(), t.as_str())
                    .clicked()
                {
                    *tower_type = t.to_string();
                }
            }
        });
    ui.end_row();
}

/// Save or Add (or "Add anyway" past a position check), New, and Delete,
/// which only opens the confirmation dialog.
fn form_buttons(
    ui: &mut egui::Ui,
    state: &mut EditorState,
    records: &[LandmarkRecord],
    result: &Result<LandmarkRecord, FieldErrors>,
    checked: bool,
) -> Option<EditorAction> {
    let mut action = None;
    ui.horizontal(|ui| {
        let renaming_over = match (&state.editing, result) {
            (None, Ok(r)) => records.iter().any(|x| x.id == r.id),
            _ => false,
        };
        let label = match (state.editing.is_some(), checked) {
            (true, false) => "Save",
            (true, true) => "Save anyway",
            (false, false) => "Add",
            (false, true) => "Add anyway",
        };
        let save = ui.add_enabled(result.is_ok() && !renaming_over, egui::Button::new(label));
        if renaming_over {
            ui.colored_label(Color32::RED, "that id is taken");
        }
        if save.clicked()
            && let Ok(r) = result
        {
            let expect = match (&state.editing, state.editing_revision) {
                (Some(id), Some(rev)) if *id == r.id => towernav_landmark_db::Expect::Revision(rev),
                _ => towernav_landmark_db::Expect::Absent,
            };
            action = Some(EditorAction::Upsert(Box::new(r.clone()), expect));
        }
        if ui.button("New").clicked() {
            state.form = Form::default();
            state.editing = None;
            state.confirm_delete = None;
            state.touched.clear();
            state.message = None;
        }
        if let Some(id) = state.editing.clone()
            && ui
                .button(RichText::new("Delete...").color(Color32::LIGHT_RED))
                .clicked()
        {
            state.confirm_delete = Some(id);
        }
    });
    action
}

/// The confirmation of a delete: a dialog in the middle of the window, away
/// from the button that opened it (a double click cannot reach it), naming
/// the tower and what deleting it does.
fn delete_dialog(
    ui: &mut egui::Ui,
    state: &mut EditorState,
    records: &[LandmarkRecord],
) -> Option<EditorAction> {
    let id = state.confirm_delete.clone()?;
    let Some(record) = records.iter().find(|r| r.id == id) else {
        state.confirm_delete = None;
        return None;
    };
    let mut action = None;
    let mut close = false;
    let modal = egui::Modal::new(egui::Id::unique("confirm delete")).show(ui.ctx(), |ui| {
        ui.heading(format!("Delete tower {id}?"));
        ui.label(format!(
            "{} ({}) at {:.6}, {:.6}, {:.1} m tall{}.",
            record.id,
            record.tower_type,
            record.lat_deg,
            record.lon_deg,
            record.height_m,
            record
                .line_name
                .as_deref()
                .map(|l| format!(" (line: {l})"))
                .unwrap_or_default()
        ));
        ui.label("The removal goes live to every edge at once. It can be undone here.");
        ui.add_space(12.0);
        ui.horizontal(|ui| {
            if ui.button("Keep it").clicked() {
                close = true;
            }
            ui.add_space(60.0);
            if ui
                .button(RichText::new(format!("Delete {id}")).color(Color32::RED))
                .clicked()
            {
                action = Some(EditorAction::Delete(id.clone()));
                close = true;
            }
        });
    });
    if close || modal.should_close() {
        state.confirm_delete = None;
    }
    action
}

fn files(ui: &mut egui::Ui, state: &mut EditorState) -> Option<EditorAction> {
    ui.heading("Import / export");
    let mut action = None;
    ui.horizontal(|ui| {
        let name = ui.label("File");
        ui.add(egui::TextEdit::singleline(&mut state.io_path).desired_width(170.0))
            .labelled_by(name.id);
        if ui.button("Browse...").clicked() {
            state.browser = Some(FileBrowser::new(&state.io_path));
        }
    });
    ui.horizontal(|ui| {
        for f in FileFormat::ALL {
            ui.radio_value(&mut state.io_format, f, f.label());
        }
    });
    ui.horizontal(|ui| {
        let path = std::path::PathBuf::from(state.io_path.trim());
        let has_path = !state.io_path.trim().is_empty();
        if ui
            .add_enabled(has_path, egui::Button::new("Import"))
            .clicked()
        {
            action = Some(EditorAction::Import(path.clone(), state.io_format, false));
        }
        if ui
            .add_enabled(has_path, egui::Button::new("Export"))
            .clicked()
        {
            action = Some(EditorAction::Export(path, state.io_format, false));
        }
    });
    if let Some((path, format)) = state.pending_overwrite.clone() {
        ui.horizontal(|ui| {
            ui.colored_label(egui::Color32::YELLOW, format!("{} exists.", path.display()));
            if ui.button("Overwrite").clicked() {
                action = Some(EditorAction::Export(path.clone(), format, true));
                state.pending_overwrite = None;
            }
            if ui.button("Keep it").clicked() {
                state.pending_overwrite = None;
            }
        });
    }
    if let Some(pending) = state.pending_import.clone() {
        ui.colored_label(
            egui::Color32::YELLOW,
            format!(
                "{} was not imported: {} tower(s) look wrong",
                pending.path.display(),
                pending.warnings.len()
            ),
        );
        for w in pending.warnings.iter().take(5) {
            ui.label(format!("  {w}"));
        }
        ui.horizontal(|ui| {
            if ui.button("Import anyway").clicked() {
                action = Some(EditorAction::Import(
                    pending.path.clone(),
                    pending.format,
                    true,
                ));
                state.pending_import = None;
            }
            if ui.button("Cancel import").clicked() {
                state.pending_import = None;
            }
        });
    }
    if let Some(browser) = state.browser.as_mut() {
        match browser.show(ui.ctx()) {
            Some(Some(path)) => {
                state.io_path = path.display().to_string();
                state.browser = None;
            }
            Some(None) => state.browser = None,
            None => {}
        }
    }
    action
}

/// The database's change log, newest first, with who made each change and when (UTC).
pub fn history(ui: &mut egui::Ui, changes: &[HistoryEntry]) {
    ui.heading(format!("Edit history ({} revisions)", changes.len()));
    egui::ScrollArea::vertical()
        .id_salt("history")
        .show(ui, |ui| {
            egui::Grid::new("history grid")
                .striped(true)
                .num_columns(4)
                .show(ui, |ui| {
                    for h in ["Revision", "Change", "By", "At (UTC)"] {
                        ui.strong(h);
                    }
                    ui.end_row();
                    for entry in changes.iter().rev().take(2000) {
                        let c = &entry.change;
                        ui.label(c.revision.to_string());
                        match &c.change {
                            LandmarkChangeOp::Upsert { record } => ui.label(format!(
                                "set {} ({}, {:.6}, {:.6}, {:.1} m)",
                                record.id,
                                record.tower_type,
                                record.lat_deg,
                                record.lon_deg,
                                record.height_m
                            )),
                            LandmarkChangeOp::Remove { id } => ui.label(format!("removed {id}")),
                        };
                        ui.label(&entry.author.by);
                        ui.label(utc(entry.author.at_unix_s));
                        ui.end_row();
                    }
                });
        });
}

/// A unix time as a person reads it; 0 (changes older than authorship) as "-".
pub fn utc(at_unix_s: i64) -> String {
    match u64::try_from(at_unix_s) {
        Ok(s) if s > 0 => {
            let at = std::time::UNIX_EPOCH + std::time::Duration::from_secs(s);
            humantime::format_rfc3339_seconds(at)
                .to_string()
                .replace('T', " ")
                .trim_end_matches('Z')
                .to_owned()
        }
        _ => "-".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn form() -> Form {
        Form {
            id: "A9".into(),
            lat: "30.52".into(),
            lon: "114.36".into(),
            elev: "25".into(),
            height: "35".into(),
            ..Form::default()
        }
    }

    #[test]
    fn a_good_form_makes_a_record_and_bad_fields_are_each_named() {
        let r = form().record(None).expect("valid");
        assert_eq!((r.id.as_str(), r.height_m), ("A9", 35.0));
        let bad = Form {
            lat: "north".into(),
            height: String::new(),
            ..form()
        };
        let errors = bad.record(None).expect_err("invalid");
        assert_eq!(
            errors,
            vec![
                ("lat_deg", "\"north\" is not a number".to_owned()),
                ("height_m", "is required".to_owned())
            ]
        );
        let portal = Form {
            tower_type: "Portal 2".into(),
            ..form()
        };
        let r = portal.record(None).expect("any design's name is a type");
        assert_eq!(r.tower_type.as_str(), "Portal 2");
        let unnamed = Form {
            tower_type: " ".into(),
            ..form()
        };
        let errors = unnamed.record(None).expect_err("a type needs a name");
        assert_eq!(errors[0].0, "tower_type", "{errors:?}");
        let tall = Form {
            height: "900".into(),
            ..form()
        };
        let errors = tall.record(None).expect_err("too tall");
        assert_eq!(errors[0].0, "height_m", "{errors:?}");
    }

    #[test]
    fn rows_filter_and_sort() {
        let mut state = EditorState::default();
        let records = vec![
            LandmarkRecord::new("B2", TowerType::B, 30.0, 114.0, 20.0, 50.0),
            LandmarkRecord::new("A1", TowerType::A, 30.1, 114.0, 20.0, 30.0),
            LandmarkRecord::new("A3", TowerType::A, 30.2, 114.0, 20.0, 40.0),
        ];
        let ids =
            |rows: Vec<&LandmarkRecord>| rows.iter().map(|r| r.id.clone()).collect::<Vec<_>>();
        assert_eq!(ids(rows(&state, &records)), ["A1", "A3", "B2"]);
        state.sort = (Column::Height, false);
        assert_eq!(ids(rows(&state, &records)), ["B2", "A3", "A1"]);
        state.filter = "a".into();
        assert_eq!(ids(rows(&state, &records)), ["A3", "A1"]);
    }
}
