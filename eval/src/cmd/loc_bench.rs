//! `towernav-edge bench-localization`: localization over random worlds and
//! turning flights, with random weather, the oracle and a YOLO detector on
//! the rendered frames, every frame through the pipeline (tracker, identity,
//! localizer, filter) as the daemon runs it, scored against truth.

use std::path::{Path, PathBuf};

use anyhow::Context;
use comfy_table::Table;
use nalgebra::Vector2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Distribution;
use serde::Serialize;
use towernav_core::landmarks::LandmarkMap;
use towernav_core::localizer::{Method, Usable};
use towernav_core::pipeline::{Pipeline, PipelineConfig};
use towernav_geometry::PixelBox;
use towernav_onnx::{DetectorOptions, YoloDetector};
use towernav_sim::world::WorldParams;
use towernav_sim::{Barometer, BarometerParams, Conditions, Scenario, World};

use super::loc_gaps::{Gaps, table as gaps_table};
use crate::edge_precision::robust_sigma;
use crate::gnss_score::TWO_SIGMA_CHI2;
use crate::mot_metrics::{MotAccumulator, tower_under};
use crate::progress::bar;
use crate::sim_eval::error_stats;
use crate::tracking_eval::{add_frame, pipeline_hypotheses};

pub struct LocBenchOptions {
    pub worlds: u64,
    /// World `i` is drawn from `seed + i` (tests and datasets use others).
    pub seed: u64,
    /// YOLO model and type classifier; `None`: the oracle only.
    pub model: Option<(PathBuf, Option<PathBuf>, DetectorOptions)>,
    /// The localizer's box-edge spread for the YOLO runs, pixels (`None`:
    /// the pipeline's default).
    pub edge_sigma_px: Option<f64>,
    /// The share of the box height that adds to it for the YOLO runs
    /// (`None`: the pipeline's default).
    pub edge_sigma_share: Option<f64>,
    /// The share of the box height within which a box's end near the
    /// border is taken as cut, for the YOLO runs (`None`: the pipeline's).
    pub cut_margin_share: Option<f64>,
    /// The edge spread of a cut box, times a whole one's, for the YOLO runs
    /// (`None`: the pipeline's).
    pub cut_sigma_scale: Option<f64>,
    /// The published covariance, times the filter's, for the YOLO runs
    /// (`None`: unscaled).
    pub covariance_scale: Option<f64>,
    /// The filter publishes an estimate only while its horizontal 1-sigma
    /// is within this, metres, in both runs (`None`: the filter's default).
    pub max_report_sigma_m: Option<f64>,
    /// How long the filter predicts without a fix before it is lost,
    /// seconds, in both runs (`None`: the filter's default).
    pub max_coast_s: Option<f64>,
    /// Also fuse a velocity, as a VIO or optical-flow estimator would give
    /// it: the truth's plus white noise of this 1-sigma per axis, m/s.
    pub velocity_sigma_mps: Option<f64>,
    /// Fly without a barometer (the localizer then has no height to lean on).
    pub no_barometer: bool,
    /// The per-frame estimator: ours, or the paper's for comparison.
    pub method: Method,
    /// Turn each frame by the IMU's roll before the detector, so towers
    /// stand upright in what it sees.
    pub upright: bool,
}

/// How one flight is flown besides its detector.
#[derive(Debug, Clone, Copy, Default)]
pub struct FlyOptions {
    /// The localizer's box-edge spread, pixels (`None`: the pipeline's default).
    pub edge_sigma_px: Option<f64>,
    /// The share of the box height that adds to it (`None`: the pipeline's default).
    pub edge_sigma_share: Option<f64>,
    /// How near the border a box's end is taken as cut, as a share of its
    /// height (`None`: the pipeline's default).
    pub cut_margin_share: Option<f64>,
    /// The edge spread of a cut box, times a whole one's (`None`: the
    /// pipeline's default).
    pub cut_sigma_scale: Option<f64>,
    /// The published covariance, times the filter's (`None`: unscaled).
    pub covariance_scale: Option<f64>,
    /// The filter's bound on a published estimate's horizontal 1-sigma,
    /// metres (`None`: the filter's default).
    pub max_report_sigma_m: Option<f64>,
    /// How long the filter predicts without a fix before it is lost, seconds
    /// (`None`: the filter's default).
    pub max_coast_s: Option<f64>,
    /// A simulated outside velocity's 1-sigma per axis, m/s (`None`: none).
    pub velocity_sigma_mps: Option<f64>,
    /// A simulated barometer; `None`: none.
    pub barometer: Option<BarometerParams>,
    /// The per-frame estimator (ours unless the paper's is asked for).
    pub method: Method,
    /// Turn frames upright by the IMU's roll before the detector.
    pub upright: bool,
}

