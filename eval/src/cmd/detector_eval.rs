//! `towernav-edge eval-detector`: the paper's Table 1 for a YOLO model on
//! held-out simulated worlds, rendered here from seeds training never drew
//! (`towernav-sim dataset --seed 0` draws worlds 0..N of seed 0; this draws
//! from `--seed`, 1 by default).

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use comfy_table::Table;
use serde::Serialize;
use towernav_protocol::Detection;
use towernav_protocol::TowerType;
use towernav_sim::{FrameTruth, Scenario};

use crate::confusion::ConfusionMatrix;
use crate::map_eval::{
    HEIGHT_BANDS, Labelled, MapAccumulator, MapMetrics, Scored, restrict, restrict_to_height,
};
use crate::progress::bar;
use towernav_onnx::yolo::{DetectorOptions, YoloDetector};

/// The held-out set and where the report goes.
#[derive(Debug, Clone)]
pub struct DetectorEvalOptions {
    pub worlds: u64,
    pub frames_per_world: u64,
    pub seed: u64,
    /// Score at which precision, recall and the height bands are read.
    pub recall_score: f32,
}

/// Towers shorter than this are outside the accuracy target (they are still
/// reported in the height bands).
pub const TARGET_MIN_HEIGHT_PX: f64 = 40.0;

/// A tower at least this share of whose box is behind nearer objects' boxes
/// is not in full view.
pub const HIDDEN_SHARE: f64 = 0.5;

#[derive(Debug, Clone, Serialize)]
pub struct DetectorEval {
    pub model: String,
    /// The type classifier, when one named the boxes' types.
    pub type_model: Option<String>,
    pub input: (u32, u32),
    /// Types each box was scored under (1: as the pipeline gets them).
    pub types_per_box: usize,
    /// Weight of the detector's type scores against the classifier's.
    pub detector_type_weight: f32,
    pub images: usize,
    pub all: MetricsJson,
    pub taller_than_40px: MetricsJson,
    /// The same towers with every type collapsed into one: how well boxes are
    /// found, whatever type they were given.
    pub taller_than_40px_any_type: MetricsJson,
    /// Towers taller than 40 px: rows labelled A..D then background, columns
    /// detected A..D then missed (score >= `recall_score`, IoU >= 0.5).
    pub confusion_taller_than_40px: Vec<Vec<usize>>,
    /// Towers taller than 40 px that are in full view: those the frame's edge
    /// cuts or that are at least half hidden behind nearer objects are "don't
    /// care" (KITTI's way): finding one is neither a hit nor a false positive.
    pub taller_than_40px_visible: MetricsJson,
    /// Of those towers found at all, the share given the right type.
    pub type_accuracy_of_found: f64,
    /// Wall time per frame of `detect` (pre-processing, inference, post-processing), ms.
    pub latency_ms_p50: f64,
    pub latency_ms_p99: f64,
    pub latency_ms_mean: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct MetricsJson {
    pub precision: f64,
    pub recall: f64,
    pub map50: f64,
    pub map50_95: f64,
    pub per_class_map50: Vec<(String, f64)>,
    pub recall_by_height: Vec<(String, f64, usize)>,
}

impl From<&MapMetrics> for MetricsJson {
    fn from(m: &MapMetrics) -> Self {
        Self {
            precision: m.overall.precision,
            recall: m.overall.recall,
            map50: m.overall.ap50,
            map50_95: m.overall.ap50_95,
            per_class_map50: TowerType::ALL
                .iter()
                .zip(&m.per_class)
                .map(|(t, c)| (t.to_string(), c.ap50))
                .collect(),
            recall_by_height: band_names()
                .into_iter()
                .zip(m.recall_by_height)
                .map(|(n, (r, k))| (n, r, k))
                .collect(),
        }
    }
}

fn band_names() -> Vec<String> {
    HEIGHT_BANDS
        .iter()
        .map(|(lo, hi)| {
            if hi.is_infinite() {
                format!(">{lo:.0} px")
            } else {
                format!("{lo:.0}-{hi:.0} px")
            }
        })
        .collect()
}

/// Everything `write_all` prints.
pub struct Report {
    pub eval: DetectorEval,
    pub all: MapMetrics,
    pub tall: MapMetrics,
    pub tall_any_type: MapMetrics,
    pub visible: MapMetrics,
    pub confusion: ConfusionMatrix,
}

/// Every table `evaluate` fills, one frame at a time.
struct Tables {
    all: MapAccumulator,
    tall: MapAccumulator,
    tall_any_type: MapAccumulator,
    visible: MapAccumulator,
    confusion: ConfusionMatrix,
}

impl Tables {
    fn new(recall_score: f32) -> Self {
        let classes = TowerType::ALL.len();
        Self {
            all: MapAccumulator::new(classes, recall_score),
            tall: MapAccumulator::new(classes, recall_score),
            tall_any_type: MapAccumulator::new(1, recall_score),
            visible: MapAccumulator::new(classes, recall_score),
            confusion: ConfusionMatrix::new(classes, recall_score, 0.5),
        }
    }

