//! `towernav-edge label`: labels from a survey flight (desk build, beside `replay`).

use std::path::PathBuf;

use clap::Args;
use towernav_core::survey_labels::LabelParams;
use towernav_edge::survey::{LabelOptions, label_flight};

use crate::cli::recording_args::RecordingArgs;

/// A survey flight (GNSS still working) into a YOLO dataset: every tower in
/// the landmarks projected into every `--every`-th frame by the log's GNSS
/// and attitude, and snapped to the detector's box where they agree.
#[derive(Args)]
pub struct LabelArgs {
    #[command(flatten)]
    recording: RecordingArgs,
    /// The flight log with attitude and GNSS: ArduPilot .bin, MAVLink .tlog,
    /// PX4 .ulg, CSV, DJI .srt or a GoPro .mp4; default: a GoPro --video's own.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Label every n-th frame.
    #[arg(long, default_value_t = 5)]
    every: u64,
    /// Towers shorter than this in the image get no label.
    #[arg(long, default_value_t = 24.0)]
    min_height_px: f64,
    /// The IoU at which a detector's box replaces the projected one.
    #[arg(long, default_value_t = 0.5)]
    snap_iou: f64,
    /// Keep the projections; run no detector.
    #[arg(long)]
    no_snap: bool,
    /// One class, `tower`, instead of the database's types.
    #[arg(long)]
    one_class: bool,
    /// YOLO model to snap to; default: the daemon's.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Folder for images/, labels/, data.yaml and report.csv.
    #[arg(long)]
    out: PathBuf,
}

impl LabelArgs {
    pub fn run(&self) -> anyhow::Result<()> {
        let r = &self.recording;
        anyhow::ensure!(
            r.camera.is_some() && r.landmarks.is_some(),
            "labels need the calibration (--camera) and the towers (--landmarks)"
        );
        let mut c = r.survey_config(self.log.as_ref())?;
        c.detector.classify_types = false;
        if let Some(m) = &self.model {
            c.detector.model = m.clone();
        }
        anyhow::ensure!(
            self.min_height_px > 0.0 && (0.0..1.0).contains(&self.snap_iou) && self.every > 0,
            "--min-height-px and --every must be positive and --snap-iou in [0, 1)"
        );
        let options = LabelOptions {
            params: LabelParams {
                min_height_px: self.min_height_px,
                snap_iou: self.snap_iou,
                ..LabelParams::default()
            },
            every: self.every,
            snap: !self.no_snap,
            one_class: self.one_class,
            out: self.out.clone(),
        };
        let bar = towernav_eval::progress::bar(0, "frames");
        let run = label_flight(&c, &options, |seq, total| {
            if let Some(n) = total {
                bar.set_length(n);
            }
            bar.set_position(seq + 1);
        })?;
        bar.finish_and_clear();
        println!(
            "{} of {} frames labelled ({} without a GNSS fix around them): {} labels, {} snapped to the detector's boxes, {} towers dropped (report.csv says why); dataset in {}",
            run.labelled_frames,
            run.frames,
            run.without_pose,
            run.labels,
            run.snapped,
            run.dropped,
            self.out.display()
        );
        Ok(())
    }
}

/// Reviewed labels back from COCO JSON (CVAT, Label Studio) into a YOLO
/// dataset's `labels/` and `data.yaml`, beside its `images/`.
#[derive(Args)]
pub struct LabelImportArgs {
    /// The COCO JSON export.
    #[arg(long)]
    coco: PathBuf,
    /// The dataset folder (`towernav-edge label`'s --out).
    #[arg(long)]
    out: PathBuf,
}

impl LabelImportArgs {
    pub fn run(&self) -> anyhow::Result<()> {
        use anyhow::Context;
        let text = std::fs::read_to_string(&self.coco)
            .with_context(|| format!("reading {}", self.coco.display()))?;
        let yolo =
            towernav_edge::coco_import::yolo_from_coco(&text, &self.coco.display().to_string())?;
        let labels = self.out.join("labels");
        std::fs::create_dir_all(&labels)
            .with_context(|| format!("creating {}", labels.display()))?;
        for (stem, lines) in &yolo.files {
            let path = labels.join(format!("{stem}.txt"));
            std::fs::write(&path, lines).with_context(|| format!("writing {}", path.display()))?;
        }
        let mut yaml = format!(
            "# Labels reviewed and imported from {}.\npath: {}\ntrain: images\nval: images\nnames:\n",
            self.coco.display(),
            std::path::absolute(&self.out)
                .unwrap_or_else(|_| self.out.clone())
                .display()
        );
        for (i, name) in yolo.names.iter().enumerate() {
            yaml.push_str(&format!("  {i}: {name:?}\n"));
        }
        let path = self.out.join("data.yaml");
        std::fs::write(&path, yaml).with_context(|| format!("writing {}", path.display()))?;
        println!(
            "{} label files, classes {:?}, into {}",
            yolo.files.len(),
            yolo.names,
            labels.display()
        );
        Ok(())
    }
}
