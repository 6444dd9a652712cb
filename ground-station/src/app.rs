//! The operator's window: the fleet on the left; the map with the selected
//! UAV's camera, the landmark editor, the edit history, or a labelled
//! dataset under review in the middle.
//!
//! The app owns the landmark database: its edits are transactions on the
//! same file the landmark service tails, so they go live to the edges.

use std::path::PathBuf;

use towernav_geometry::{Datum, Geodetic};
use towernav_landmark_db::{
    Author, CheckKind, DbError, Expect, Format, HistoryEntry, ImportOptions, LandmarkDb,
    OsmMapping, export_csv, export_geojson, export_osm_xml, import_parsed, likely_mistakes,
    parse_file,
};
use towernav_protocol::{LandmarkRecord, NodeId};

use crate::camera_view::{self, CameraAction, CameraState};
use crate::corrections::Corrections;
use crate::events::NetEvent;
use crate::fleet::Fleet;
use crate::fleet_panel;
use crate::label_review_view::{self, ReviewView};
use crate::landmark_editor::{
    self, EditorAction, EditorState, FileFormat, PendingImport, UNDO_DEPTH, UndoStep,
};
use crate::map_view::{self, MapState, MapTower};
use crate::net::{NetCommand, NetLink};
use crate::recording::ReplayPlayer;
use crate::session_bar::{self, RecordAction};
use crate::survey_review::{Decision, SurveyReview};
use crate::survey_review_view::{self, SurveyAction, SurveyView};
use crate::tiles::TileLayer;

/// How far from the towers' median a tower may stand and still pull the
/// map's origin and first view: a typo'd latitude thousands of km off does not.
pub const MAP_CORE_RADIUS_M: f64 = 20_000.0;

