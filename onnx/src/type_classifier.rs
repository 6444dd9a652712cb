//! The tower-type classifier on ONNX Runtime: an Ultralytics classification
//! export (`training/train_types.py`) run on the full-resolution crop of every
//! box the detector found. The crops and the retyping are
//! `towernav_core::detector::type_stage`'s.

use std::path::{Path, PathBuf};

use image::RgbImage;
use ort::session::Session;
use ort::value::TensorRef;
use towernav_geometry::PixelBox;
use towernav_protocol::Detection;

use crate::runtime::{OnnxError, load_session, model_classes, only_input};
use towernav_core::detector::postprocess::Candidate;
use towernav_core::detector::type_stage::{crop_square, retype};
use towernav_core::detector::{ClassMap, CropBatch, PostprocessParams, Region};

/// At most this many boxes a frame are classified, best first; the rest are
/// dropped. It bounds the frame's work: a camera sees a handful of towers, and
/// a frame of tower-like clutter must not blow the frame budget.
pub const MAX_TYPED: usize = 32;

pub struct TypeClassifier {
    session: Session,
    path: PathBuf,
    input_name: String,
    classes: ClassMap,
    size: u32,
    crops: CropBatch,
}

impl TypeClassifier {
    /// Load and check a model: one [N, 3, S, S] input with S fixed, one
    /// [N, classes] output, and classes that are the database's tower types.
    pub fn load(path: &Path, threads: usize, cuda: bool) -> Result<Self, OnnxError> {
        let session = load_session(path, threads, cuda)?;
        let bad = |reason: String| OnnxError::Model {
            path: path.to_path_buf(),
            reason,
        };
        let classes = model_classes(&session, path)?;
        let (input_name, dims) = only_input(&session, path, "the crops")?;
        let size = match dims.as_slice() {
            [_, 3, h, w] if *h > 0 && h == w => *h as u32,
            other => {
                return Err(bad(format!(
                    "expected square crops [N, 3, S, S] with S fixed (a classifier exported by \
                     training/train_types.py), found {other:?}"
                )));
            }
        };
        let [output] = session.outputs() else {
            return Err(bad(format!(
                "expected one output (class probabilities), found {}",
                session.outputs().len()
            )));
        };
        match output.dtype().tensor_shape().map(|s| s.to_vec()) {
            Some(s) if s.len() == 2 && s[1] == classes.len() as i64 => {}
            other => {
                return Err(bad(format!(
                    "expected an output [N, {}] of class probabilities, found {other:?}",
                    classes.len()
                )));
            }
        }
        tracing::info!(model = %path.display(), crop = size, "tower-type classifier loaded");
        Ok(Self {
            input_name,
            session,
            path: path.to_path_buf(),
            classes,
            size,
            crops: CropBatch::new(size, size),
        })
    }

    /// Its class names, in output order.
    pub fn class_names(&self) -> &[String] {
        &self.classes.names
    }

    /// The tower types it names, in output order.
    pub fn types(&self) -> &[towernav_protocol::TowerType] {
        self.classes.types()
    }

    /// Class probabilities for each box, one row of `classes` per box.
    pub fn probabilities(
        &mut self,
        frame: &RgbImage,
        boxes: &[PixelBox],
    ) -> Result<Vec<f32>, OnnxError> {
        if boxes.is_empty() {
            return Ok(Vec::new());
        }
        let fail = |reason: String| OnnxError::Run {
            path: self.path.clone(),
            reason,
        };
        let regions: Vec<Region> = boxes.iter().map(crop_square).collect();
        let batch = self
            .crops
            .cut(frame, &regions)
            .map_err(|e| fail(e.to_string()))?;
        let s = self.size as usize;
        let tensor = TensorRef::from_array_view(([boxes.len(), 3, s, s], batch))
            .map_err(|e| fail(e.to_string()))?;
        let outputs = self
            .session
            .run(ort::inputs![self.input_name.as_str() => tensor])
            .map_err(|e| fail(e.to_string()))?;
        let (shape, values) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| fail(format!("output is not float32: {e}")))?;
        match &**shape {
            [n, k] if *n as usize == boxes.len() && *k as usize == self.classes.len() => {
                Ok(values.to_vec())
            }
            other => Err(fail(format!(
                "expected output [{}, {}], got {other:?}",
                boxes.len(),
                self.classes.len()
            ))),
        }
    }

    /// The detector's boxes (best first) with the types read from their
    /// crops; beyond the first `MAX_TYPED`, dropped.
    pub fn retype(
        &mut self,
        frame: &RgbImage,
        candidates: &[Candidate],
        params: &PostprocessParams,
    ) -> Result<Vec<Detection>, OnnxError> {
        let candidates = &candidates[..candidates.len().min(MAX_TYPED)];
        let boxes: Vec<PixelBox> = candidates.iter().map(|c| c.detection.bbox).collect();
        let probs = self.probabilities(frame, &boxes)?;
        Ok(retype(candidates, &probs, &self.classes, params))
    }
}