/// One flight with one detector.
#[derive(Debug, Clone, Default, Serialize)]
pub struct BenchRow {
    pub world_seed: u64,
    pub detector: String,
    pub frames: usize,
    pub flight_s: f64,
    pub rms_m: f64,
    pub median_m: f64,
    pub p95_m: f64,
    pub max_m: f64,
    pub within_5m: f64,
    /// Share of frames with an estimate.
    pub estimate_share: f64,
    /// Share of errors inside the reported 2-sigma ellipse (95 % if honest).
    pub two_sigma_coverage: f64,
    /// Of bound track-frames, the share on their true tower.
    pub identity: f64,
    /// Share of frames with a tower in view that gave a fix, level (roll
    /// under 3 degrees) and banked (over 10 degrees): (frames, share).
    pub fix_rate_level: (usize, f64),
    pub fix_rate_banked: (usize, f64),
    /// Robust spread (1.4826 MAD) of the top and bottom edges of the
    /// detector's boxes against truth, for whole towers over 40 px matched
    /// at IoU 0.5, pixels.
    pub edge_error_px: Option<(f64, f64)>,
    /// The same spread of each edge's error as a share of the true box's
    /// height: what `detector.edge_sigma_share` stands for.
    pub edge_error_share: Option<(f64, f64)>,
    /// The same spread, as a share of the true height, of the box's height
    /// (bottom minus top) and of its middle row. Edges that err together
    /// leave the height, which gives the range, better than either edge.
    pub height_middle_error_share: Option<(f64, f64)>,
    /// The same spread of the box's centre column, as a share of the true
    /// box's width: what the share stands for on the box's sides.
    pub centre_error_share: Option<f64>,
    /// Every frame, for a closer look (written as CSV, not in the JSON).
    #[serde(skip)]
    pub per_frame: Vec<FrameRow>,
}

/// One frame of one flight: what was in view, what the pipeline made of it.
#[derive(Debug, Clone, Default)]
pub struct FrameRow {
    pub time_s: f64,
    pub roll_deg: f64,
    /// Towers the oracle must see (tall enough, not hidden).
    pub in_view: usize,
    pub detections: usize,
    /// Of the towers in view, those with a box on them (IoU 0.3).
    pub detected: usize,
    pub tracks: usize,
    pub bound: usize,
    /// Bound boxes the frame cuts so that fewer than two of their centre
    /// column, top and foot rows are left: too little for a one-tower fix.
    pub bound_cut: usize,
    /// Tracks whose binding stands but whose box was left out of this frame
    /// (it fits a neighbouring tower about as well).
    pub held: usize,
    /// Bound tracks on the wrong tower.
    pub wrong: usize,
    pub fix: bool,
    pub fix_towers: usize,
    pub verdict: String,
    /// The filter was running (had a state to predict) as the frame came.
    pub filter_running: bool,
    /// Horizontal error of the published estimate, and its NEES (2 DOF).
    pub error_m: Option<f64>,
    pub nees: Option<f64>,
    pub sigma_m: Option<f64>,
    pub coast_s: Option<f64>,
    /// This frame's own fix: its horizontal error, NEES and 1-sigma.
    pub fix_error_m: Option<f64>,
    pub fix_nees: Option<f64>,
    pub fix_sigma_m: Option<f64>,
    /// The fix's height error and its 1-sigma.
    pub fix_up_error_m: Option<f64>,
    pub fix_up_sigma_m: Option<f64>,
}

impl FrameRow {
    pub const HEADER: &str = "time_s,roll_deg,in_view,detections,detected,tracks,bound,bound_cut,held,wrong,fix,fix_towers,verdict,filter_running,error_m,nees,sigma_m,coast_s,fix_error_m,fix_nees,fix_sigma_m,fix_up_error_m,fix_up_sigma_m";