/// The map frame's origin: the towers' median position (one tower far off
/// does not move it), on the lowest foot among the towers near it.
pub fn map_datum(landmarks: &[LandmarkRecord]) -> Option<Datum> {
    if landmarks.is_empty() {
        return None;
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let centre = Geodetic {
        lat_deg: median(landmarks.iter().map(|l| l.lat_deg).collect()),
        lon_deg: median(landmarks.iter().map(|l| l.lon_deg).collect()),
        height_m: 0.0,
    };
    let near = Datum::new(centre);
    let core: Vec<&LandmarkRecord> = landmarks
        .iter()
        .filter(|l| {
            let en = near.to_enu(&Geodetic {
                lat_deg: l.lat_deg,
                lon_deg: l.lon_deg,
                height_m: 0.0,
            });
            en.x.hypot(en.y) <= MAP_CORE_RADIUS_M
        })
        .collect();
    let lowest = core
        .iter()
        .map(|l| l.ground_elev_m)
        .fold(f64::INFINITY, f64::min);
    Some(Datum::new(Geodetic {
        height_m: if lowest.is_finite() { lowest } else { 0.0 },
        ..centre
    }))
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tab {
    Map,
    Landmarks,
    History,
    Labels,
    /// Towers a survey flight measured, under review.
    Survey,
}

/// How the app was started.
pub struct GsOptions {
    /// What the operator is told about where the UAVs are expected.
    pub listening_on: String,
    /// Name stamped on database changes and corrections.
    pub operator: String,
    /// First correction request id (seed from the clock).
    pub first_request_id: u64,
    /// A local slippy-map tile folder for the map background.
    pub tiles: Option<PathBuf>,
    /// Set when the app shows a recording instead of live traffic.
    pub replaying: Option<PathBuf>,
    /// A labelled dataset to open in the Labels tab.
    pub labels: Option<PathBuf>,
}

impl Default for GsOptions {
    fn default() -> Self {
        Self {
            listening_on: "tcp/127.0.0.1:7447".into(),
            operator: "ground-station".into(),
            first_request_id: 1,
            tiles: None,
            replaying: None,
            labels: None,
        }
    }
}

pub struct GsApp {
    fleet: Fleet,
    db: LandmarkDb,
    records: Vec<LandmarkRecord>,
    history: Vec<HistoryEntry>,
    towers: Vec<MapTower>,
    /// Whether the datum came from towers (an empty database gets a placeholder).
    datum_from_towers: bool,
    link: NetLink,
    options: GsOptions,
    tiles: Option<TileLayer>,
    pub selected: Option<NodeId>,
    pub tab: Tab,
    map: MapState,
    camera: CameraState,
    editor: EditorState,
    labels: ReviewView,
    pub survey: SurveyView,
    /// A Record was asked for and the network side has not answered yet.
    record_waiting: bool,
    record_path: String,
    /// The recording being shown instead of live traffic.
    replay: Option<ReplayPlayer>,
}

impl GsApp {
    pub fn new(db: LandmarkDb, link: NetLink, options: GsOptions) -> Result<Self, DbError> {
        let records = db.list()?;
        let (datum, from_towers) = match map_datum(&records) {
            Some(d) => (d, true),
            None => (
                Datum::new(Geodetic {
                    lat_deg: 0.0,
                    lon_deg: 0.0,
                    height_m: 0.0,
                }),
                false,
            ),
        };
        let mut fleet = Fleet::new(datum);
        fleet.corrections = Corrections::starting_at(options.first_request_id);
        let tiles = options.tiles.as_deref().and_then(|dir| {
            TileLayer::open(dir, datum)
                .map_err(|e| fleet.notices.push(e.to_string()))
                .ok()
        });
        let mut app = Self {
            fleet,
            db,
            records: Vec::new(),
            history: Vec::new(),
            towers: Vec::new(),
            datum_from_towers: from_towers,
            link,
            tiles,
            selected: None,
            tab: Tab::Map,
            map: MapState::default(),
            camera: CameraState::default(),
            editor: EditorState::default(),
            labels: ReviewView::default(),
            survey: SurveyView::default(),
            record_waiting: false,
            record_path: "session.mcap".into(),
            replay: None,
            options,
        };
        app.reload_landmarks()?;
        if let Some(dir) = app.options.labels.clone() {
            app.labels.open(&dir);
        }
        Ok(app)
    }

    /// Shows `player`'s recording instead of live traffic; the landmarks
    /// become read-only (they are the recording's, not the field's).
    pub fn replaying(mut self, player: ReplayPlayer) -> Self {
        self.replay = Some(player);
        self
    }

    pub fn replay(&self) -> Option<&ReplayPlayer> {
        self.replay.as_ref()
    }

    pub fn fleet(&self) -> &Fleet {
        &self.fleet
    }

    pub fn db(&self) -> &LandmarkDb {
        &self.db
    }

    /// The stored tower the landmark form edits (`None`: it adds one).
    pub fn editing(&self) -> Option<&str> {
        self.editor.editing.as_deref()
    }

    fn reload_landmarks(&mut self) -> Result<(), DbError> {
        self.records = self.db.list()?;
        self.history = self.db.history_since(0)?;
        if !self.datum_from_towers
            && let Some(datum) = map_datum(&self.records)
        {
            // The first towers of an empty database set the map frame.
            let corrections = std::mem::take(&mut self.fleet.corrections);
            self.fleet = Fleet::new(datum);
            self.fleet.corrections = corrections;
            self.datum_from_towers = true;
        }
        let datum = self.fleet.datum;
        self.towers = self
            .records
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
        Ok(())
    }

    /// Draws one frame; `now_s` is the ground station's monotonic clock
    /// (while replaying, the recording's own clock takes its place).
    pub fn show(&mut self, ui: &mut egui::Ui, now_s: f64) {
        let now_s = match self.replay.as_mut() {
            Some(player) => {
                let due = player.advance(now_s);
                let at = player.position_s();
                for event in due {
                    self.fleet.apply(event, at);
                }
                at
            }
            None => now_s,
        };
        while let Ok(event) = self.link.events.try_recv() {
            if matches!(event, NetEvent::Recording(_)) {
                self.record_waiting = false;
            }
            self.fleet.apply(event, now_s);
        }
        self.fleet.corrections.expire(now_s);
        // A frame under review is not lost with the window.
        if ui.input(|i| i.viewport().close_requested()) {
            self.labels.save();
        }
        if self.selected.is_none() {
            self.selected = self.fleet.uavs.keys().next().cloned();
        }
        egui::Panel::top("toolbar").show(ui, |ui| self.toolbar(ui, now_s));
        egui::Panel::left("fleet")
            .default_size(270.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    fleet_panel::show(
                        ui,
                        &self.fleet,
                        &mut self.selected,
                        &self.options.listening_on,
                        now_s,
                    );
                    ui.separator();
                    ui.label(format!("Towers: {}", self.towers.len()));
                });
            });
        match self.tab {
            Tab::Map => {
                egui::Panel::right("camera")
                    .min_size(520.0)
                    .default_size(560.0)
                    .show(ui, |ui| self.camera_panel(ui, now_s));
                egui::CentralPanel::default().show(ui, |ui| {
                    map_view::show(
                        ui,
                        &mut self.map,
                        &self.fleet,
                        &self.towers,
                        self.tiles.as_mut(),
                        self.selected.as_ref(),
                        now_s,
                    );
                });
            }
            Tab::Landmarks => {
                if self.replay.is_some() {
                    ui.colored_label(
                        egui::Color32::YELLOW,
                        "REPLAY: these are the recording's towers, read-only; nothing here \
                         reaches an edge. Export still works.",
                    );
                }
                let action = landmark_editor::show(ui, &mut self.editor, &self.records);
                // A replay's towers are the recording's: looked at, not edited.
                match action {
                    Some(a) if self.replay.is_none() || matches!(a, EditorAction::Export(..)) => {
                        self.apply_editor(a);
                    }
                    Some(_) => {
                        self.editor.message =
                            Some((false, "not saved: a replay's towers are read-only".into()));
                    }
                    None => {}
                }
            }
            Tab::History => {
                egui::CentralPanel::default()
                    .show(ui, |ui| landmark_editor::history(ui, &self.history));
            }
            Tab::Labels => {
                label_review_view::show(ui, &mut self.labels);
            }
            Tab::Survey => {
                let datum = self.fleet.datum;
                if let Some(action) =
                    survey_review_view::show(ui, &mut self.survey, &self.towers, &datum)
                {
                    self.apply_survey(action);
                }
            }
        }
    }

    /// The survey review's actions: open a file, take a proposal into the
    /// landmark form, or write the accepted ones as one import.
    pub fn apply_survey(&mut self, action: SurveyAction) {
        match action {
            SurveyAction::Open(path) => {
                let file = path.display().to_string();
                let opened = std::fs::read_to_string(&path)
                    .map_err(|e| format!("{file}: {e}"))
                    .and_then(|text| SurveyReview::parse(&text, &file));
                self.survey.message = Some(match opened {
                    Ok(review) => {
                        let text = format!(
                            "{}: {} proposals, {} other towers listed",
                            file,
                            review.proposals.len(),
                            review.others.len()
                        );
                        self.survey.review = Some(review);
                        (true, text)
                    }
                    Err(e) => (false, e),
                });
            }
            SurveyAction::Edit(i) => {
                let Some(p) = self
                    .survey
                    .review
                    .as_mut()
                    .and_then(|r| r.proposals.get_mut(i))
                else {
                    return;
                };
                p.decision = Decision::Edited;
                let stored = self.records.iter().find(|r| r.id == p.record.id);
                self.editor.form = landmark_editor::Form::from_record(&p.record);
                self.editor.editing = stored.map(|r| r.id.clone());
                self.editor.editing_revision = stored.map(|r| r.revision);
                self.editor.touched.clear();
                self.tab = Tab::Landmarks;
            }
            SurveyAction::Apply => {
                let Some(review) = self.survey.review.as_ref() else {
                    return;
                };
                let records = review.accepted();
                let file = format!("survey {}", review.file);
                let parsed = towernav_landmark_db::Parsed {
                    records,
                    problems: Vec::new(),
                };
                let outcome = self.write_import(parsed, &file);
                if let (Ok(_), Some(review)) = (&outcome, self.survey.review.as_mut()) {
                    review.proposals.retain(|p| p.decision != Decision::Accept);
                }
                if let Err(e) = self.reload_landmarks() {
                    self.fleet
                        .notices
                        .push(format!("reading the database: {e}"));
                }
                self.survey.message = Some(match outcome {
                    Ok(text) => (true, text),
                    Err(text) => (false, text),
                });
            }
        }
    }

    fn toolbar(&mut self, ui: &mut egui::Ui, now_s: f64) {
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.tab, Tab::Map, "Map");
            ui.selectable_value(&mut self.tab, Tab::Landmarks, "Landmarks");
            ui.selectable_value(&mut self.tab, Tab::History, "History");
            ui.selectable_value(&mut self.tab, Tab::Labels, "Labels");
            ui.selectable_value(&mut self.tab, Tab::Survey, "Survey review");
            ui.separator();
            if let Some(player) = self.replay.as_mut() {
                let name = self
                    .options
                    .replaying
                    .as_deref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default();
                if session_bar::replay_controls(ui, player, &name) {
                    self.fleet.forget_uavs();
                }
            } else {
                let asked = session_bar::record_controls(
                    ui,
                    self.fleet.recording.as_ref(),
                    self.record_waiting,
                    &mut self.record_path,
                    now_s,
                );
                match asked {
                    Some(RecordAction::Start(path)) => {
                        self.record_waiting = true;
                        let landmarks = self.records.clone();
                        self.command(NetCommand::StartRecording { path, landmarks });
                    }
                    Some(RecordAction::Stop) => self.command(NetCommand::StopRecording),
                    None => {}
                }
            }
            if let Some(notice) = self.fleet.notices.last() {
                ui.separator();
                ui.label(notice);
            }
        });
    }

    fn command(&mut self, command: NetCommand) {
        if self.link.commands.send(command).is_err() {
            self.fleet
                .notices
                .push("the network thread has stopped; nothing was sent".into());
        }
    }

    fn camera_panel(&mut self, ui: &mut egui::Ui, now_s: f64) {
        let Some(uav) = self.selected.clone() else {
            ui.label("Select a UAV in the fleet panel to see its camera.");
            return;
        };
        let Some(view) = self.fleet.uavs.get(&uav) else {
            return;
        };
        let action = egui::ScrollArea::vertical()
            .auto_shrink([false, false])
            .show(ui, |ui| {
                camera_view::show(
                    ui,
                    &mut self.camera,
                    camera_view::Shown {
                        uav: &uav,
                        view,
                        link: self.fleet.link(&uav, now_s),
                        now_s,
                    },
                    &self.fleet.corrections,
                    &self.towers,
                )
            })
            .inner;
        let operator = self.options.operator.clone();
        let message = match action {
            Some(CameraAction::Send {
                uav,
                track_id,
                session,
                tower,
                previous,
            }) => Some(self.fleet.corrections.issue(
                &uav,
                track_id,
                (session != 0).then_some(session),
                tower,
                previous,
                &operator,
                now_s,
            )),
            Some(CameraAction::Undo(request_id)) => {
                self.fleet.corrections.undo(request_id, &operator, now_s)
            }
            Some(CameraAction::Resend(request_id)) => {
                self.fleet.corrections.resend(request_id, &operator, now_s)
            }
            Some(CameraAction::Cancel(request_id)) => {
                self.fleet.corrections.cancel(request_id);
                None
            }
            None => None,
        };
        if let Some(m) = message {
            self.command(NetCommand::Correct(m));
        }
    }

    fn push_undo(&mut self, step: UndoStep) {
        self.editor.undo.push(step);
        if self.editor.undo.len() > UNDO_DEPTH {
            self.editor.undo.remove(0);
        }
    }

    fn apply_editor(&mut self, action: EditorAction) {
        let author = Author::now(&self.options.operator);
        let outcome: Result<String, String> = match action {
            EditorAction::Upsert(record, expect) => self
                .db
                .upsert_expecting(&record, expect, &author)
                .map(|rev| {
                    // The form now stands for the record as just stored.
                    self.editor.editing = Some(record.id.clone());
                    self.editor.editing_revision = Some(rev);
                    format!("saved {} (revision {rev})", record.id)
                })
                .map_err(|e| e.to_string()),
            EditorAction::Delete(id) => match self.db.remove(&id, &author) {
                Ok(Some(rev)) => {
                    if let Some(gone) = self.records.iter().find(|r| r.id == id).cloned() {
                        self.push_undo(UndoStep::Delete(gone));
                    }
                    self.editor.editing = None;
                    self.editor.form = Default::default();
                    self.editor.touched.clear();
                    Ok(format!("deleted {id} (revision {rev})"))
                }
                Ok(None) => Err(format!("{id} was already gone")),
                Err(e) => Err(e.to_string()),
            },
            // A refused undo keeps its step: the operator can try again.
            EditorAction::Undo => match self.editor.undo.last().cloned() {
                None => Err("nothing to undo".into()),
                Some(UndoStep::Delete(record)) => self
                    .db
                    .upsert_expecting(&record, Expect::Absent, &author)
                    .map(|rev| {
                        self.editor.undo.pop();
                        format!("restored {} (revision {rev})", record.id)
                    })
                    .map_err(|e| format!("{} was not restored: {e}", record.id)),
                Some(UndoStep::Import { file, before }) => self
                    .db
                    .revert(&before, &author)
                    .map(|rev| {
                        self.editor.undo.pop();
                        format!(
                            "took back the import of {file}: {} towers as they were (revision {rev})",
                            before.len()
                        )
                    })
                    .map_err(|e| format!("the import of {file} was not taken back: {e}")),
            },
            EditorAction::Import(path, file_format, confirmed) => {
                let options = ImportOptions {
                    osm: OsmMapping::towernav(),
                    ..ImportOptions::default()
                };
                let format = match file_format {
                    FileFormat::Csv => Format::Csv,
                    FileFormat::GeoJson => Format::GeoJson,
                    FileFormat::Osm => Format::OsmXml,
                };
                // Read once: the form's checks, the undo's "before" and the
                // write all take the same towers.
                let parsed = match parse_file(&path, format, &options.osm) {
                    Ok(parsed) => parsed,
                    Err(e) => {
                        self.editor.message = Some((false, e.to_string()));
                        return;
                    }
                };
                // Before anything is written: a tower far from every other
                // or on top of another waits for the operator.
                let doubtful: Vec<String> = if confirmed {
                    Vec::new()
                } else {
                    likely_mistakes(&parsed.records, &self.records, &options)
                        .into_iter()
                        .filter(|w| matches!(w.kind, CheckKind::Far | CheckKind::Spacing))
                        .map(|w| w.to_string())
                        .collect()
                };
                if !doubtful.is_empty() {
                    self.editor.pending_import = Some(PendingImport {
                        path: path.clone(),
                        format: file_format,
                        warnings: doubtful,
                    });
                    self.editor.message = Some((
                        false,
                        format!("{} held back: check the towers listed", path.display()),
                    ));
                    return;
                }
                self.editor.pending_import = None;
                self.write_import(parsed, &path.display().to_string())
            }
            EditorAction::Export(path, format, false) if path.exists() => {
                self.editor.pending_overwrite = Some((path.clone(), format));
                Err(format!(
                    "not exported: {} exists; Overwrite replaces it",
                    path.display()
                ))
            }
            EditorAction::Export(path, format, _) => {
                self.editor.pending_overwrite = None;
                self.export(&path, format)
            }
        };
        if let Err(e) = self.reload_landmarks() {
            self.fleet
                .notices
                .push(format!("reading the database: {e}"));
        }
        self.editor.message = Some(match outcome {
            Ok(text) => (true, text),
            Err(text) => (false, text),
        });
    }

    /// Writes `parsed`'s towers as one import from `file`, under the
    /// operator's name, and keeps what they were before for Undo.
    fn write_import(
        &mut self,
        parsed: towernav_landmark_db::Parsed,
        file: &str,
    ) -> Result<String, String> {
        let author = Author::now(&self.options.operator);
        let options = ImportOptions {
            osm: OsmMapping::towernav(),
            ..ImportOptions::default()
        };
        let before: Vec<_> = parsed
            .records
            .iter()
            .map(|r| self.db.get(&r.id).map(|stored| (r.id.clone(), stored)))
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?;
        let report = import_parsed(&mut self.db, parsed, file, &options, &author)
            .map_err(|e| e.to_string())?;
        if !before.is_empty() {
            let name = std::path::Path::new(file)
                .file_name()
                .map_or_else(|| file.to_owned(), |n| n.to_string_lossy().into_owned());
            self.push_undo(UndoStep::Import { file: name, before });
        }
        let mut text = format!(
            "imported {} towers from {file} (revision {})",
            report.imported, report.revision
        );
        for w in report.warnings.iter().take(3) {
            text += &format!("; {}: {}", w.id, w.message);
        }
        Ok(text)
    }

    fn export(&self, path: &std::path::Path, format: FileFormat) -> Result<String, String> {
        let bytes = match format {
            FileFormat::Csv => {
                let mut out = Vec::new();
                export_csv(&self.records, &mut out).map_err(|e| e.to_string())?;
                out
            }
            FileFormat::GeoJson => export_geojson(&self.records)
                .map_err(|e| e.to_string())?
                .into_bytes(),
            FileFormat::Osm => export_osm_xml(&self.records).into_bytes(),
        };
        std::fs::write(path, bytes).map_err(|e| format!("writing {}: {e}", path.display()))?;
        Ok(format!(
            "exported {} towers to {}",
            self.records.len(),
            path.display()
        ))
    }
}

