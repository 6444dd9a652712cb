//! `towernav-gs`: the ground station window.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use clap::Parser;
use towernav_ground_station::app::{GsApp, GsOptions, Tab};
use towernav_ground_station::net::{self, NetLink};
use towernav_ground_station::recording::{self, ReplayPlayer};
use towernav_ground_station::survey_review_view::SurveyAction;
use towernav_landmark_db::{Author, LandmarkDb, import_csv};
use towernav_protocol::NodeId;
use towernav_protocol::security::Credentials;
use towernav_protocol::session::Endpoints;

#[derive(Parser)]
#[command(
    about = "towernav ground station: landmark database, live fleet map, camera view, corrections"
)]
struct Cli {
    /// The landmark database (created if missing).
    #[arg(long, default_value = "towers.sqlite")]
    db: PathBuf,
    /// Import this landmark CSV into the database first (all rows or none).
    #[arg(long)]
    import: Option<PathBuf>,
    #[arg(long, default_value = "demo")]
    fleet: NodeId,
    /// Zenoh endpoint of an edge or router to connect to (repeatable).
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    connect: Vec<String>,
    /// Zenoh endpoint to listen on, for edges that connect to the ground station.
    #[arg(long)]
    listen: Vec<String>,
    /// This ground station's credentials folder (`towernav-fleet issue --role
    /// ground-station`): links become mutual TLS (`tls/` endpoints) under the
    /// fleet's access rules. Without it, plain TCP (loopback and tests only).
    #[arg(long)]
    credentials: Option<PathBuf>,
    /// Its certificate name, when the roster has several ground stations.
    #[arg(long, requires = "credentials")]
    node: Option<String>,
    /// Name stamped on database changes and corrections made from this ground station.
    #[arg(long, env = "USER", default_value = "ground-station")]
    operator: String,
    /// A local slippy-map tile folder (<zoom>/<x>/<y>.png) for the map background.
    #[arg(long)]
    tiles: Option<PathBuf>,
    /// Replay this MCAP recording instead of joining the network.
    #[arg(long)]
    replay: Option<PathBuf>,
    /// Replay speed (1 = as recorded, 0 = as fast as possible).
    #[arg(long, default_value_t = 1.0)]
    replay_speed: f64,
    /// The tab the window opens on (with --labels, the Labels tab; with
    /// --survey, the Survey review tab).
    #[arg(long, value_parser = ["map", "landmarks", "history", "labels", "survey"])]
    tab: Option<String>,
    /// Review a survey's measured towers (`towernav-edge map-towers`'s
    /// towers-mapped.geojson): accept, reject or edit each before it is written.
    #[arg(long)]
    survey: Option<PathBuf>,
    /// Review a labelled dataset (`towernav-edge label`'s output folder, or
    /// images/ with labels/): accept, reject and move its boxes, frame by frame.
    #[arg(long)]
    labels: Option<PathBuf>,
    /// Close the window after this many seconds (screenshots, benchmarks).
    #[arg(long)]
    quit_after_s: Option<f64>,
    /// Save a PNG of the window here just before quitting (needs --quit-after-s).
    #[arg(long, requires = "quit_after_s")]
    screenshot: Option<PathBuf>,
    /// Repaint continuously and log the frame rate at exit (a benchmark, not for flying).
    #[arg(long)]
    continuous: bool,
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,towernav=info".into()),
        )
        .init();
    let cli = Cli::parse();
    // A replay is read, and refused, before any window opens; it brings its
    // own towers, and touches no database file.
    let replay = cli
        .replay
        .as_deref()
        .map(|path| replay_database(path, &cli))
        .transpose()?;
    let (db, replay) = match replay {
        Some((db, samples)) => (db, Some(samples)),
        None => (open_database(&cli)?, None),
    };
    let security = match &cli.credentials {
        Some(dir) => {
            let credentials = Credentials::load_ground_station(dir, cli.node.as_deref())?;
            tracing::info!(
                node = credentials.name(),
                "zenoh: mutual TLS, fleet access rules"
            );
            Some(credentials)
        }
        None => {
            tracing::info!(
                "zenoh: plain TCP, no credentials (loopback and tests only; see `towernav-fleet`)"
            );
            None
        }
    };
    let endpoints = Endpoints {
        listen: cli.listen.clone(),
        connect: cli.connect.clone(),
        security,
    };
    let options = gs_options(&cli);
    let db_path = cli.db.clone();
    let start = Instant::now();
    let continuous = cli.continuous;
    let tab = cli.tab.clone().unwrap_or_else(|| {
        if cli.labels.is_some() {
            "labels"
        } else if cli.survey.is_some() {
            "survey"
        } else {
            "map"
        }
        .into()
    });
    let mut exit = Exit {
        quit_after_s: cli.quit_after_s,
        screenshot: cli.screenshot.clone(),
        shot_requested: false,
        shot_done: Arc::new(AtomicBool::new(false)),
    };
    let mut frames = FrameStats::default();
    eframe::run_native(
        "towernav ground station",
        eframe::NativeOptions {
            viewport: egui::ViewportBuilder::default().with_inner_size([1600.0, 900.0]),
            // A benchmark measures the app, not the display's refresh.
            glow_options: eframe::egui_glow::GlowConfiguration {
                vsync: !continuous,
                ..Default::default()
            },
            ..Default::default()
        },
        Box::new(move |cc| {
            let ctx = cc.egui_ctx.clone();
            let wake = move || ctx.request_repaint();
            let mut app = match replay {
                Some(samples) => {
                    let (_tx, _commands, link) = NetLink::detached();
                    GsApp::new(db, link, options)?
                        .replaying(ReplayPlayer::of(samples, cli.replay_speed))
                }
                None => GsApp::new(
                    db,
                    net::spawn(endpoints, cli.fleet, Some(db_path), wake),
                    options,
                )?,
            };
            app.tab = match tab.as_str() {
                "landmarks" => Tab::Landmarks,
                "history" => Tab::History,
                "labels" => Tab::Labels,
                "survey" => Tab::Survey,
                _ => Tab::Map,
            };
            if let Some(path) = &cli.survey {
                app.survey.path = path.display().to_string();
                app.apply_survey(SurveyAction::Open(path.clone()));
            }
            Ok(Box::new(FnApp(move |ui: &mut egui::Ui| {
                let now = start.elapsed().as_secs_f64();
                let drawn = Instant::now();
                app.show(ui, now);
                frames.add(now, drawn.elapsed().as_secs_f64());
                let quitting = exit.after_frame(ui.ctx(), now, &mut frames);
                if continuous || quitting {
                    ui.ctx().request_repaint();
                } else {
                    // Ages tick even when no message arrives.
                    ui.ctx()
                        .request_repaint_after(std::time::Duration::from_millis(250));
                }
            })))
        }),
    )
    .map_err(|e| anyhow::anyhow!("ground station window: {e}"))
}

