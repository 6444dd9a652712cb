//! The eval commands' detector flags (demo build).

use std::path::PathBuf;

use clap::Args;
use towernav_core::detector::PostprocessParams;
use towernav_edge::daemon::config::DetectorSection;
use towernav_onnx::DetectorOptions;

#[derive(Args, Clone)]
pub struct DetectorArgs {
    /// YOLO model (Ultralytics ONNX export, classes A-D); default: the
    /// daemon's (`towernav-edge print-config`).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Tower-type classifier run on each box's full-resolution crop; default:
    /// the daemon's.
    #[arg(long, conflicts_with = "no_type_model")]
    pub type_model: Option<PathBuf>,
    /// No classifier: the detector's own types.
    #[arg(long)]
    pub no_type_model: bool,
    /// ONNX Runtime threads for inference.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Run inference on CUDA (build with `--features cuda`).
    #[arg(long)]
    pub cuda: bool,
    /// Detections below this confidence are dropped.
    #[arg(long, default_value_t = 0.25)]
    pub min_score: f32,
    /// Weight of the detector's own type scores against the classifier's
    /// reading of the crop, 0 to 1 (0: the classifier alone).
    #[arg(long, default_value_t = towernav_core::detector::postprocess::DETECTOR_TYPE_WEIGHT,
          value_parser = unit_interval)]
    pub detector_type_weight: f32,
}

fn unit_interval(text: &str) -> Result<f32, String> {
    match text.parse::<f32>() {
        Ok(w) if (0.0..=1.0).contains(&w) => Ok(w),
        Ok(w) => Err(format!("{w} is not between 0 and 1")),
        Err(e) => Err(e.to_string()),
    }
}

impl DetectorArgs {
    /// The daemon's detector section with these flags applied: the evaluator
    /// scores what the daemon runs unless told otherwise.
    pub fn section(&self) -> DetectorSection {
        let mut section = DetectorSection::default();
        if let Some(model) = &self.model {
            section.model = model.clone();
        }
        if let Some(type_model) = &self.type_model {
            section.type_model = type_model.clone();
            section.classify_types = true;
        }
        if self.no_type_model {
            section.classify_types = false;
        }
        section
    }

    pub fn options(&self) -> DetectorOptions {
        DetectorOptions {
            threads: self.threads,
            cuda: self.cuda,
            post: PostprocessParams {
                min_score: self.min_score,
                detector_type_weight: self.detector_type_weight,
                ..PostprocessParams::default()
            },
        }
    }
}
