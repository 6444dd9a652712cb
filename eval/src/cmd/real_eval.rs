//! `towernav-edge eval-detector --images DIR [--negatives DIR]`: the
//! detector on real labelled photographs and on real tower-free frames.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use comfy_table::Table;
use image::{DynamicImage, ImageDecoder, ImageReader};
use serde::Serialize;
use towernav_onnx::yolo::{DetectorOptions, YoloDetector};

use crate::edge_precision::EdgePrecision;
use crate::map_eval::{Labelled, Scored};
use crate::progress::bar;
use crate::real_score::{
    FolderScore, NegativeScore, Row, ScoredImage, score_folder, score_negatives,
};
use towernav_dataset::{ImageFolder, images_under};

#[derive(Debug, Clone, Default)]
pub struct RealEvalOptions {
    pub images: Option<PathBuf>,
    pub negatives: Option<PathBuf>,
    /// The data.yaml split to score (default: test, else val).
    pub split: Option<String>,
    /// Class names replacing the folder's own.
    pub names: Option<Vec<String>>,
    /// Classes whose towers are neither hits nor false positives.
    pub dont_care: Vec<String>,
    /// The daemon's threshold: P, R and the false-box rate are read here.
    pub at_score: f32,
}

#[derive(Debug, Clone, Serialize)]
pub struct RealEval {
    pub model: String,
    pub model_names: Vec<String>,
    pub images_folder: Option<String>,
    pub labelled: Option<FolderScore>,
    pub negatives_folder: Option<String>,
    pub negatives: Option<NegativeScore>,
    /// The tower-free images that got a box, relative to their folder, each
    /// with its best box's score.
    pub negatives_boxed: Vec<(String, f32)>,
    /// Per image, pre-processing, inference and post-processing, ms.
    pub latency_ms_mean: f64,
}