    fn csv(&self) -> String {
        let opt = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v:.3}"));
        format!(
            "{:.3},{:.2},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            self.time_s,
            self.roll_deg,
            self.in_view,
            self.detections,
            self.detected,
            self.tracks,
            self.bound,
            self.bound_cut,
            self.held,
            self.wrong,
            u8::from(self.fix),
            self.fix_towers,
            self.verdict,
            u8::from(self.filter_running),
            opt(self.error_m),
            opt(self.nees),
            opt(self.sigma_m),
            opt(self.coast_s),
            opt(self.fix_error_m),
            opt(self.fix_nees),
            opt(self.fix_sigma_m),
            opt(self.fix_up_error_m),
            opt(self.fix_up_sigma_m),
        )
    }
}

/// World `seed`'s flight: a random world, a turning plan beside its lines
/// and random weather, all drawn from the seed.
pub fn scenario(seed: u64) -> anyhow::Result<(Scenario, Conditions)> {
    let world = World::random(seed, &WorldParams::default());
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7u64.rotate_left(40));
    let plan = towernav_sim::waypoints::random_turning(&world, &mut rng)
        .with_context(|| format!("world {seed} has no line to fly beside"))?;
    let conditions = Conditions::random(&mut rng);
    Ok((Scenario::flying(world, &plan, seed), conditions))
}

