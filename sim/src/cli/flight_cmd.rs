//! `towernav-sim flight`: fly one plan and write its trajectory, truth, MOT
//! ground truth and, optionally, every rendered frame.

use std::path::Path;

use anyhow::Context;
use towernav_geometry::Attitude;
use towernav_sim::replay::ReplaySource;
use towernav_sim::{Conditions, FrameTruth, Renderer, Scenario};

use crate::cli::flight_dataset::FlightDataset;
use crate::cli::mot;
use crate::cli::progress::progress;
use crate::cli::tlog::{LogRow, TlogWriter};
use crate::cli::video::VideoWriter;
use towernav_sim::gnss::GnssParams;

/// What `towernav-sim flight` writes beside its CSV files.
pub struct FlightOutputs<'a> {
    /// Every frame to `mot/<name>/img1/*.jpg`; the replay reads them as a camera.
    pub images: bool,
    /// Every frame to `flight.mp4` (H.264), as a UAV's camera records.
    pub video: bool,
    /// The calibration file the camera was built from, copied beside the
    /// flight for its replay.
    pub calibration: Option<&'a Path>,
    /// The GNSS error of `flight.tlog`'s positions.
    pub gnss: GnssParams,
    /// Every Nth frame with its truth boxes to `dataset/`, a YOLO dataset.
    pub dataset_every: Option<u64>,
}

/// Write `trajectory.csv`, `truth.csv`, `mot/<name>/`, `attitude.csv` (the
/// IMU as an autopilot logs it), `flight.tlog` (the same attitude and noisy
/// GNSS on the autopilot's clock), `towers.csv` and `replay.toml`
/// (`towernav-edge run --config replay.toml`). With `images`, every frame goes
/// to `mot/<name>/img1/*.jpg` and the replay reads them as a real camera;
/// without, it flies the same simulated flight with the oracle detector.
pub fn write_flight(
    scenario: &Scenario,
    name: &str,
    out: &Path,
    outputs: &FlightOutputs<'_>,
    conditions: &Conditions,
    replay: &ReplaySource,
) -> anyhow::Result<()> {
    let images = outputs.images;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut traj = csv_file(&out.join("trajectory.csv"))?;
    let mut truth_csv = csv_file(&out.join("truth.csv"))?;
    traj.write_record([
        "seq",
        "time_s",
        "east_m",
        "north_m",
        "up_m",
        "roll_rad",
        "pitch_rad",
        "yaw_rad",
        "imu_roll_rad",
        "imu_pitch_rad",
        "imu_yaw_rad",
    ])?;
    truth_csv.write_record([
        "seq",
        "tower_id",
        "type",
        "left",
        "top",
        "right",
        "bottom",
        "truncated",
        "occluded",
        "distance_m",
    ])?;
    let seq_dir = out.join("mot").join(name);
    let img_dir = seq_dir.join("img1");
    if images {
        std::fs::create_dir_all(&img_dir)
            .with_context(|| format!("creating {}", img_dir.display()))?;
    }
    let k = scenario.camera.intrinsics;
    let mut dataset = outputs
        .dataset_every
        .map(|every| FlightDataset::create(out, every))
        .transpose()?;
    let renderer = (images || outputs.video || dataset.is_some())
        .then(|| Renderer::new(&scenario.world, scenario.camera, scenario.seed));
    let mut buffers = renderer.as_ref().map(Renderer::buffers);
    let mut video = outputs
        .video
        .then(|| VideoWriter::create(&out.join("flight.mp4"), k.width, k.height, scenario.fps))
        .transpose()?;
    let mut tlog = TlogWriter::create(
        &out.join("flight.tlog"),
        scenario.world.datum,
        outputs.gnss,
        scenario.seed,
    )?;
    let attitude_path = out.join("attitude.csv");
    let mut attitude_csv = csv_file(&attitude_path)?;
    attitude_csv.write_record(["time_s", "roll_deg", "pitch_deg", "heading_deg"])?;
    let bar = progress(scenario.frame_count(), "flight");
    let mut truths = Vec::with_capacity(scenario.frame_count() as usize);
    for (truth, input) in scenario.frames() {
        let p = &truth.pose;
        write_rows(
            &truth,
            &input.imu_attitude,
            &mut traj,
            &mut attitude_csv,
            &mut truth_csv,
        )?;
        tlog.write(&LogRow {
            time_s: truth.time_s,
            attitude: input.imu_attitude,
            position_in_world: p.position_in_world,
        })?;
        let into_dataset = dataset.as_ref().is_some_and(|d| d.wants(truth.seq));
        let drawn = images || outputs.video || into_dataset;
        if let (Some(renderer), Some(buffers), true) = (&renderer, &mut buffers, drawn) {
            let rates = scenario.flight.attitude_rates(truth.time_s);
            renderer.render_into(buffers, p, conditions, rates, scenario.seed ^ truth.seq);
            if images {
                let path = img_dir.join(format!("{:06}.jpg", truth.seq + 1));
                buffers
                    .image
                    .save(&path)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            if let Some(video) = &mut video {
                video.push(&buffers.image)?;
            }
            if let (Some(dataset), true) = (&mut dataset, into_dataset) {
                dataset.push(&truth, &buffers.image)?;
            }
        }
        truths.push(truth);
        bar.inc(1);
    }
    bar.finish();
    traj.flush()?;
    truth_csv.flush()?;
    attitude_csv.flush()?;
    tlog.finish()?;
    if let Some(video) = video {
        video.finish()?;
    }
    if let Some(dataset) = dataset {
        let (frames, boxes) = dataset.finish()?;
        tracing::info!(frames, boxes, dir = %out.join("dataset").display(), "wrote the flight's truth dataset");
    }
    let towers = write_towers(scenario, out)?;
    let calibration = outputs
        .calibration
        .map(|from| copy_calibration(from, out))
        .transpose()?;
    let camera = ReplaySource::Camera {
        images: absolute(&img_dir),
        attitude_log: absolute(&attitude_path),
        calibration,
    };
    let source = if images { &camera } else { replay };
    write_replay_config(scenario, out, &towers, source)?;
    mot::write_sequence(&seq_dir, name, scenario, &truths)
}

/// The camera's calibration file beside the flight, as `camera.<ext>`.
fn copy_calibration(from: &Path, out: &Path) -> anyhow::Result<std::path::PathBuf> {
    let ext = from.extension().and_then(|e| e.to_str()).unwrap_or("yaml");
    let to = out.join(format!("camera.{ext}"));
    std::fs::copy(from, &to)
        .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
    Ok(absolute(&to))
}

/// The world's towers as the landmark file the replay localizes against.
fn write_towers(scenario: &Scenario, out: &Path) -> anyhow::Result<std::path::PathBuf> {
    let towers = out.join("towers.csv");
    let file =
        std::fs::File::create(&towers).with_context(|| format!("creating {}", towers.display()))?;
    towernav_landmark_db::export_csv(&scenario.world.landmarks(), file)
        .with_context(|| format!("writing {}", towers.display()))?;
    Ok(towers)
}

fn absolute(p: &Path) -> std::path::PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// `replay.toml` beside the flight's files, every path in it absolute.
fn write_replay_config(
    scenario: &Scenario,
    out: &Path,
    towers: &Path,
    source: &ReplaySource,
) -> anyhow::Result<()> {
    let path = out.join("replay.toml");
    let text = source.config_toml(scenario, &absolute(&path), &absolute(towers));
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))
}

