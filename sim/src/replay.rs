//! The edge daemon's config that replays a simulated flight (`replay.toml`):
//! either the rendered frames read as a real camera, or the same simulated
//! flight again with the oracle standing in for the detector. Text only; the
//! binary writes it, with the paths made absolute.

use std::path::{Path, PathBuf};

use crate::Scenario;

/// The world as the edge's `[source]` names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ReplayWorld {
    PaperField,
    Random(u64),
    /// A landmark CSV or database the world was built from.
    File(PathBuf),
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ReplaySource {
    /// The simulator again: this world, this flight (a preset's name or a
    /// plan file's path), the scenario's seed, the oracle detector.
    Oracle { world: ReplayWorld, flight: String },
    /// The rendered frames and the IMU's attitude log, as a camera would give them.
    Camera {
        images: PathBuf,
        attitude_log: PathBuf,
        /// The lens's calibration file; none: an ideal pinhole by field of view.
        calibration: Option<PathBuf>,
    },
}

impl ReplaySource {
    /// The whole config: `[source]` and what it needs, and the landmarks at `towers`.
    pub fn config_toml(&self, scenario: &Scenario, config: &Path, towers: &Path) -> String {
        let source = match self {
            Self::Oracle { world, flight } => {
                let world = match world {
                    ReplayWorld::PaperField => String::new(),
                    ReplayWorld::Random(seed) => format!("random_world = {seed}\n"),
                    ReplayWorld::File(path) => {
                        format!("world = {:?}\n", path.display().to_string())
                    }
                };
                format!(
                    "[source]\nkind = \"sim\"\n{world}flight = {flight:?}\nseed = {seed}\n\n\
                     [detector]\nkind = \"oracle\"\n",
                    seed = scenario.seed,
                )
            }
            Self::Camera {
                images,
                attitude_log,
                calibration,
            } => {
                let takeoff = scenario.world.datum.to_geodetic(&scenario.start_in_world());
                let k = &scenario.camera.intrinsics;
                let camera = match calibration {
                    Some(path) => format!("calibration = {:?}", path.display().to_string()),
                    None => format!(
                        "hfov_deg = {:.4}",
                        (2.0 * (f64::from(k.width) / (2.0 * k.fx)).atan()).to_degrees()
                    ),
                };
                format!(
                    "[source]\nkind = \"images\"\npath = {img:?}\nfps = {fps}\nwidth = {w}\nheight = {h}\n\n\
                     [camera]\n{camera}\n\n\
                     [attitude]\nkind = \"csv\"\npath = {att:?}\n\n\
                     [pipeline]\ntakeoff = [{lat:.9}, {lon:.9}, {alt:.3}]\n",
                    img = images.display().to_string(),
                    fps = scenario.fps,
                    w = k.width,
                    h = k.height,
                    att = attitude_log.display().to_string(),
                    lat = takeoff.lat_deg,
                    lon = takeoff.lon_deg,
                    alt = takeoff.height_m,
                )
            }
        };
        format!(
            "# Replays this flight through the edge daemon:\n\
             #   towernav-edge run --config {config}\n\
             {source}\n[landmarks]\nfile = {towers:?}\n",
            config = config.display(),
            towers = towers.display().to_string(),
        )
    }
}