/// Flies `scenario` through the pipeline; with `detector`, on its boxes in
/// the frames rendered under `conditions`, else on the oracle's.
pub fn fly(
    scenario: &Scenario,
    conditions: &Conditions,
    mut detector: Option<&mut YoloDetector>,
    options: &FlyOptions,
    name: &str,
    tick: &dyn Fn(),
) -> anyhow::Result<BenchRow> {
    let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
    let mut config = PipelineConfig::new(scenario.camera, scenario.start_in_world());
    if let Some(sigma) = options.edge_sigma_px {
        config.localizer.edge_sigma_px = sigma;
    }
    if let Some(share) = options.edge_sigma_share {
        config.localizer.edge_sigma_share = share;
    }
    if let Some(share) = options.cut_margin_share {
        config.localizer.cut_margin_share = share;
    }
    if let Some(scale) = options.cut_sigma_scale {
        config.localizer.cut_sigma_scale = scale;
    }
    if let (Some(sigma), Some(filter)) = (options.max_report_sigma_m, config.filter.as_mut()) {
        filter.max_report_sigma_m = sigma;
    }
    if let (Some(coast), Some(filter)) = (options.max_coast_s, config.filter.as_mut()) {
        filter.max_coast_s = coast;
    }
    if let (Some(scale), Some(filter)) = (options.covariance_scale, config.filter.as_mut()) {
        filter.report_covariance_scale = scale;
    }
    config.method = options.method;
    let mut velocity_noise = ChaCha8Rng::seed_from_u64(scenario.seed ^ 0x005e_ed0f_u64);
    let velocity_error = options
        .velocity_sigma_mps
        .map(|sigma| rand_distr::Normal::new(0.0, sigma).map(|n| (sigma, n)))
        .transpose()?;
    let mut barometer = options
        .barometer
        .map(|b| Barometer::new(b, scenario.seed, scenario.start_in_world().z));
    let mut previous_truth: Option<(f64, nalgebra::Point3<f64>)> = None;
    let mut pipeline = Pipeline::new(config, map.clone());
    let (mut tops, mut bottoms) = (Vec::new(), Vec::new());
    let (mut top_shares, mut bottom_shares) = (Vec::new(), Vec::new());
    let (mut height_shares, mut middle_shares) = (Vec::new(), Vec::new());
    let mut centre_shares = Vec::new();
    // (frames with a tower in view, of them with a fix), level and banked.
    let (mut level, mut banked) = ((0usize, 0usize), (0usize, 0usize));
    let renderer = detector.as_ref().map(|_| scenario.renderer());
    let mut buffers = renderer.as_ref().map(|r| r.buffers());
    let mut identity = MotAccumulator::default();
    let (mut errors, mut inside, mut frames) = (Vec::new(), 0usize, 0usize);
    let mut per_frame = Vec::new();
    for (truth, mut frame) in scenario.frames() {
        if let (Some(d), Some(r), Some(b)) = (detector.as_deref_mut(), &renderer, &mut buffers) {
            scenario.render_into(r, b, &truth, conditions);
            let turn = if options.upright {
                -scenario.camera.lean_of_vertical(&frame.imu_attitude)
            } else {
                0.0
            };
            frame.detections = d
                .detect_turned(&b.image, frame.seq, turn)
                .with_context(|| format!("world {}, frame {}", scenario.seed, frame.seq))?;
            for t in truth
                .boxes
                .iter()
                .filter(|t| !t.truncated && t.bbox.height() > 40.0)
            {
                if let Some(d) = frame.detections.iter().find(|d| d.bbox.iou(&t.bbox) >= 0.5) {
                    let (top, bottom) = (d.bbox.top - t.bbox.top, d.bbox.bottom - t.bbox.bottom);
                    tops.push(top);
                    bottoms.push(bottom);
                    top_shares.push(top / t.bbox.height());
                    bottom_shares.push(bottom / t.bbox.height());
                    height_shares.push((bottom - top) / t.bbox.height());
                    middle_shares.push(0.5 * (top + bottom) / t.bbox.height());
                    centre_shares.push((d.bbox.center_x() - t.bbox.center_x()) / t.bbox.width());
                }
            }
        }
        let detections = frame.detections.len();
        let here = truth.pose.position_in_world;
        if let (Some((sigma, noise)), Some((t0, p0))) = (velocity_error, previous_truth)
            && frame.time_s > t0
        {
            let v = (here - p0) / (frame.time_s - t0)
                + nalgebra::Vector3::from_fn(|_, _| noise.sample(&mut velocity_noise));
            let c = nalgebra::Matrix3::identity() * sigma * sigma;
            pipeline.fuse_velocity(frame.time_s, &v, &c);
        }
        previous_truth = Some((frame.time_s, here));
        if let Some(b) = barometer.as_mut() {
            pipeline.barometric_height(frame.time_s, b.read(here.z));
        }
        let filter_running = pipeline.filter_running(frame.time_s);
        let demanded: Vec<&PixelBox> = truth
            .boxes
            .iter()
            .filter(|b| scenario.demanded(b))
            .map(|b| &b.bbox)
            .collect();
        let detected = demanded
            .iter()
            .filter(|t| frame.detections.iter().any(|d| d.bbox.iou(t) >= 0.3))
            .count();
        let out = pipeline.process(&frame);
        let mut row = FrameRow {
            time_s: frame.time_s,
            roll_deg: truth.pose.attitude.roll.to_degrees(),
            in_view: demanded.len(),
            detections,
            detected,
            tracks: out.tracks.len(),
            bound: out.tracks.iter().filter(|t| t.tower.is_some()).count(),
            bound_cut: out
                .tracks
                .iter()
                .filter(|t| t.tower.is_some() && too_cut(&t.bbox, &pipeline))
                .count(),
            held: out
                .tracks
                .iter()
                .filter(|t| t.tower.is_none() && t.held.is_some())
                .count(),
            wrong: wrong_bindings(&out, &truth, &map),
            fix: out.fix.is_some(),
            fix_towers: out.fix.as_ref().map_or(0, |f| f.towers_used.len()),
            verdict: format!("{:?}", out.verdict),
            filter_running,
            ..FrameRow::default()
        };
        if !demanded.is_empty() {
            let roll = truth.pose.attitude.roll.abs().to_degrees();
            let bin = if roll < 3.0 {
                Some(&mut level)
            } else if roll > 10.0 {
                Some(&mut banked)
            } else {
                None
            };
            if let Some((seen, fixed)) = bin {
                *seen += 1;
                *fixed += usize::from(out.fix.is_some());
            }
        }
        add_frame(
            &mut identity,
            scenario,
            &truth,
            &pipeline_hypotheses(&out, &map),
        );
        frames += 1;
        if let Some(f) = &out.fix {
            let (error, nees, sigma) = horizontal_error(
                &f.position_in_world,
                &f.covariance,
                &truth.pose.position_in_world,
            );
            (row.fix_error_m, row.fix_nees, row.fix_sigma_m) = (Some(error), nees, Some(sigma));
            row.fix_up_error_m = Some(f.position_in_world.z - truth.pose.position_in_world.z);
            row.fix_up_sigma_m = Some(f.covariance[(2, 2)].max(0.0).sqrt());
        }
        if let Some(e) = &out.estimate {
            let (error, nees, sigma) = horizontal_error(
                &e.position_in_world,
                &e.covariance,
                &truth.pose.position_in_world,
            );
            if nees.is_some_and(|n| n <= TWO_SIGMA_CHI2) {
                inside += 1;
            }
            errors.push(error);
            (row.error_m, row.nees, row.sigma_m) = (Some(error), nees, Some(sigma));
            row.coast_s = Some(e.coast_s);
        }
        per_frame.push(row);
        tick();
    }
    let stats = error_stats(&errors);
    Ok(BenchRow {
        world_seed: scenario.seed,
        detector: name.to_owned(),
        frames,
        flight_s: frames as f64 / scenario.fps,
        rms_m: stats.rms,
        median_m: stats.median,
        p95_m: stats.p95,
        max_m: stats.max,
        within_5m: stats.within_5m,
        estimate_share: errors.len() as f64 / frames.max(1) as f64,
        two_sigma_coverage: inside as f64 / errors.len().max(1) as f64,
        identity: identity.finish().binding_accuracy,
        fix_rate_level: (level.0, level.1 as f64 / level.0.max(1) as f64),
        fix_rate_banked: (banked.0, banked.1 as f64 / banked.0.max(1) as f64),
        edge_error_px: robust_sigma(&mut tops).zip(robust_sigma(&mut bottoms)),
        edge_error_share: robust_sigma(&mut top_shares).zip(robust_sigma(&mut bottom_shares)),
        height_middle_error_share: robust_sigma(&mut height_shares)
            .zip(robust_sigma(&mut middle_shares)),
        centre_error_share: robust_sigma(&mut centre_shares),
        per_frame,
    })
}