/// The towers a replay shows, in memory: those the recording carries, else
/// `--db`'s if that file exists (a recording made before recordings carried
/// towers), else none.
fn replay_database(
    path: &std::path::Path,
    cli: &Cli,
) -> anyhow::Result<(LandmarkDb, recording::Recording)> {
    let samples = recording::read(path)?;
    if let Some(cut) = &samples.cut_short {
        tracing::warn!("{cut}");
    }
    let towers = match recording::landmarks(path, &samples.samples)? {
        Some(towers) => towers,
        None if cli.db.is_file() => {
            tracing::warn!(recording = %path.display(), db = %cli.db.display(), "the recording carries no towers: showing the database's");
            LandmarkDb::open(&cli.db)?.list()?
        }
        None => {
            tracing::warn!(recording = %path.display(), "the recording carries no towers and --db does not exist: no towers on the map");
            Vec::new()
        }
    };
    let mut db = LandmarkDb::open_in_memory()?;
    db.upsert_all(&towers, &Author::now("replay"))?;
    Ok((db, samples))
}

/// Opens the landmark database, importing `--import` first.
fn open_database(cli: &Cli) -> anyhow::Result<LandmarkDb> {
    let mut db = LandmarkDb::open(&cli.db)?;
    if let Some(csv) = &cli.import {
        let n = import_csv(&mut db, csv, &Author::now(&cli.operator))?;
        tracing::info!(towers = n, file = %csv.display(), "imported");
    }
    if db.list()?.is_empty() {
        tracing::warn!(db = %cli.db.display(), "no towers yet: add them in the Landmarks tab or with --import");
    }
    Ok(db)
}

