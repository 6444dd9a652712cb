//! `towernav-sim`: worlds, flights, rendered frames and datasets with exact truth.

mod cli;

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use cli::flight_cmd::FlightOutputs;
use towernav_sim::gnss::GnssParams;
use towernav_sim::replay::{ReplaySource, ReplayWorld};
use towernav_sim::waypoints::FlightPlan;
use towernav_sim::{Conditions, Renderer, Scenario, World};

#[derive(Parser)]
#[command(
    about = "towernav simulator: worlds and flights with exact truth, rendered frames, datasets"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum Weather {
    /// Clear midday, light haze, a little noise.
    Default,
    /// No haze, clouds, noise, blur or distractors: geometry only.
    Plain,
    /// Drawn at random from `--seed`.
    Random,
}

#[derive(clap::Args)]
struct WorldArg {
    /// Use a seeded random world instead of the paper's 18-tower field.
    #[arg(long, conflicts_with = "world")]
    random_world: Option<u64>,
    /// Build the world from a landmark CSV or database (positions, heights,
    /// types; lines by line_name) on a flat plate whose datum is 100 m south
    /// and west of the towers, at the lowest foot.
    #[arg(long)]
    world: Option<PathBuf>,
}

impl WorldArg {
    fn world(&self) -> anyhow::Result<World> {
        Ok(World::chosen(
            self.world.as_deref(),
            self.random_world,
            towernav_landmark_db::load_towers,
        )?)
    }
}

#[derive(clap::Args)]
struct PlanArg {
    /// A named flight plan: paper-path-1, paper-path-2, straight, out-and-back, lawnmower.
    #[arg(long, default_value = "paper-path-1", conflicts_with = "plan")]
    preset: String,
    /// A waypoint file (TOML, as in sim/flights/).
    #[arg(long)]
    plan: Option<PathBuf>,
}

impl PlanArg {
    /// The same plan as the edge's `source.flight` spells it: a preset's name or a file's path.
    fn spelled(&self) -> String {
        match &self.plan {
            Some(path) => std::path::absolute(path)
                .unwrap_or_else(|_| path.clone())
                .display()
                .to_string(),
            None => self.preset.clone(),
        }
    }

    fn plan(&self) -> anyhow::Result<FlightPlan> {
        Ok(match &self.plan {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .with_context(|| format!("reading flight plan {}", path.display()))?;
                FlightPlan::parse(&text, &path.display().to_string())?
            }
            None => FlightPlan::preset(&self.preset)?,
        })
    }
}

#[derive(Subcommand)]
enum Command {
    /// Write a world's towers as a landmark CSV.
    World {
        #[command(flatten)]
        world: WorldArg,
        /// Write the towers as a poor map would hold them: every other one
        /// left out, the rest moved 5-10 m in a direction drawn from this
        /// seed (the input of a `towernav-edge map-towers` trial).
        #[arg(long, value_name = "SEED")]
        degrade: Option<u64>,
        /// Output CSV path; `-` for standard output.
        #[arg(long, default_value = "-")]
        out: PathBuf,
    },
    /// Fly a plan: trajectory.csv, truth.csv, MOT ground truth, towers.csv and
    /// replay.toml (the edge replays it: with --images the frames as a camera,
    /// else the same simulated flight with the oracle detector).
    Flight {
        #[command(flatten)]
        world: WorldArg,
        #[command(flatten)]
        plan: PlanArg,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Also render every frame into mot/<plan>/img1/.
        #[arg(long)]
        images: bool,
        /// Also render every frame into flight.mp4 (H.264, through ffmpeg).
        #[arg(long)]
        video: bool,
        /// See through this lens: an OpenCV, ROS camera_info or Kalibr
        /// calibration file (its intrinsics, distortion and image size).
        #[arg(long)]
        calibration: Option<PathBuf>,
        /// One-sigma horizontal GNSS error of flight.tlog's positions, metres.
        #[arg(long, default_value_t = 1.5)]
        gnss_sigma_m: f64,
        /// How long the GNSS error takes to forget itself, seconds (0: a
        /// fresh error every fix).
        #[arg(long, default_value_t = 10.0)]
        gnss_correlation_s: f64,
        /// One-sigma error of flight.tlog's GNSS velocities, m/s per axis
        /// (forgotten within a second).
        #[arg(long, default_value_t = 0.1)]
        gnss_velocity_sigma_mps: f64,
        /// One-sigma IMU attitude error (roll, pitch and heading), degrees;
        /// default: the simulator's IMU (0.1 roll and pitch, 0.2 heading).
        #[arg(long)]
        attitude_sigma_deg: Option<f64>,
        #[arg(long, value_enum, default_value = "default")]
        weather: Weather,
        /// Also write every Nth frame with its exact truth boxes to
        /// dataset/ (YOLO images, labels and data.yaml), to score a
        /// detector on this flight with `towernav-edge eval-detector --images`.
        #[arg(long, value_name = "N")]
        dataset_every: Option<u64>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Render one frame of a flight to PNG, with its truth boxes drawn unless
    /// --no-boxes; with --randomized N, a contact sheet of N frames as the
    /// randomized dataset draws them.
    Render {
        #[command(flatten)]
        world: WorldArg,
        #[command(flatten)]
        plan: PlanArg,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Seconds into the flight.
        #[arg(long, default_value_t = 20.0)]
        time: f64,
        #[arg(long, value_enum, default_value = "default")]
        weather: Weather,
        #[arg(long)]
        no_boxes: bool,
        /// Draw this many randomized frames from worlds drawn from --seed instead, as one sheet.
        #[arg(long, default_value_t = 0)]
        randomized: usize,
        /// Folders of real tower-free photos for the randomized frames' backgrounds.
        #[arg(long)]
        backgrounds: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// YOLO dataset (images, labels, data.yaml; split by world) and MOT truth, from random worlds.
    Dataset {
        #[arg(long)]
        out: PathBuf,
        #[arg(long, default_value_t = 40)]
        worlds: usize,
        #[arg(long, default_value_t = 40)]
        frames_per_world: usize,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long, default_value_t = 0.1)]
        val_share: f64,
        #[arg(long, default_value_t = 0.1)]
        test_share: f64,
        /// Share of frames drawn with domain randomization: random viewpoints
        /// from the ground to 120 m, skies, paints, look-alikes, lens defects
        /// and real photos behind the scene (from --backgrounds).
        #[arg(long, default_value_t = 0.0)]
        randomize: f64,
        /// A folder of real tower-free photos (repeatable): backgrounds for
        /// randomized frames, and each also a training image with no tower.
        #[arg(long)]
        backgrounds: Vec<PathBuf>,
    },
}