/// Horizontal error of `position` against `truth`, its NEES under
/// `covariance` (none when singular), and the ellipse's major 1-sigma.
fn horizontal_error(
    position: &nalgebra::Point3<f64>,
    covariance: &nalgebra::Matrix4<f64>,
    truth: &nalgebra::Point3<f64>,
) -> (f64, Option<f64>, f64) {
    let d = Vector2::new(position.x - truth.x, position.y - truth.y);
    let c = covariance.fixed_view::<2, 2>(0, 0).into_owned();
    let nees = c.try_inverse().map(|ci| (d.transpose() * ci * d)[(0, 0)]);
    (d.norm(), nees, towernav_core::filter::horizontal_sigma(&c))
}

/// Whether the frame cuts `bbox` (in the real image) so that fewer than two
/// of its centre column, top and foot rows are usable, by the localizer's rule.
fn too_cut(bbox: &PixelBox, pipeline: &Pipeline) -> bool {
    let config = pipeline.config();
    Usable::of_box(bbox, &config.camera.intrinsics, &config.localizer).count() < 2
}

/// Bound tracks whose box lies on another tower than their own.
fn wrong_bindings(
    out: &towernav_core::pipeline::FrameOutput,
    truth: &towernav_sim::FrameTruth,
    map: &LandmarkMap,
) -> usize {
    let boxes: Vec<(String, PixelBox)> = truth
        .boxes
        .iter()
        .map(|b| (b.tower_id.clone(), b.bbox))
        .collect();
    out.tracks
        .iter()
        .filter_map(|t| Some((t, &map.towers.get(t.tower?)?.id)))
        .filter(|(t, id)| tower_under(&boxes, &t.bbox).is_some_and(|under| under != *id))
        .count()
}