fn gs_options(cli: &Cli) -> GsOptions {
    let listening_on = cli
        .connect
        .iter()
        .chain(&cli.listen)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    // Request ids start at the clock, so a restarted station never reuses one.
    let first_request_id = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(1, |d| u64::try_from(d.as_millis()).unwrap_or(1));
    GsOptions {
        listening_on,
        operator: cli.operator.clone(),
        first_request_id,
        tiles: cli.tiles.clone(),
        replaying: cli.replay.clone(),
        labels: cli.labels.clone(),
    }
}

/// `--quit-after-s` and `--screenshot`: when to close, and the PNG taken first.
struct Exit {
    quit_after_s: Option<f64>,
    screenshot: Option<PathBuf>,
    shot_requested: bool,
    shot_done: Arc<AtomicBool>,
}

impl Exit {
    /// After each frame: asks for the screenshot, then closes once it is saved.
    /// True while quitting, so frames keep coming until the window closes.
    fn after_frame(&mut self, ctx: &egui::Context, now: f64, frames: &mut FrameStats) -> bool {
        let quitting = self.quit_after_s.is_some_and(|q| now > q);
        match (&self.screenshot, quitting) {
            (Some(path), true) if !self.shot_requested => {
                self.shot_requested = true;
                let (path, done) = (path.clone(), self.shot_done.clone());
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(
                    egui::ScreenshotCallback::new(move |image| {
                        save_png(&path, &image);
                        done.store(true, Ordering::Relaxed);
                    }),
                ));
            }
            (Some(_), true) if !self.shot_done.load(Ordering::Relaxed) => {}
            (_, true) => {
                frames.log();
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
            _ => {}
        }
        quitting
    }
}

fn save_png(path: &std::path::Path, image: &egui::ColorImage) {
    let [w, h] = image.size;
    let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    let saved = image::RgbaImage::from_raw(w as u32, h as u32, rgba)
        .ok_or_else(|| "screenshot size does not match its pixels".to_owned())
        .and_then(|img| img.save(path).map_err(|e| e.to_string()));
    match saved {
        Ok(()) => tracing::info!(path = %path.display(), width = w, height = h, "screenshot saved"),
        Err(e) => tracing::error!(path = %path.display(), error = %e, "screenshot not saved"),
    }
}

/// Frame intervals and UI build times after the first two seconds (start-up excluded).
#[derive(Default)]
struct FrameStats {
    last_s: Option<f64>,
    intervals_s: Vec<f64>,
    build_s: Vec<f64>,
    logged: bool,
}

impl FrameStats {
    fn add(&mut self, now_s: f64, build_s: f64) {
        if now_s > 2.0 {
            if let Some(last) = self.last_s {
                self.intervals_s.push(now_s - last);
            }
            self.build_s.push(build_s);
        }
        self.last_s = Some(now_s);
    }

    /// Logs once: the frames after the close request are not counted twice.
    fn log(&mut self) {
        if self.logged || self.intervals_s.is_empty() {
            return;
        }
        let mean = self.intervals_s.iter().sum::<f64>() / self.intervals_s.len() as f64;
        self.build_s.sort_by(f64::total_cmp);
        let at = |q: f64| self.build_s[((self.build_s.len() - 1) as f64 * q).round() as usize];
        tracing::info!(
            frames = self.intervals_s.len(),
            fps = format!("{:.1}", 1.0 / mean),
            ui_build_p50_ms = format!("{:.2}", at(0.5) * 1e3),
            ui_build_p99_ms = format!("{:.2}", at(0.99) * 1e3),
            "frame rate"
        );
        self.logged = true;
    }
}

struct FnApp<F>(F);

impl<F: FnMut(&mut egui::Ui)> eframe::App for FnApp<F> {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        (self.0)(ui);
    }
}