    /// One frame's truth and the detector's boxes, into every table.
    fn add_frame(&mut self, truth: &FrameTruth, dets: &[Detection]) {
        // Rendered worlds hold the four rendered designs only; a type
        // outside them (from a model with other classes) is a class
        // past them, scored as wrong.
        let class = |t: TowerType| t.rendered_index().unwrap_or(TowerType::ALL.len());
        let labels: Vec<Labelled> = truth
            .boxes
            .iter()
            .map(|b| Labelled {
                bbox: b.bbox,
                class: class(b.tower_type),
            })
            .collect();
        let scored: Vec<Scored> = dets
            .iter()
            .map(|d| Scored {
                bbox: d.bbox,
                class: class(d.tower_type),
                score: d.score as f32,
            })
            .collect();
        // Towers with barely any structure in frame are in no table.
        let unlabelled: Vec<bool> = truth.boxes.iter().map(|b| !b.labelled()).collect();
        let (labels, scored) = restrict(&labels, &scored, 0.0, &unlabelled);
        self.all.add_image(&labels, &scored);
        let hidden: Vec<bool> = truth
            .boxes
            .iter()
            .filter(|b| b.labelled())
            .map(|b| b.truncated || b.occluded >= HIDDEN_SHARE)
            .collect();
        let (v_labels, v_scored) = restrict(&labels, &scored, TARGET_MIN_HEIGHT_PX, &hidden);
        self.visible.add_image(&v_labels, &v_scored);
        let (labels, scored) = restrict_to_height(&labels, &scored, TARGET_MIN_HEIGHT_PX);
        self.tall.add_image(&labels, &scored);
        self.confusion.add_image(&labels, &scored);
        let (labels, scored) = one_type(&labels, &scored);
        self.tall_any_type.add_image(&labels, &scored);
    }
}

/// The `q` quantile of sorted `values`; NaN when there are none.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    sorted
        .get(((sorted.len() as f64 - 1.0) * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// Run `model` (and `type_model`, if any) over the held-out worlds and score it.
pub fn evaluate(
    model: &Path,
    type_model: Option<&Path>,
    detector_options: &DetectorOptions,
    options: &DetectorEvalOptions,
) -> anyhow::Result<Report> {
    let mut detector = YoloDetector::load_with_types(model, type_model, detector_options)?;
    let mut tables = Tables::new(options.recall_score);
    let mut latencies = Vec::new();
    let progress = bar(options.worlds * options.frames_per_world, "eval-detector");
    for w in 0..options.worlds {
        let world_seed = options.seed.wrapping_mul(1_000_003).wrapping_add(w);
        let (scenario, conditions) = Scenario::random_crossing(world_seed);
        let renderer = scenario.renderer();
        let mut buffers = renderer.buffers();
        let stride = (scenario.frame_count() / options.frames_per_world.max(1)).max(1);
        for k in 0..options.frames_per_world {
            let seq = k * stride;
            if seq >= scenario.frame_count() {
                break;
            }
            let truth = scenario.truth(seq);
            scenario.render_into(&renderer, &mut buffers, &truth, &conditions);
            let t0 = Instant::now();
            let dets = detector
                .detect(&buffers.image, seq)
                .with_context(|| format!("world {world_seed}, frame {seq}"))?;
            latencies.push(t0.elapsed().as_secs_f64() * 1e3);
            tables.add_frame(&truth, &dets);
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    latencies.sort_by(f64::total_cmp);
    let Tables {
        all,
        tall,
        tall_any_type,
        visible,
        confusion,
    } = tables;
    let (all, tall, tall_any_type, visible) = (
        all.finish(),
        tall.finish(),
        tall_any_type.finish(),
        visible.finish(),
    );
    let info = detector.info();
    let eval = DetectorEval {
        model: model.display().to_string(),
        type_model: type_model.map(|p| p.display().to_string()),
        input: (info.input_width, info.input_height),
        types_per_box: detector_options.post.types_per_box,
        detector_type_weight: detector_options.post.detector_type_weight,
        images: latencies.len(),
        all: MetricsJson::from(&all),
        taller_than_40px: MetricsJson::from(&tall),
        taller_than_40px_any_type: MetricsJson::from(&tall_any_type),
        taller_than_40px_visible: MetricsJson::from(&visible),
        confusion_taller_than_40px: confusion.rows().to_vec(),
        type_accuracy_of_found: confusion.type_accuracy_of_found(),
        latency_ms_p50: quantile(&latencies, 0.5),
        latency_ms_p99: quantile(&latencies, 0.99),
        latency_ms_mean: latencies.iter().sum::<f64>() / latencies.len().max(1) as f64,
    };
    Ok(Report {
        eval,
        all,
        tall,
        tall_any_type,
        visible,
        confusion,
    })
}

/// Labels and boxes with their types erased, for the class-agnostic score; a
/// box scored under several types counts once, at its best.
fn one_type(labels: &[Labelled], dets: &[Scored]) -> (Vec<Labelled>, Vec<Scored>) {
    let mut boxes: Vec<Scored> = Vec::with_capacity(dets.len());
    for d in dets {
        match boxes.iter_mut().find(|b| b.bbox == d.bbox) {
            Some(b) => b.score = b.score.max(d.score),
            None => boxes.push(Scored { class: 0, ..*d }),
        }
    }
    (
        labels.iter().map(|l| Labelled { class: 0, ..*l }).collect(),
        boxes,
    )
}

/// Table 1: one row per class and the overall row.
pub fn table(m: &MapMetrics) -> Table {
    let mut table = Table::new();
    table.set_header(["class", "labels", "P", "R", "mAP50", "mAP50-95"]);
    let row = |name: String, c: &crate::map_eval::ClassMetrics| {
        [
            name,
            c.truths.to_string(),
            format!("{:.3}", c.precision),
            format!("{:.3}", c.recall),
            format!("{:.3}", c.ap50),
            format!("{:.3}", c.ap50_95),
        ]
    };
    for (t, c) in TowerType::ALL.iter().zip(&m.per_class) {
        table.add_row(row(t.to_string(), c));
    }
    table.add_row(row("all".into(), &m.overall));
    table
}

/// Rows: labelled type (and background); columns: detected type (and missed).
pub fn confusion_table(m: &ConfusionMatrix) -> Table {
    let names: Vec<String> = TowerType::ALL.iter().map(|t| t.to_string()).collect();
    let mut table = Table::new();
    let mut header = vec!["labelled \\ detected".to_string()];
    header.extend(names.iter().cloned());
    header.push("missed".into());
    table.set_header(header);
    for (i, row) in m.rows().iter().enumerate() {
        let mut cells = vec![names.get(i).cloned().unwrap_or_else(|| "background".into())];
        cells.extend(row.iter().map(|n| n.to_string()));
        table.add_row(cells);
    }
    table
}

pub fn band_table(m: &MapMetrics) -> Table {
    let mut table = Table::new();
    table.set_header(["box height", "towers", "recall"]);
    for (name, (r, n)) in band_names().into_iter().zip(m.recall_by_height) {
        table.add_row([name, n.to_string(), format!("{r:.3}")]);
    }
    table
}

/// The command: tables on stdout, the numbers as JSON in `out`.
pub fn write_all(
    model: &Path,
    type_model: Option<&Path>,
    detector_options: &DetectorOptions,
    options: &DetectorEvalOptions,
    out: &Path,
) -> anyhow::Result<()> {
    let Report {
        eval,
        all,
        tall,
        tall_any_type,
        visible,
        confusion,
    } = evaluate(model, type_model, detector_options, options)?;
    println!(
        "Detector {} ({}x{} input), types from {} ({} per box), on {} frames of {} held-out worlds (seed {})\n",
        eval.model,
        eval.input.0,
        eval.input.1,
        eval.type_model.as_deref().map_or_else(
            || "the detector".to_string(),
            |m| format!(
                "{m} and the detector (weight {})",
                eval.detector_type_weight
            )
        ),
        eval.types_per_box,
        eval.images,
        options.worlds,
        options.seed
    );
    println!(
        "All towers (those with under {:.0} % of their structure in frame are in no table):\n{}\n",
        100.0 * towernav_sim::truth::MIN_IN_FRAME,
        table(&all)
    );
    println!(
        "Towers taller than {TARGET_MIN_HEIGHT_PX} px (the target):\n{}\n",
        table(&tall)
    );
    println!(
        "Towers taller than {TARGET_MIN_HEIGHT_PX} px, type ignored: P {:.3}, R {:.3}, mAP50 {:.3}, mAP50-95 {:.3}\n",
        tall_any_type.overall.precision,
        tall_any_type.overall.recall,
        tall_any_type.overall.ap50,
        tall_any_type.overall.ap50_95
    );
    println!(
        "Towers taller than {TARGET_MIN_HEIGHT_PX} px in full view (cut by the frame's edge or at least {:.0} % hidden: don't care):\n{}\n",
        100.0 * HIDDEN_SHARE,
        table(&visible)
    );
    println!(
        "Types given to towers taller than {TARGET_MIN_HEIGHT_PX} px (score >= {}, IoU >= 0.5); {:.1} % of the towers found got the right type:\n{}\n",
        options.recall_score,
        100.0 * confusion.type_accuracy_of_found(),
        confusion_table(&confusion)
    );
    println!(
        "Recall by box height (score >= {}):\n{}\n",
        options.recall_score,
        band_table(&all)
    );
    println!(
        "Latency per 1280x720 frame, pre + inference + post, {} threads: p50 {:.1} ms, p99 {:.1} ms, mean {:.1} ms",
        detector_options.threads, eval.latency_ms_p50, eval.latency_ms_p99, eval.latency_ms_mean
    );
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("detector-eval.json");
    std::fs::write(&path, serde_json::to_string_pretty(&eval)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