/// Every world with the oracle and, when given, the YOLO detector.
pub fn bench(options: &LocBenchOptions) -> anyhow::Result<Vec<BenchRow>> {
    let mut detector = match &options.model {
        Some((model, types, detector_options)) => Some(YoloDetector::load_with_types(
            model,
            types.as_deref(),
            detector_options,
        )?),
        None => None,
    };
    let flights: Vec<(Scenario, Conditions)> = (0..options.worlds)
        .map(|i| scenario(options.seed + i))
        .collect::<anyhow::Result<_>>()?;
    let passes = if detector.is_some() { 2 } else { 1 };
    let total: usize = flights.iter().map(|(s, _)| s.frame_count() as usize).sum();
    let progress = bar((total * passes) as u64, "bench-localization");
    let tick = || progress.inc(1);
    let mut rows = Vec::new();
    for (scenario, conditions) in &flights {
        let barometer = (!options.no_barometer).then(BarometerParams::default);
        let oracle = FlyOptions {
            edge_sigma_px: None,
            edge_sigma_share: None,
            cut_margin_share: None,
            cut_sigma_scale: None,
            covariance_scale: None,
            max_report_sigma_m: options.max_report_sigma_m,
            max_coast_s: options.max_coast_s,
            velocity_sigma_mps: options.velocity_sigma_mps,
            barometer,
            method: options.method,
            upright: false,
        };
        rows.push(fly(scenario, conditions, None, &oracle, "oracle", &tick)?);
        if let Some(d) = detector.as_mut() {
            let name = d
                .info()
                .path
                .file_name()
                .map_or_else(|| "yolo".to_owned(), |n| n.to_string_lossy().into_owned());
            let yolo = FlyOptions {
                edge_sigma_px: options.edge_sigma_px,
                edge_sigma_share: options.edge_sigma_share,
                cut_margin_share: options.cut_margin_share,
                cut_sigma_scale: options.cut_sigma_scale,
                covariance_scale: options.covariance_scale,
                max_report_sigma_m: options.max_report_sigma_m,
                max_coast_s: options.max_coast_s,
                velocity_sigma_mps: options.velocity_sigma_mps,
                barometer,
                method: options.method,
                upright: options.upright,
            };
            rows.push(fly(scenario, conditions, Some(d), &yolo, &name, &tick)?);
        }
    }
    progress.finish_and_clear();
    Ok(rows)
}

/// The rows, and for each detector all frames pooled (RMS over every frame).
pub fn table(rows: &[BenchRow]) -> Table {
    let mut table = Table::new();
    table.set_header([
        "world",
        "detector",
        "flight",
        "RMS",
        "median",
        "p95",
        "max",
        "within 5 m",
        "estimates",
        "2-sigma coverage",
        "identity",
        "fix rate level / banked",
    ]);
    let mut push = |world: String, r: &BenchRow| {
        table.add_row([
            world,
            r.detector.clone(),
            format!("{:.0} s", r.flight_s),
            format!("{:.2} m", r.rms_m),
            format!("{:.2} m", r.median_m),
            format!("{:.2} m", r.p95_m),
            format!("{:.1} m", r.max_m),
            format!("{:.1} %", 100.0 * r.within_5m),
            format!("{:.1} %", 100.0 * r.estimate_share),
            format!("{:.1} %", 100.0 * r.two_sigma_coverage),
            format!("{:.2} %", 100.0 * r.identity),
            format!(
                "{:.1} % / {:.1} % ({} banked)",
                100.0 * r.fix_rate_level.1,
                100.0 * r.fix_rate_banked.1,
                r.fix_rate_banked.0
            ),
        ]);
    };
    for r in rows {
        push(r.world_seed.to_string(), r);
    }
    let detectors = detector_names(rows);
    for name in detectors {
        push(
            "all".into(),
            &pooled(rows.iter().filter(|r| r.detector == name)),
        );
    }
    table
}

/// The detectors of `rows`, each once.
fn detector_names(rows: &[BenchRow]) -> Vec<&str> {
    let mut names: Vec<&str> = rows.iter().map(|r| r.detector.as_str()).collect();
    names.sort();
    names.dedup();
    names
}

/// Rows of one detector pooled, each weighted by its estimates (or frames).
fn pooled<'a>(rows: impl Iterator<Item = &'a BenchRow>) -> BenchRow {
    let rows: Vec<&BenchRow> = rows.collect();
    let estimates = |r: &BenchRow| r.estimate_share * r.frames as f64;
    let n: f64 = rows.iter().map(|r| estimates(r)).sum::<f64>().max(1.0);
    let frames: usize = rows.iter().map(|r| r.frames).sum();
    let mean =
        |f: &dyn Fn(&BenchRow) -> f64| rows.iter().map(|r| f(r) * estimates(r)).sum::<f64>() / n;
    BenchRow {
        world_seed: 0,
        detector: rows
            .first()
            .map_or_else(String::new, |r| r.detector.clone()),
        frames,
        flight_s: rows.iter().map(|r| r.flight_s).sum(),
        rms_m: mean(&|r| r.rms_m.powi(2)).sqrt(),
        // Medians and p95s do not pool: their estimate-weighted means.
        median_m: mean(&|r| r.median_m),
        p95_m: mean(&|r| r.p95_m),
        max_m: rows.iter().map(|r| r.max_m).fold(0.0, f64::max),
        within_5m: mean(&|r| r.within_5m),
        estimate_share: n / frames.max(1) as f64,
        two_sigma_coverage: mean(&|r| r.two_sigma_coverage),
        identity: rows.iter().map(|r| r.identity).sum::<f64>() / rows.len().max(1) as f64,
        fix_rate_level: pool_rate(rows.iter().map(|r| r.fix_rate_level)),
        fix_rate_banked: pool_rate(rows.iter().map(|r| r.fix_rate_banked)),
        edge_error_px: None,
        edge_error_share: None,
        height_middle_error_share: None,
        centre_error_share: None,
        per_frame: Vec::new(),
    }
}