fn conditions(weather: Weather, seed: u64) -> Conditions {
    match weather {
        Weather::Default => Conditions::default(),
        Weather::Plain => Conditions::plain(),
        Weather::Random => {
            use rand::SeedableRng;
            Conditions::random(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed))
        }
    }
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::World {
            world,
            degrade,
            out,
        } => {
            let mut landmarks = world.world()?.landmarks();
            if let Some(seed) = degrade {
                landmarks = towernav_sim::landmark_world::degraded(&landmarks, seed);
            }
            if out.as_os_str() == "-" {
                towernav_landmark_db::export_csv(&landmarks, std::io::stdout().lock())?;
            } else {
                let file = std::fs::File::create(&out)
                    .with_context(|| format!("creating {}", out.display()))?;
                towernav_landmark_db::export_csv(&landmarks, file)
                    .with_context(|| format!("writing {}", out.display()))?;
                eprintln!("wrote {} towers to {}", landmarks.len(), out.display());
            }
        }
        Command::Flight {
            world,
            plan,
            seed,
            images,
            video,
            calibration,
            gnss_sigma_m,
            gnss_correlation_s,
            gnss_velocity_sigma_mps,
            attitude_sigma_deg,
            weather,
            dataset_every,
            out,
        } => {
            anyhow::ensure!(
                gnss_correlation_s.is_finite() && gnss_correlation_s >= 0.0,
                "--gnss-correlation-s must be 0 or more, got {gnss_correlation_s}"
            );
            anyhow::ensure!(
                attitude_sigma_deg.is_none_or(|s| s.is_finite() && s >= 0.0),
                "--attitude-sigma-deg must be 0 or more"
            );
            anyhow::ensure!(
                gnss_velocity_sigma_mps.is_finite() && gnss_velocity_sigma_mps >= 0.0,
                "--gnss-velocity-sigma-mps must be 0 or more, got {gnss_velocity_sigma_mps}"
            );
            anyhow::ensure!(
                gnss_sigma_m.is_finite() && gnss_sigma_m >= 0.0,
                "--gnss-sigma-m must be 0 or more, got {gnss_sigma_m}"
            );
            let outputs = FlightOutputs {
                images,
                video,
                calibration: calibration.as_deref(),
                gnss: GnssParams {
                    horizontal_sigma_m: gnss_sigma_m,
                    vertical_sigma_m: 2.0 * gnss_sigma_m,
                    correlation_s: gnss_correlation_s,
                    velocity_sigma_mps: gnss_velocity_sigma_mps,
                },
                dataset_every,
            };
            fly(
                &world,
                &plan,
                seed,
                &outputs,
                attitude_sigma_deg,
                weather,
                &out,
            )?
        }
        Command::Render {
            world,
            plan,
            seed,
            time,
            weather,
            no_boxes,
            randomized,
            backgrounds,
            out,
        } => {
            if randomized > 0 {
                cli::contact_sheet::write(&out, randomized, seed, &backgrounds)?;
                eprintln!("wrote {}", out.display());
            } else {
                render(&world, &plan, seed, time, weather, no_boxes, &out)?;
            }
        }
        Command::Dataset {
            out,
            worlds,
            frames_per_world,
            seed,
            val_share,
            test_share,
            randomize,
            backgrounds,
        } => {
            cli::dataset::write_dataset(
                &out,
                &cli::dataset::DatasetOptions {
                    worlds,
                    frames_per_world,
                    seed,
                    val_share,
                    test_share,
                    randomize,
                    backgrounds,
                },
            )?;
            eprintln!("wrote {}", out.join("data.yaml").display());
        }
    }
    Ok(())
}