#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::rc::Rc;

    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;
    use towernav_protocol::{
        CorrectionAck, EdgeState, Health, NodeId, StatusHeartbeat, TowerType, Track, TrackReport,
    };

    use towernav_geometry::PixelBox;

    use super::{GsApp, Tab};
    use crate::events::NetEvent;
    use crate::net::NetCommand;
    use crate::test_support::{app, pose};

    fn harness(app: GsApp, now: Rc<Cell<f64>>) -> Harness<'static, GsApp> {
        Harness::builder()
            .with_size([1600.0, 900.0])
            .build_ui_state(move |ui, app: &mut GsApp| app.show(ui, now.get()), app)
    }

    fn status(uav: &str) -> StatusHeartbeat {
        StatusHeartbeat {
            uav: NodeId::new(uav).expect("valid"),
            time_s: 1.0,
            state: EdgeState::Localized,
            frames_processed: 30,
            frame_rate_hz: 30.0,
            landmarks_loaded: 2,
            datum_lat_deg: 30.52,
            datum_lon_deg: 114.36,
            datum_alt_m: 25.0,
            health: Health::Degraded,
            frames_dropped: 4,
            frames_failed: 0,
            latency_p50_ms: 3.0,
            latency_p99_ms: 9.0,
            detector: "oracle".into(),
        }
    }

    #[test]
    fn the_fleet_panel_shows_each_uav_and_warns_when_it_goes_quiet() {
        let (tx, _commands, app) = app();
        tx.send(NetEvent::Alive {
            uav: NodeId::new("uav1").expect("valid"),
            alive: true,
        })
        .expect("send");
        tx.send(NetEvent::Pose(pose("uav1", 30.5205, 114.3601, 30)))
            .expect("send");
        tx.send(NetEvent::Status(status("uav1"))).expect("send");
        let now = Rc::new(Cell::new(0.0));
        let mut harness = harness(app, now.clone());
        harness.run();
        harness.get_by_label("online");
        harness.get_by_label("latency p50 3 ms, p99 9 ms");
        harness.get_by_label("degraded");
        harness.get_by_label("4 dropped, 0 failed frames; oracle");
        harness.get_by_label("fix from 2 towers: A1 B1");
        assert!(harness.query_by_label_contains("STALE").is_none());
        assert_eq!(
            harness.state().selected.as_ref().map(NodeId::as_str),
            Some("uav1")
        );

        // Everything stops: after two seconds the panel says so.
        now.set(4.0);
        harness.run();
        harness.get_by_label("STALE: nothing heard for 4.0 s");
    }

    #[test]
    fn adding_a_landmark_in_the_ui_persists_it() {
        let (_tx, _commands, app) = app();
        let mut harness = harness(app, Rc::new(Cell::new(0.0)));
        harness.run();
        harness.get_by_label("Landmarks").click();
        harness.run();
        assert_eq!(harness.state().tab, Tab::Landmarks);
        for (field, text) in [
            ("Id", "C7"),
            ("Latitude (deg)", "30.5231"),
            ("Longitude (deg)", "114.3612"),
            ("Ground elevation (m)", "24.5"),
            ("Height (m)", "nine"),
        ] {
            harness
                .get_by_role_and_label(egui::Role::TextInput, field)
                .focus();
            harness.run();
            harness
                .get_by_role_and_label(egui::Role::TextInput, field)
                .type_text(text);
            harness.run();
        }
        // Validation is shown beside the field, and the button stays off.
        harness.get_by_label("\"nine\" is not a number");
        harness.get_by_label("Add").click();
        harness.run();
        assert!(harness.state().db().get("C7").expect("db").is_none());

        let height = "Height (m)";
        harness
            .get_by_role_and_label(egui::Role::TextInput, height)
            .focus();
        harness.run();
        for _ in 0..4 {
            harness.key_press(egui::Key::Backspace);
        }
        harness
            .get_by_role_and_label(egui::Role::TextInput, height)
            .type_text("41");
        harness.run();
        harness.get_by_label("Add").click();
        harness.run();
        let stored = harness
            .state()
            .db()
            .get("C7")
            .expect("db")
            .expect("the tower was written");
        assert_eq!((stored.tower_type, stored.height_m), (TowerType::A, 41.0));
        harness.get_by_label_contains("saved C7");
        // The map and the history know it too.
        harness.get_by_label("Towers: 3");
        harness.get_by_label("History").click();
        harness.run();
        harness.get_by_label("Edit history (3 revisions)");
        harness.get_by_label_contains("set C7 (A, 30.523100");
    }

    #[test]
    fn a_click_on_a_box_then_a_tower_publishes_a_correction_and_shows_its_ack() {
        let (tx, mut commands, app) = app();
        let uav = NodeId::new("uav1").expect("valid");
        tx.send(NetEvent::Pose(pose("uav1", 30.5205, 114.3601, 5)))
            .expect("send");
        tx.send(NetEvent::Tracks(TrackReport {
            uav: uav.clone(),
            time_s: 0.2,
            seq: 5,
            tracks: vec![Track {
                track_id: 7,
                bbox: PixelBox::new(600.0, 200.0, 660.0, 400.0),
                tower_type: TowerType::B,
                tower_id: Some("A1".into()),
                pinned: false,
                confidence: Some(0.3),
            }],
            session: 0,
        }))
        .expect("send");
        let jpeg = crate::test_support::jpeg(64, 36, [90, 120, 160]);
        let preview = towernav_protocol::Preview {
            uav: uav.clone(),
            time_s: 0.2,
            seq: 5,
            frame_width: 1280,
            frame_height: 720,
            jpeg,
        };
        let bytes = towernav_protocol::encode(&preview).expect("encode");
        let key = towernav_protocol::Keys::new(NodeId::new("demo").expect("valid"))
            .uav_key::<towernav_protocol::Preview>(&uav);
        tx.send(crate::events::decode_sample(&key, &bytes).expect("preview"))
            .expect("send");
        let mut harness = harness(app, Rc::new(Cell::new(0.0)));
        harness.run();

        harness.get_by_label("T7 A1").click();
        harness.run();
        harness.get_by_label("Correct track 7 (now A1)");
        harness.get_by_label("Tower id").focus();
        harness.run();
        harness.get_by_label("Tower id").type_text("B");
        harness.run();
        assert!(harness.query_by_label("A1 (A)").is_none(), "search filters");
        harness.get_by_label("B1 (B)").click();
        harness.run();
        harness.get_by_label("Send B1").click();
        harness.run();

        let sent = match commands.try_recv() {
            Ok(NetCommand::Correct(c)) => c,
            other => panic!("expected a correction, got {other:?}"),
        };
        assert_eq!(
            (sent.uav.as_str(), sent.track_id, sent.tower_id.as_deref()),
            ("uav1", 7, Some("B1"))
        );
        harness.get_by_label("pending 0 s");

        tx.send(NetEvent::Ack(CorrectionAck {
            uav: uav.clone(),
            request_id: sent.request_id,
            accepted: true,
            reason: None,
        }))
        .expect("send");
        harness.run();
        harness.get_by_label("accepted");
        harness.get_by_label("Undo").click();
        harness.run();
        match commands.try_recv() {
            Ok(NetCommand::Correct(c)) => {
                // The edge had bound A1 itself: the undo hands the track back to it.
                assert_eq!(
                    (c.track_id, c.tower_id.as_deref(), c.release),
                    (7, None, true)
                );
                tx.send(NetEvent::Ack(CorrectionAck {
                    uav,
                    request_id: c.request_id,
                    accepted: false,
                    reason: Some("track 7 ended".into()),
                }))
                .expect("send");
            }
            other => panic!("expected the undo, got {other:?}"),
        }
        harness.run();
        harness.get_by_label("rejected: track 7 ended");
    }

    #[test]
    fn export_then_import_round_trips_every_format_and_a_bad_file_is_refused() {
        use crate::landmark_editor::{EditorAction, FileFormat};
        let dir = tempfile::tempdir().expect("tempdir");
        for format in FileFormat::ALL {
            let (_tx, _commands, mut app) = app();
            let path = dir
                .path()
                .join(format!("towers.{}", format.label().replace(' ', "")));
            app.apply_editor(EditorAction::Export(path.clone(), format, false));
            assert_eq!(
                app.editor.message.as_ref().map(|m| m.0),
                Some(true),
                "{format:?}"
            );
            // A second export to the same file asks first, then overwrites when told.
            app.apply_editor(EditorAction::Export(path.clone(), format, false));
            assert_eq!(
                app.editor.message.as_ref().map(|m| m.0),
                Some(false),
                "{format:?}: an existing file is not overwritten unasked"
            );
            assert!(app.editor.pending_overwrite.is_some());
            app.apply_editor(EditorAction::Export(path.clone(), format, true));
            assert_eq!(
                app.editor.message.as_ref().map(|m| m.0),
                Some(true),
                "{format:?}"
            );
            app.apply_editor(EditorAction::Delete("A1".into()));
            assert_eq!(app.records.len(), 1);
            app.apply_editor(EditorAction::Import(path, format, false));
            let message = app.editor.message.clone().expect("message");
            assert!(
                message.0 && message.1.contains("imported 2 towers"),
                "{format:?}: {message:?}"
            );
            assert_eq!(app.records.len(), 2, "{format:?}");
            assert_eq!(app.towers.len(), 2, "the map follows the database");
        }
        let (_tx, _commands, mut app) = app();
        let junk = dir.path().join("junk.csv");
        std::fs::write(&junk, "id,tower_type\nX1,Q\n").expect("write");
        app.apply_editor(EditorAction::Import(junk, FileFormat::Csv, false));
        let message = app.editor.message.clone().expect("message");
        assert!(!message.0 && message.1.contains("junk.csv"), "{message:?}");
        assert_eq!(app.records.len(), 2, "nothing written");
    }

    #[test]
    fn an_import_with_a_tower_far_from_every_other_waits_for_the_operator() {
        use crate::landmark_editor::{EditorAction, FileFormat};
        let dir = tempfile::tempdir().expect("tempdir");
        let (_tx, _commands, mut app) = app();
        assert_eq!(app.records.len(), 2);
        // One latitude with a wrong digit: 26 degrees north of the line.
        let file = dir.path().join("survey.csv");
        std::fs::write(
            &file,
            "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m\n\
             C1,A,30.5231,114.3612,24.5,33\n\
             C2,A,56.5241,114.3622,24.5,33\n",
        )
        .expect("write");
        app.apply_editor(EditorAction::Import(file.clone(), FileFormat::Csv, false));
        assert_eq!(app.records.len(), 2, "held back: nothing written");
        let pending = app.editor.pending_import.clone().expect("held back");
        assert_eq!(pending.warnings.len(), 1, "{:?}", pending.warnings);
        assert!(
            pending.warnings[0].starts_with("C2: stands"),
            "{:?}",
            pending.warnings
        );
        // The operator says the file is right.
        app.apply_editor(EditorAction::Import(file, FileFormat::Csv, true));
        assert_eq!(app.records.len(), 4);
        assert!(app.editor.pending_import.is_none());
        // The map's origin stays on the line, not halfway to C2.
        let datum = crate::app::map_datum(&app.records).expect("datum");
        assert!((datum.origin.lat_deg - 30.52).abs() < 0.01, "{datum:?}");
    }

    #[test]
    fn an_import_is_taken_back_as_a_whole_and_a_refused_undo_stays() {
        use crate::landmark_editor::{EditorAction, FileFormat, UndoStep};
        let dir = tempfile::tempdir().expect("tempdir");
        let (_tx, _commands, mut app) = app();
        let a1 = app.db.get("A1").expect("db").expect("A1");
        let file = dir.path().join("resurvey.csv");
        // A1 moved by the re-survey, C1 new.
        std::fs::write(
            &file,
            "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m\n\
             A1,A,30.5201,114.3601,25,35\n\
             C1,A,30.5231,114.3612,24.5,33\n",
        )
        .expect("write");
        app.apply_editor(EditorAction::Import(file, FileFormat::Csv, true));
        assert_eq!(app.records.len(), 3);
        let step = app.editor.undo.last().cloned().expect("an undo step");
        assert_eq!(step.label(), "Undo import of resurvey.csv (2 towers)");
        // One undo puts A1 back where it was and removes C1, in one go.
        app.apply_editor(EditorAction::Undo);
        let back = app.db.get("A1").expect("db").expect("A1");
        assert_eq!(
            (back.lat_deg, back.lon_deg, back.height_m),
            (a1.lat_deg, a1.lon_deg, a1.height_m)
        );
        assert!(app.db.get("C1").expect("db").is_none());
        assert!(app.editor.undo.is_empty());
        // A delete's undo refused (the id was taken again) keeps its button.
        app.apply_editor(EditorAction::Delete("A1".into()));
        assert!(matches!(app.editor.undo.last(), Some(UndoStep::Delete(_))));
        app.db
            .upsert(&a1, &towernav_landmark_db::Author::now("someone else"))
            .expect("retaken");
        app.apply_editor(EditorAction::Undo);
        assert!(
            matches!(app.editor.undo.last(), Some(UndoStep::Delete(_))),
            "a refused undo lost its step"
        );
    }
}