fn pool_rate(rates: impl Iterator<Item = (usize, f64)>) -> (usize, f64) {
    let (n, fixed) = rates.fold((0usize, 0.0), |(n, f), (m, r)| (n + m, f + r * m as f64));
    (n, fixed / n.max(1) as f64)
}

pub fn write_all(options: &LocBenchOptions, out: &Path) -> anyhow::Result<()> {
    let rows = bench(options)?;
    println!(
        "Localization over {} random worlds (seeds {}..{}), turning flights beside their lines, random weather; every frame through the pipeline, against truth:\n{}",
        options.worlds,
        options.seed,
        options.seed + options.worlds,
        table(&rows)
    );
    for r in &rows {
        if let (Some((top, bottom)), Some((top_share, bottom_share))) =
            (r.edge_error_px, r.edge_error_share)
        {
            println!(
                "world {} {}: box edges against truth (whole towers over 40 px), robust sigma top {top:.2} px, bottom {bottom:.2} px; as a share of the box height top {:.1} %, bottom {:.1} %",
                r.world_seed,
                r.detector,
                100.0 * top_share,
                100.0 * bottom_share
            );
        }
        if let (Some((height, middle)), Some(centre)) =
            (r.height_middle_error_share, r.centre_error_share)
        {
            println!(
                "world {} {}: box height against truth, robust sigma {:.1} % of the height; middle row {:.1} %; centre column {:.1} % of the width",
                r.world_seed,
                r.detector,
                100.0 * height,
                100.0 * middle,
                100.0 * centre
            );
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    for r in &rows {
        let path = out.join(format!("loc-bench-{}-{}.csv", r.world_seed, r.detector));
        let mut text = String::from(FrameRow::HEADER);
        for f in &r.per_frame {
            text.push('\n');
            text.push_str(&f.csv());
        }
        text.push('\n');
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    let detectors = detector_names(&rows);
    let mut gaps = Vec::new();
    for name in detectors {
        let of: Vec<&BenchRow> = rows.iter().filter(|r| r.detector == name).collect();
        let g = Gaps::of(name, &of);
        println!("{}", gaps_table(&g));
        gaps.push(g);
    }
    let path = out.join("loc-gaps.json");
    std::fs::write(&path, serde_json::to_string_pretty(&gaps)?)
        .with_context(|| format!("writing {}", path.display()))?;
    let path = out.join("loc-bench.json");
    std::fs::write(&path, serde_json::to_string_pretty(&rows)?)
        .with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_oracle_localizes_a_turning_flight_and_the_row_adds_up() {
        let (scenario, conditions) = scenario(1000).expect("a flight");
        let row = fly(
            &scenario,
            &conditions,
            None,
            &FlyOptions::default(),
            "oracle",
            &|| {},
        )
        .expect("flown");
        assert_eq!(row.frames, scenario.frame_count() as usize);
        assert!(row.estimate_share > 0.5, "{row:?}");
        assert!(row.rms_m < 10.0, "{row:?}");
        assert!((0.0..=1.0).contains(&row.two_sigma_coverage));
        // A turning flight has level and banked frames with towers in view.
        assert!(
            row.fix_rate_level.0 > 100 && row.fix_rate_banked.0 > 20,
            "{row:?}"
        );
        assert!(row.fix_rate_level.1 > 0.5, "{row:?}");
        let all = pooled([&row, &row].into_iter());
        assert!((all.rms_m - row.rms_m).abs() < 1e-9);
        assert_eq!(all.frames, 2 * row.frames);
    }

    fn oracle_flight(seed: u64, options: &FlyOptions) -> BenchRow {
        let (scenario, conditions) = scenario(seed).expect("a flight");
        fly(&scenario, &conditions, None, options, "oracle", &|| {}).expect("flown")
    }

    fn with_barometer() -> FlyOptions {
        FlyOptions {
            barometer: Some(BarometerParams::default()),
            ..FlyOptions::default()
        }
    }

    /// Chi-square quantile `p` for `k` degrees of freedom (Wilson-Hilferty;
    /// within 0.1 % for k over 50).
    fn chi2_quantile(z: f64, k: f64) -> f64 {
        k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
    }

    /// The reported covariance is what the autopilot weighs the pose by.
    /// Over two turning flights with the oracle: the share of estimates
    /// whose horizontal NEES lies inside the 95 % chi-square bound (2 DOF)
    /// is 90-98 %, and the mean NEES of one estimate a second (errors a
    /// second apart are nearly independent) is under the two-sided 95 %
    /// chi-square bound: the covariance is not overconfident. (It may be
    /// conservative: the filter adds the part of a fix's error that
    /// persists from frame to frame, which no averaging removes.)
    #[test]
    fn the_oracles_covariance_is_consistent_on_two_turning_flights() {
        for seed in [1, 2] {
            let row = oracle_flight(seed, &with_barometer());
            let nees: Vec<f64> = row.per_frame.iter().filter_map(|f| f.nees).collect();
            let inside = nees.iter().filter(|n| **n <= TWO_SIGMA_CHI2).count() as f64;
            let coverage = inside / nees.len() as f64;
            assert!(
                (0.90..=0.98).contains(&coverage),
                "world {seed}: {:.1} % inside the 95 % bound",
                100.0 * coverage
            );
            let fps = (row.frames as f64 / row.flight_s).round() as usize;
            let samples: Vec<f64> = row
                .per_frame
                .iter()
                .step_by(fps)
                .filter_map(|f| f.nees)
                .collect();
            let n = samples.len() as f64;
            assert!(n > 40.0, "world {seed}: {n} samples");
            let mean = samples.iter().sum::<f64>() / n;
            let upper = chi2_quantile(1.96, 2.0 * n) / n;
            assert!(
                mean <= upper,
                "world {seed}: mean NEES {mean:.2} over {n} samples, bound {upper:.2}"
            );
        }
    }

    /// Banking turns the towers in the image; with the oracle's boxes the
    /// share of frames with a tower in view that give a fix stays, banked
    /// over 10 degrees, at 95 % or more of level flight's (four flights pooled).
    #[test]
    fn the_oracle_fixes_banked_frames_as_often_as_level_ones() {
        let rows: Vec<BenchRow> = (1..=4)
            .map(|seed| oracle_flight(seed, &with_barometer()))
            .collect();
        let level = pool_rate(rows.iter().map(|r| r.fix_rate_level));
        let banked = pool_rate(rows.iter().map(|r| r.fix_rate_banked));
        assert!(banked.0 > 200, "{banked:?} banked frames");
        assert!(
            banked.1 >= 0.95 * level.1,
            "banked {:.1} % against level {:.1} %",
            100.0 * banked.1,
            100.0 * level.1
        );
    }

    /// The paper's method takes its height from the barometer, not from its
    /// boxes; without one the height is marked unknown.
    #[test]
    fn the_papers_height_is_the_barometers_or_unknown() {
        let paper = |barometer| FlyOptions {
            barometer,
            method: Method::Paper,
            ..FlyOptions::default()
        };
        let row = oracle_flight(3, &paper(Some(BarometerParams::default())));
        let heights: Vec<(f64, f64)> = row
            .per_frame
            .iter()
            .filter_map(|f| f.fix_up_error_m.zip(f.fix_up_sigma_m))
            .collect();
        assert!(heights.len() > 500, "{} fixes", heights.len());
        for (error, sigma) in &heights {
            assert!(
                error.abs() < 5.0 && *sigma < 5.0,
                "{error} m, sigma {sigma} m"
            );
        }
        let row = oracle_flight(3, &paper(None));
        let unknown = towernav_core::localizer::Height::UNKNOWN_SIGMA_M;
        assert!(
            row.per_frame
                .iter()
                .filter_map(|f| f.fix_up_sigma_m)
                .all(|sigma| sigma >= unknown - 1e-6)
        );
    }
}