fn csv_file(path: &Path) -> anyhow::Result<csv::Writer<std::fs::File>> {
    csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))
}

/// One frame's rows: the trajectory (truth and IMU), the attitude log as a
/// camera replay reads it, and the truth boxes.
fn write_rows(
    truth: &FrameTruth,
    imu: &Attitude,
    traj: &mut csv::Writer<std::fs::File>,
    attitude_csv: &mut csv::Writer<std::fs::File>,
    truth_csv: &mut csv::Writer<std::fs::File>,
) -> anyhow::Result<()> {
    let p = &truth.pose;
    let a = &p.attitude;
    let values = [
        truth.time_s,
        p.position_in_world.x,
        p.position_in_world.y,
        p.position_in_world.z,
        a.roll,
        a.pitch,
        a.yaw,
        imu.roll,
        imu.pitch,
        imu.yaw,
    ];
    let mut row = vec![truth.seq.to_string()];
    row.extend(values.iter().map(|v| format!("{v:.6}")));
    traj.write_record(&row)?;
    attitude_csv.write_record([
        format!("{:.6}", truth.time_s),
        format!("{:.4}", imu.roll.to_degrees()),
        format!("{:.4}", imu.pitch.to_degrees()),
        format!("{:.4}", imu.yaw_from_north().to_degrees().rem_euclid(360.0)),
    ])?;
    for b in &truth.boxes {
        truth_csv.write_record([
            truth.seq.to_string(),
            b.tower_id.clone(),
            b.tower_type.to_string(),
            format!("{:.2}", b.bbox.left),
            format!("{:.2}", b.bbox.top),
            format!("{:.2}", b.bbox.right),
            format!("{:.2}", b.bbox.bottom),
            b.truncated.to_string(),
            format!("{:.3}", b.occluded),
            format!("{:.2}", b.distance_m),
        ])?;
    }
    Ok(())
}