/// Decode `path` upright (its EXIF orientation applied, as labelling tools show it).
pub fn load_upright(path: &Path) -> anyhow::Result<image::RgbImage> {
    let mut decoder = ImageReader::open(path)
        .with_context(|| format!("opening {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("reading {}", path.display()))?
        .into_decoder()
        .with_context(|| format!("decoding {}", path.display()))?;
    let orientation = decoder
        .orientation()
        .with_context(|| format!("reading the orientation of {}", path.display()))?;
    let mut image = DynamicImage::from_decoder(decoder)
        .with_context(|| format!("decoding {}", path.display()))?;
    image.apply_orientation(orientation);
    Ok(image.to_rgb8())
}

pub fn evaluate(
    model: &Path,
    type_model: Option<&Path>,
    detector_options: &DetectorOptions,
    options: &RealEvalOptions,
) -> anyhow::Result<RealEval> {
    anyhow::ensure!(
        options.images.is_some() || options.negatives.is_some(),
        "give --images, --negatives or both"
    );
    let mut detector = Timed {
        detector: YoloDetector::load_with_types(model, type_model, detector_options)?,
        spent_ms: 0.0,
        runs: 0,
    };
    let model_names: Vec<String> = detector.detector.info().classes.clone();
    let labelled = match &options.images {
        Some(dir) => Some(score_labelled(&mut detector, dir, &model_names, options)?),
        None => None,
    };
    let mut negatives_boxed = Vec::new();
    let negatives = match &options.negatives {
        Some(dir) => {
            let paths = images_under(dir)?;
            let progress = bar(paths.len() as u64, "negatives");
            let mut boxes = Vec::with_capacity(paths.len());
            for (seq, path) in paths.iter().enumerate() {
                boxes.push(detector.detect(path, seq as u64, &model_names)?.0);
                progress.inc(1);
            }
            progress.finish_and_clear();
            let score = score_negatives(&boxes, options.at_score);
            negatives_boxed = score
                .boxed
                .iter()
                .map(|&(i, best)| {
                    let name = paths[i].strip_prefix(dir).unwrap_or(&paths[i]);
                    (name.display().to_string(), best)
                })
                .collect();
            Some(score)
        }
        None => None,
    };
    Ok(RealEval {
        model: model.display().to_string(),
        model_names,
        images_folder: options.images.as_ref().map(|p| p.display().to_string()),
        labelled,
        negatives_folder: options.negatives.as_ref().map(|p| p.display().to_string()),
        negatives,
        negatives_boxed,
        latency_ms_mean: detector.spent_ms / detector.runs.max(1) as f64,
    })
}

/// The detector, with the time it has spent per image.
struct Timed {
    detector: YoloDetector,
    spent_ms: f64,
    runs: usize,
}

impl Timed {
    /// The boxes on the image at `path` with class indices in `model_names`'
    /// order, and the image's size.
    fn detect(
        &mut self,
        path: &Path,
        seq: u64,
        model_names: &[String],
    ) -> anyhow::Result<(Vec<Scored>, (f64, f64))> {
        let frame = load_upright(path)?;
        let t0 = Instant::now();
        let dets = self
            .detector
            .detect(&frame, seq)
            .with_context(|| format!("detecting in {}", path.display()))?;
        self.spent_ms += t0.elapsed().as_secs_f64() * 1e3;
        self.runs += 1;
        let boxes = dets
            .iter()
            .map(|d| Scored {
                bbox: d.bbox,
                class: model_names
                    .iter()
                    .position(|n| n == d.tower_type.as_str())
                    .unwrap_or(model_names.len()),
                score: d.score as f32,
            })
            .collect();
        Ok((boxes, (f64::from(frame.width()), f64::from(frame.height()))))
    }
}

/// Every image of the labelled folder `dir`, scored against its labels.
fn score_labelled(
    detector: &mut Timed,
    dir: &Path,
    model_names: &[String],
    options: &RealEvalOptions,
) -> anyhow::Result<FolderScore> {
    let folder = ImageFolder::open(dir, options.split.as_deref(), options.names.as_deref())?;
    let dont_care = options
        .dont_care
        .iter()
        .map(|n| {
            folder.names.iter().position(|f| f == n).with_context(|| {
                format!(
                    "--dont-care {n}: {} names {:?}",
                    dir.display(),
                    folder.names
                )
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let progress = bar(folder.images.len() as u64, "eval-detector");
    let mut scored = Vec::with_capacity(folder.images.len());
    for (seq, item) in folder.images.iter().enumerate() {
        let (boxes, (w, h)) = detector.detect(&item.image, seq as u64, model_names)?;
        let labels = item
            .labels
            .iter()
            .map(|l| Labelled {
                bbox: l.pixels(w, h),
                class: l.class,
            })
            .collect();
        scored.push(ScoredImage {
            frame: (w, h),
            labels,
            boxes,
        });
        progress.inc(1);
    }
    progress.finish_and_clear();
    Ok(score_folder(
        &scored,
        &folder.names,
        model_names,
        &dont_care,
        options.at_score,
    ))
}

fn rows_table(rows: &[&Row]) -> Table {
    let mut table = Table::new();
    table.set_header(["class", "labels", "P", "R", "mAP50", "mAP50-95"]);
    for r in rows {
        // A class with no labels here has no recall or precision to speak of.
        let f = |v: f64| {
            if r.labels == 0 {
                "-".to_string()
            } else {
                format!("{v:.3}")
            }
        };
        table.add_row([
            r.class.clone(),
            r.labels.to_string(),
            f(r.precision),
            f(r.recall),
            f(r.map50),
            f(r.map50_95),
        ]);
    }
    table
}

fn edges_table(edges: &EdgePrecision) -> Table {
    let mut table = Table::new();
    table.set_header([
        "label height",
        "labels",
        "matched",
        "height bias",
        "height spread",
        "edge spread",
    ]);
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:+.1} %", 100.0 * v));
    let spread = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.1} %", 100.0 * v));
    for r in edges.rows.iter().chain([&edges.over_40px]) {
        let range = match r.max_px {
            Some(max) => format!("{:.0}-{max:.0} px", r.min_px),
            None => format!("{:.0}+ px", r.min_px),
        };
        table.add_row([
            range,
            r.labels.to_string(),
            r.matched.to_string(),
            pct(r.height_bias),
            spread(r.height_spread),
            spread(r.edge_spread),
        ]);
    }
    table
}

/// The command: tables on stdout, the numbers as `real-eval.json` in `out`.
pub fn write_all(
    model: &Path,
    type_model: Option<&Path>,
    detector_options: &DetectorOptions,
    options: &RealEvalOptions,
    out: &Path,
) -> anyhow::Result<()> {
    let eval = evaluate(model, type_model, detector_options, options)?;
    println!(
        "Detector {} (classes {:?}) on real images\n",
        eval.model, eval.model_names
    );
    if let (Some(dir), Some(s)) = (&eval.images_folder, &eval.labelled) {
        let care = if s.dont_care.is_empty() {
            String::new()
        } else {
            format!("; don't care: {}", s.dont_care.join(", "))
        };
        println!(
            "{dir}: {} images, boxes matched whatever their class (P and R at score {}{care}):",
            s.images, options.at_score
        );
        let mut rows: Vec<&Row> = s.per_class.iter().collect();
        rows.push(&s.any_class);
        println!("{}\n", rows_table(&rows));
        if let Some(typed) = &s.typed {
            println!(
                "The model's classes are the folder's; typed:\n{}\n",
                rows_table(&typed.iter().collect::<Vec<_>>())
            );
        }
        println!(
            "Box tops and bottoms against the labels' (whole towers, boxes at IoU 0.5 scoring {}):\n{}",
            options.at_score,
            edges_table(&s.edges)
        );
        if let Some(spread) = s.edges.over_40px.edge_spread {
            println!(
                "The localizer takes an edge to stray by detector.edge_sigma_share of the box's height \
                 (with 1 px and a small-box term); this model's edges over 40 px stray by {:.1} %.\n",
                100.0 * spread
            );
        }
    }
    if let (Some(dir), Some(n)) = (&eval.negatives_folder, &eval.negatives) {
        println!(
            "{dir}: {} of {} tower-free images ({:.1} %) got a box scoring {} or more\n",
            n.with_a_false_box,
            n.images,
            100.0 * n.rate,
            n.at_score
        );
        for (name, best) in &eval.negatives_boxed {
            println!("  {name}: best box {best:.2}");
        }
        if !eval.negatives_boxed.is_empty() {
            println!();
        }
    }
    println!(
        "Mean time per image, pre + inference + post: {:.1} ms",
        eval.latency_ms_mean
    );
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("real-eval.json");
    std::fs::write(&path, serde_json::to_string_pretty(&eval)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
