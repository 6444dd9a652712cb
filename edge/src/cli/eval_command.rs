//! The eval commands (demo build): the paper's tables reproduced on the
//! simulator, and the detector's on rendered or real images.

use anyhow::Context;
use std::path::PathBuf;

use clap::Subcommand;
use towernav_eval::cmd::detector_eval::DetectorEvalOptions;
use towernav_eval::cmd::real_eval::RealEvalOptions;

use crate::cli::detector_args::DetectorArgs;

#[derive(Subcommand)]
pub enum EvalCommand {
    /// The paper's Table 2: SORT, ByteTrack-style and ours on the paper's paths and
    /// random fields (oracle detector), with MOT-challenge result files.
    #[command(name = "eval-tracking")]
    Tracking {
        /// Folder for the MOT-challenge files.
        #[arg(long, default_value = "target/tracking-eval")]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// An ONNX re-identification model ([N, 3, H, W] crops in, [N, D] out) for
        /// DeepSORT's appearance; default: the Rust crop descriptor.
        #[arg(long)]
        reid: Option<PathBuf>,
    },
    /// The paper's Table 1 for a YOLO model: precision, recall, mAP50, mAP50-95 per
    /// class, recall by box height, and latency, on held-out simulated worlds;
    /// with --images or --negatives, on real photographs instead.
    #[command(name = "eval-detector")]
    Detector {
        #[command(flatten)]
        detector: DetectorArgs,
        /// A labelled folder of real images: an Ultralytics dataset (data.yaml)
        /// or images/ with labels/ (or labels_yolo/). Scored class-agnostic,
        /// overall and per labelled class, at --min-score.
        #[arg(long)]
        images: Option<PathBuf>,
        /// A folder of real tower-free images (and its subfolders): the share
        /// that gets a box at --min-score.
        #[arg(long)]
        negatives: Option<PathBuf>,
        /// The data.yaml split to score (default: test, else val).
        #[arg(long)]
        split: Option<String>,
        /// The folder's class names, in id order, replacing its own
        /// (data.yaml's names or classes.txt).
        #[arg(long, value_delimiter = ',')]
        names: Option<Vec<String>>,
        /// A labelled class that is neither a hit nor a false positive (repeatable).
        #[arg(long)]
        dont_care: Vec<String>,
        /// Held-out worlds to render (drawn from --seed; training used seed 0).
        #[arg(long, default_value_t = 10)]
        worlds: u64,
        #[arg(long, default_value_t = 30)]
        frames_per_world: u64,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Types each box may be scored under, best first: 1 is what the
        /// pipeline gets; 4 scores mAP as Ultralytics validates (`multi_label`).
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=4))]
        types_per_box: u8,
        /// Folder for detector-eval.json.
        #[arg(long, default_value = "target/detector-eval")]
        out: PathBuf,
    },
    /// The detector on a folder of your own photos, before you fly your
    /// line: each photo annotated with its boxes (class and score), a contact
    /// sheet of them all, and every box in detections.csv.
    #[command(name = "detect")]
    Detect {
        #[command(flatten)]
        detector: DetectorArgs,
        /// A folder of photos (JPEG, PNG; and its subfolders, one level down).
        #[arg(long)]
        images: PathBuf,
        /// Folder for annotated/, contact-sheet.jpg, detections.csv and detect.json.
        #[arg(long)]
        out: PathBuf,
    },
    /// Localization over random worlds and turning flights beside their
    /// lines, with random weather: the oracle and the YOLO detector on the
    /// rendered frames, every frame through the pipeline, scored against
    /// truth (RMS, median, p95, within 5 m, estimates, 2-sigma coverage,
    /// identity).
    #[command(name = "bench-localization")]
    LocBench {
        #[command(flatten)]
        detector: DetectorArgs,
        #[arg(long, default_value_t = 5)]
        worlds: u64,
        /// World i is drawn from seed + i (no test or dataset uses 1000 on).
        #[arg(long, default_value_t = 1000)]
        seed: u64,
        /// The oracle only: no model, no rendering.
        #[arg(long)]
        oracle_only: bool,
        /// The localizer's box-edge spread for the YOLO runs, pixels
        /// (default: the daemon's, `detector.edge_sigma_px`).
        #[arg(long)]
        edge_sigma_px: Option<f64>,
        /// The share of the box's size (its height for its ends, its width
        /// for its sides) that adds to that spread for the YOLO runs
        /// (default: the daemon's, `detector.edge_sigma_share`).
        #[arg(long)]
        edge_sigma_share: Option<f64>,
        /// The share of the box height within which a box's end near the
        /// image's border is taken as cut, for the YOLO runs (default: the
        /// daemon's, `detector.cut_margin_share`).
        #[arg(long)]
        cut_margin_share: Option<f64>,
        /// The edge spread of a box the frame cuts, times a whole one's, for
        /// the YOLO runs (default: the daemon's, `detector.cut_sigma_scale`).
        #[arg(long)]
        cut_sigma_scale: Option<f64>,
        /// The published covariance, times the filter's, for the YOLO runs
        /// (default: the daemon's, `detector.covariance_scale`).
        #[arg(long)]
        covariance_scale: Option<f64>,
        /// The filter publishes an estimate only while its horizontal
        /// 1-sigma is within this, metres, in both runs (default: the
        /// daemon's, `pipeline.max_report_sigma_m`).
        #[arg(long)]
        max_report_sigma: Option<f64>,
        /// How long the filter predicts without a fix before it is lost,
        /// seconds, in both runs (default: the filter's, 20 s).
        #[arg(long)]
        max_coast_s: Option<f64>,
        /// Also fuse a velocity each frame, as a VIO or optical-flow
        /// estimator would send it: the truth's plus noise of this 1-sigma
        /// per axis, m/s.
        #[arg(long)]
        velocity_sigma: Option<f64>,
        /// Fly without the simulated barometer (its height above take-off,
        /// off by a 1 m bias and 0.3 m noise, 1-sigma).
        #[arg(long)]
        no_barometer: bool,
        /// Turn each frame by the IMU's roll before the detector, so towers
        /// stand upright in what it sees.
        #[arg(long)]
        upright: bool,
        /// The per-frame estimator: `rays` (ours) or `paper`.
        #[arg(long, default_value = "rays")]
        method: String,
        /// Folder for loc-bench.json and each flight's per-frame CSV.
        #[arg(long, default_value = "target/loc-bench")]
        out: PathBuf,
    },
    /// Reproduce the paper's localization analysis (seed vs ours, tables and PNG plots).
    #[command(name = "eval-localization")]
    Localization {
        /// Folder for the plots.
        #[arg(long, default_value = "target/loc-eval")]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

impl EvalCommand {
    pub fn run(&self) -> anyhow::Result<()> {
        match self {
            Self::Localization { out, seed } => towernav_eval::cmd::loc_eval::write_all(out, *seed),
            Self::LocBench {
                detector,
                worlds,
                seed,
                oracle_only,
                edge_sigma_px,
                edge_sigma_share,
                cut_margin_share,
                cut_sigma_scale,
                covariance_scale,
                max_report_sigma,
                max_coast_s,
                velocity_sigma,
                no_barometer,
                method,
                upright,
                out,
            } => {
                let method = towernav_core::localizer::Method::from_name(method)
                    .with_context(|| format!("--method {method:?}: not rays or paper"))?;
                let section = detector.section();
                let model = (!oracle_only).then(|| {
                    (
                        section.model.clone(),
                        section.type_model().map(PathBuf::from),
                        detector.options(),
                    )
                });
                let options = towernav_eval::cmd::loc_bench::LocBenchOptions {
                    worlds: *worlds,
                    seed: *seed,
                    model,
                    edge_sigma_px: Some(edge_sigma_px.unwrap_or(section.edge_sigma_px)),
                    edge_sigma_share: Some(edge_sigma_share.unwrap_or(section.edge_sigma_share)),
                    cut_margin_share: Some(cut_margin_share.unwrap_or(section.cut_margin_share)),
                    cut_sigma_scale: Some(cut_sigma_scale.unwrap_or(section.cut_sigma_scale)),
                    covariance_scale: Some(covariance_scale.unwrap_or(section.covariance_scale)),
                    max_report_sigma_m: Some(
                        max_report_sigma.unwrap_or(
                            towernav_edge::daemon::config::PipelineSection::default()
                                .max_report_sigma_m,
                        ),
                    ),
                    max_coast_s: *max_coast_s,
                    velocity_sigma_mps: *velocity_sigma,
                    no_barometer: *no_barometer,
                    method,
                    upright: *upright,
                };
                towernav_eval::cmd::loc_bench::write_all(&options, out)
            }
            Self::Detect {
                detector,
                images,
                out,
            } => {
                let section = detector.section();
                let summary = towernav_eval::cmd::detect_photos::run(
                    &section.model,
                    section.type_model(),
                    &detector.options(),
                    images,
                    out,
                )?;
                println!(
                    "{} of {} photos have a box at score {} or more ({}); contact sheet: {}",
                    summary.with_boxes(),
                    summary.photos.len(),
                    summary.min_score,
                    summary.classes.join(", "),
                    summary.contact_sheet.display()
                );
                for (photo, why) in &summary.failed {
                    eprintln!("not read: {photo}: {why}");
                }
                anyhow::ensure!(
                    !summary.photos.is_empty(),
                    "none of the {} photos in {} could be read",
                    summary.failed.len(),
                    images.display()
                );
                Ok(())
            }
            Self::Tracking { out, seed, reid } => {
                towernav_eval::cmd::tracking_eval::write_all(out, *seed, reid.as_deref())
            }
            Self::Detector {
                detector,
                images,
                negatives,
                split,
                names,
                dont_care,
                worlds,
                frames_per_world,
                seed,
                types_per_box,
                out,
            } => {
                let options = DetectorEvalOptions {
                    worlds: *worlds,
                    frames_per_world: *frames_per_world,
                    seed: *seed,
                    recall_score: detector.min_score,
                };
                // Average precision needs the whole ranking: keep candidates down to 0.001,
                // as Ultralytics' validation does; P and R are read at --min-score.
                let mut detector_options = detector.options();
                detector_options.post.min_score = 0.001;
                detector_options.post.types_per_box = usize::from(*types_per_box);
                let section = detector.section();
                if images.is_some() || negatives.is_some() {
                    let real = RealEvalOptions {
                        images: images.clone(),
                        negatives: negatives.clone(),
                        split: split.clone(),
                        names: names.clone(),
                        dont_care: dont_care.clone(),
                        at_score: detector.min_score,
                    };
                    return towernav_eval::cmd::real_eval::write_all(
                        &section.model,
                        section.type_model(),
                        &detector_options,
                        &real,
                        out,
                    );
                }
                towernav_eval::cmd::detector_eval::write_all(
                    &section.model,
                    section.type_model(),
                    &detector_options,
                    &options,
                    out,
                )
            }
        }
    }
}
