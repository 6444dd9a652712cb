//! `towernav-gs`: the ground station window.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Parser;
use towernav_ground_station::app::{GsApp, map_datum};
use towernav_ground_station::net;
use towernav_landmark_db::{Author, LandmarkDb, import_csv};
use towernav_protocol::NodeId;
use towernav_protocol::session::Endpoints;

#[derive(Parser)]
#[command(about = "towernav ground station: landmark database and live fleet map")]
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
    /// Name stamped on database changes made from this ground station.
    #[arg(long, env = "USER", default_value = "ground-station")]
    operator: String,
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| "warn,towernav=info".into()),
        )
        .init();
    let cli = Cli::parse();
    let mut db = LandmarkDb::open(&cli.db)?;
    if let Some(csv) = &cli.import {
        let n = import_csv(&mut db, csv, &Author::now(&cli.operator))?;
        tracing::info!(towers = n, file = %csv.display(), "imported");
    }
    let landmarks = db.list()?;
    let datum = map_datum(&landmarks).with_context(|| {
        format!(
            "{} holds no towers: import some with --import towers.csv",
            cli.db.display()
        )
    })?;

    let endpoints = Endpoints {
        listen: cli.listen.clone(),
        connect: cli.connect.clone(),
    };
    let listening_on = cli
        .connect
        .iter()
        .chain(&cli.listen)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    let db_path = cli.db.clone();
    let start = Instant::now();
    eframe::run_native(
        "towernav ground station",
        eframe::NativeOptions::default(),
        Box::new(move |cc| {
            let ctx = cc.egui_ctx.clone();
            let events = net::spawn(endpoints, cli.fleet, Some(db_path), move || {
                ctx.request_repaint()
            });
            let mut app = GsApp::new(&landmarks, datum, events, listening_on);
            Ok(Box::new(FnApp(move |ui: &mut egui::Ui| {
                app.show(ui, start.elapsed().as_secs_f64());
                // Ages tick even when no message arrives.
                ui.ctx()
                    .request_repaint_after(std::time::Duration::from_millis(250));
            })))
        }),
    )
    .map_err(|e| anyhow::anyhow!("ground station window: {e}"))
}

struct FnApp<F>(F);

impl<F: FnMut(&mut egui::Ui)> eframe::App for FnApp<F> {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        (self.0)(ui);
    }
}
