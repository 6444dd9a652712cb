//! The demo build's parts of `run` and `demo`: the simulated flight as a
//! source, and the demo's listener on loopback that gathers the poses like a
//! ground station, scores the run against truth from outside the daemon, and
//! ends with the report and plots.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use nalgebra::{Point3, Vector3};
use towernav_eval::cmd::demo_plots;
use towernav_eval::report::FlightReport;
use towernav_eval::truth_scorer::TruthScorer;
use towernav_geometry::{Datum, PinholeCamera};
use towernav_protocol::session::Endpoints;
use towernav_protocol::{LandmarkRecord, NodeId};
use towernav_sim::waypoints::{FlightPlan, PlanSource, along_longest_line};
use towernav_sim::{Scenario, World};
use zenoh::Session;

use crate::collector::PoseCollector;
use crate::daemon::config::{DetectorKind, EdgeConfig, SourceSection};
use crate::daemon::run::RunSummary;
use crate::daemon::sim_source::{SimRender, SimSource};
use crate::daemon::source::FrameSource;
use crate::node::{open_session, wait_for_peer};

/// Where the simulated take-off is assumed, off the true one (metres east, north).
const SIM_TAKEOFF_ERROR_M: (f64, f64) = (3.0, -4.0);

/// A simulated flight, for the sim source.
pub struct Sim {
    pub scenario: Arc<Scenario>,
}

impl Sim {
    pub fn from_config(source: &SourceSection) -> anyhow::Result<Arc<Self>> {
        Ok(Arc::new(Self {
            scenario: Arc::new(sim_scenario(source)?),
        }))
    }

    pub fn camera(&self) -> PinholeCamera {
        self.scenario.camera
    }

    pub fn datum(&self) -> Datum {
        self.scenario.world.datum
    }

    pub fn takeoff_in_world(&self) -> Point3<f64> {
        self.scenario.start_in_world()
            + Vector3::new(SIM_TAKEOFF_ERROR_M.0, SIM_TAKEOFF_ERROR_M.1, 0.0)
    }

    pub fn landmarks(&self) -> Vec<LandmarkRecord> {
        self.scenario.world.landmarks()
    }

    pub fn frame_count(&self) -> u64 {
        self.scenario.frame_count()
    }

    pub fn source(&self, config: &EdgeConfig) -> Box<dyn FrameSource> {
        let s = &self.scenario;
        let render = match config.detector.kind {
            DetectorKind::Yolo => SimRender::Detector,
            // Render just the frames the preview will show.
            DetectorKind::Oracle if config.output.preview_hz > 0.0 => {
                SimRender::PreviewEvery((s.fps / config.output.preview_hz).round().max(1.0) as u64)
            }
            DetectorKind::Oracle => SimRender::Never,
        };
        Box::new(
            SimSource::new(s.clone(), render, config.source.max_frames)
                .with_stall(config.source.stall),
        )
    }
}

/// The simulated flight `source` asks for: its world (the paper's field, a
/// random one, or one built from a landmark file) and its flight (a preset, a
/// plan file, or by default the skeleton's level flight over the paper's field
/// and a pass along the longest line over any other world).
pub fn sim_scenario(source: &SourceSection) -> anyhow::Result<Scenario> {
    let world = World::chosen(
        source.world.as_deref(),
        source.random_world,
        towernav_landmark_db::load_towers,
    )?;
    let seed = source.seed;
    let plan = match &source.flight {
        Some(flight) => match PlanSource::parse(flight) {
            PlanSource::Preset(name) => FlightPlan::preset(&name)?,
            PlanSource::File(path) => {
                let text = std::fs::read_to_string(&path).with_context(|| {
                    format!(
                        "reading the flight plan {} (not a preset either: {})",
                        path.display(),
                        towernav_sim::waypoints::PRESETS.map(|(n, _)| n).join(", ")
                    )
                })?;
                FlightPlan::parse(&text, &path.display().to_string())?
            }
        },
        None if source.world.is_none() && source.random_world.is_none() => {
            return Ok(Scenario::paper(seed));
        }
        None => along_longest_line(&world)
            .context("the world has no line of two towers to fly along; give source.flight")?,
    };
    Ok(Scenario::flying(world, &plan, seed))
}

/// The demo's side of a run: a listener on loopback and the scorer.
pub struct DemoRun {
    _session: Session,
    collector: PoseCollector,
    pub scorer: TruthScorer,
    sim: Arc<Sim>,
    out: PathBuf,
}

impl DemoRun {
    /// Connects a listener to the edge's first listen endpoint.
    pub async fn start(
        config: &EdgeConfig,
        fleet: &NodeId,
        sim: Arc<Sim>,
        out: &Path,
    ) -> anyhow::Result<Self> {
        let connect = config
            .zenoh
            .listen
            .first()
            .cloned()
            .context("the demo needs a zenoh.listen endpoint to listen on")?;
        let session = open_session(&Endpoints {
            listen: vec![],
            connect: vec![connect],
            ..Default::default()
        })
        .await?;
        let collector = PoseCollector::start(&session, fleet.clone()).await?;
        wait_for_peer(&session, Duration::from_secs(10)).await?;
        Ok(Self {
            _session: session,
            collector,
            scorer: TruthScorer::new(sim.scenario.clone()),
            sim,
            out: out.to_path_buf(),
        })
    }

    /// Gathers the last poses, prints the report and writes the plots.
    pub async fn finish(self, config: &EdgeConfig, summary: &RunSummary) -> anyhow::Result<()> {
        let scenario = &self.sim.scenario;
        let received = self
            .collector
            .drain(
                summary.record.poses_published as usize,
                Duration::from_secs(3),
            )
            .await;
        if self.collector.rejected() > 0 {
            println!(
                "warning: {} poses did not decode",
                self.collector.rejected()
            );
        }
        let report = FlightReport::new(&summary.record, &self.scorer, &received, scenario.fps);
        println!(
            "\ntowernav demo report ({}, {} towers, seed {})\n{report}",
            world_name(&config.source),
            scenario.world.towers.len(),
            config.source.seed
        );
        let (p50, p99) = summary.latency_ms;
        println!(
            "latency            frame to publish p50 {p50:.1} ms, p99 {p99:.1} ms; {} frames dropped by the queue, {} failed",
            summary.dropped, summary.failed
        );
        println!(
            "throughput         {:.1} frames/s over {:.1} s; peak RSS {}",
            summary.record.frames as f64 / summary.record.wall_seconds.max(1e-9),
            summary.record.wall_seconds,
            crate::peak_rss::peak_rss_mb()
                .map_or_else(|| "unknown".into(), |mb| format!("{mb:.0} MB"))
        );
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("creating {}", self.out.display()))?;
        let (trajectory, errors) =
            demo_plots::write(&self.out, &self.scorer, &received, scenario.fps)?;
        println!(
            "plots              {} and {}",
            trajectory.display(),
            errors.display()
        );
        Ok(())
    }
}

/// The world a simulated source flies over, for the report.
fn world_name(source: &SourceSection) -> String {
    match (&source.world, source.random_world) {
        (Some(path), _) => format!("towers of {}", path.display()),
        (None, Some(seed)) => format!("random world {seed}"),
        (None, None) => "the paper's field".into(),
    }
}