/// `flight`: fly the plan and write its files (and frames with `images`).
fn fly(
    world: &WorldArg,
    plan: &PlanArg,
    seed: u64,
    outputs: &FlightOutputs<'_>,
    attitude_sigma_deg: Option<f64>,
    weather: Weather,
    out: &std::path::Path,
) -> anyhow::Result<()> {
    let flight_plan = plan.plan()?;
    let mut scenario = Scenario::flying(world.world()?, &flight_plan, seed);
    if let Some(deg) = attitude_sigma_deg {
        scenario.imu.roll_pitch_sigma = deg.to_radians();
        scenario.imu.yaw_sigma = deg.to_radians();
    }
    if let Some(path) = outputs.calibration {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading calibration {}", path.display()))?;
        let calibration = towernav_geometry::Calibration::parse(&text)
            .with_context(|| format!("calibration {}", path.display()))?;
        scenario.camera.intrinsics = calibration.intrinsics;
        scenario.camera.distortion = calibration.distortion;
        if let Some(p) = scenario.camera.uninvertible_pixel() {
            anyhow::bail!(
                "calibration {}: its lens folds the image at pixel ({:.0}, {:.0})",
                path.display(),
                p.x,
                p.y
            );
        }
    }
    tracing::info!(plan = %flight_plan.name, frames = scenario.frame_count(), duration_s = scenario.flight.duration_s(), "flying");
    let replay = ReplaySource::Oracle {
        world: match (&world.world, world.random_world) {
            (Some(path), _) => {
                ReplayWorld::File(std::path::absolute(path).unwrap_or_else(|_| path.clone()))
            }
            (None, Some(seed)) => ReplayWorld::Random(seed),
            (None, None) => ReplayWorld::PaperField,
        },
        flight: plan.spelled(),
    };
    cli::flight_cmd::write_flight(
        &scenario,
        &flight_plan.name,
        out,
        outputs,
        &conditions(weather, seed),
        &replay,
    )?;
    eprintln!(
        "wrote {} frames of {} to {}",
        scenario.frame_count(),
        flight_plan.name,
        out.display()
    );
    Ok(())
}

/// `render`: one frame of the flight at `time`, with its truth boxes unless `no_boxes`.
fn render(
    world: &WorldArg,
    plan: &PlanArg,
    seed: u64,
    time: f64,
    weather: Weather,
    no_boxes: bool,
    out: &std::path::Path,
) -> anyhow::Result<()> {
    let plan = plan.plan()?;
    let scenario = Scenario::flying(world.world()?, &plan, seed);
    let duration = scenario.flight.duration_s();
    anyhow::ensure!(
        (0.0..=duration).contains(&time),
        "--time {time} is outside the flight, which lasts {duration:.1} s"
    );
    let seq = (time * scenario.fps).round() as u64;
    let truth = scenario.truth(seq);
    let renderer = Renderer::new(&scenario.world, scenario.camera, seed);
    let rates = scenario.flight.attitude_rates(truth.time_s);
    let mut image = renderer.render(&truth.pose, &conditions(weather, seed), rates, seed ^ seq);
    if !no_boxes {
        cli::overlay::draw_boxes(&mut image, &truth.boxes);
    }
    image
        .save(out)
        .with_context(|| format!("writing {}", out.display()))?;
    for b in &truth.boxes {
        eprintln!(
            "{:>8} {} h={:6.1} px  d={:6.1} m  occluded {:.2}{}",
            b.tower_id,
            b.tower_type,
            b.bbox.height(),
            b.distance_m,
            b.occluded,
            if b.truncated { "  cut by the edge" } else { "" }
        );
    }
    eprintln!("wrote {}", out.display());
    Ok(())
}
