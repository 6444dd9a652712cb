//! The YOLO tower detector on ONNX Runtime: an Ultralytics export (YOLOv5 or
//! YOLOv8/11 layout), checked at load, run on one frame at a time. The pure
//! pre- and post-processing live in `towernav_core::detector`.

use std::path::{Path, PathBuf};

use image::RgbImage;
use ort::session::Session;
use ort::value::TensorRef;
use towernav_protocol::{Detection, TowerType};

use crate::runtime::{OnnxError, load_session, model_classes, only_input};
use crate::type_classifier::TypeClassifier;
use towernav_core::detector::{
    ClassMap, Layout, PostprocessParams, Preprocessor, ScoreMode, layout, postprocess,
};

/// How to run the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorOptions {
    /// ONNX Runtime intra-op threads.
    pub threads: usize,
    /// Use the CUDA execution provider (needs the `cuda` feature).
    pub cuda: bool,
    pub post: PostprocessParams,
}

impl Default for DetectorOptions {
    fn default() -> Self {
        Self {
            threads: 2,
            cuda: false,
            post: PostprocessParams::default(),
        }
    }
}

/// What was loaded, for status and logs.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorInfo {
    pub path: PathBuf,
    pub input_width: u32,
    pub input_height: u32,
    pub layout: Layout,
    pub classes: Vec<String>,
    /// The second stage that reads each box's type at full resolution, if any.
    pub type_model: Option<PathBuf>,
}

pub struct YoloDetector {
    session: Session,
    info: DetectorInfo,
    input_name: String,
    classes: ClassMap,
    pre: Preprocessor,
    post: PostprocessParams,
    types: Option<TypeClassifier>,
}

impl YoloDetector {
    /// Load and check a model: one [1, 3, H, W] input, one output in a known
    /// layout, and classes that are the database's tower types.
    pub fn load(path: &Path, options: &DetectorOptions) -> Result<Self, OnnxError> {
        let session = load_session(path, options.threads, options.cuda)?;
        let bad = |reason: String| OnnxError::Model {
            path: path.to_path_buf(),
            reason,
        };
        let classes = model_classes(&session, path)?;
        let (input_name, dims) = only_input(&session, path, "the image")?;
        let (input_height, input_width) = match dims.as_slice() {
            [1 | -1, 3, h, w] if *h > 0 && *w > 0 => (*h as u32, *w as u32),
            other => {
                return Err(bad(format!(
                    "expected an image input [1, 3, H, W] with fixed H and W (export with dynamic=False), found {other:?}"
                )));
            }
        };
        let [output] = session.outputs() else {
            return Err(bad(format!(
                "expected one output (the detections), found {}",
                session.outputs().len()
            )));
        };
        let out_dims: Vec<usize> = output
            .dtype()
            .tensor_shape()
            .map(|s| s.iter().map(|d| (*d).max(1) as usize).collect())
            .ok_or_else(|| bad("its output is not a tensor".into()))?;
        let layout = layout(&out_dims, classes.len()).map_err(|e| bad(e.to_string()))?;
        let info = DetectorInfo {
            path: path.to_path_buf(),
            input_width,
            input_height,
            layout,
            classes: classes.names.clone(),
            type_model: None,
        };
        tracing::info!(model = %path.display(), input = %format!("{input_width}x{input_height}"), ?layout, classes = ?info.classes, "detector loaded");
        Ok(Self {
            input_name,
            session,
            info,
            classes,
            pre: Preprocessor::new(input_width, input_height),
            post: options.post,
            types: None,
        })
    }

    /// The detector at `model` and, when `type_model` is given, the classifier
    /// that names each box's type from its full-resolution crop.
    pub fn load_with_types(
        model: &Path,
        type_model: Option<&Path>,
        options: &DetectorOptions,
    ) -> Result<Self, OnnxError> {
        let detector = Self::load(model, options)?;
        Ok(match type_model {
            Some(path) => {
                let classifier = TypeClassifier::load(path, options.threads, options.cuda)?;
                // Its probabilities are blended with the detector's class
                // scores one for one: the classes must be the same, in order;
                // or the detector finds towers of one class (`tower`) and the
                // classifier alone names their types.
                let untyped = detector.info.classes.len() == 1;
                if !untyped && classifier.class_names() != detector.info.classes.as_slice() {
                    return Err(OnnxError::Model {
                        path: path.to_path_buf(),
                        reason: format!(
                            "the type classifier's classes {:?} are not the detector's {:?} ({})",
                            classifier.class_names(),
                            detector.info.classes,
                            model.display()
                        ),
                    });
                }
                detector.with_type_classifier(path, classifier)
            }
            None => detector,
        })
    }

    /// Let `classifier` name each box's type from its full-resolution crop.
    pub fn with_type_classifier(mut self, path: &Path, classifier: TypeClassifier) -> Self {
        self.info.type_model = Some(path.to_path_buf());
        if self.classes.len() == 1 {
            // A one-class detector has no type scores to blend.
            self.post.detector_type_weight = 0.0;
            tracing::info!(
                classes = ?classifier.class_names(),
                "one-class detector: the type classifier alone names each tower's type"
            );
        }
        self.types = Some(classifier);
        // The classifier names the type: rank boxes by how sure the detector
        // is of a tower, whatever type it guessed.
        self.post.score = ScoreMode::AnyType;
        self
    }

    /// The tower types its boxes carry, in class order: the type
    /// classifier's when it names them, else the detector's own.
    pub fn classes(&self) -> &[TowerType] {
        match &self.types {
            Some(classifier) => classifier.types(),
            None => self.classes.types(),
        }
    }

    pub fn info(&self) -> &DetectorInfo {
        &self.info
    }

    /// Towers in frame `seq`, in frame pixels.
    pub fn detect(&mut self, frame: &RgbImage, seq: u64) -> Result<Vec<Detection>, OnnxError> {
        self.detect_turned(frame, seq, 0.0)
    }

    /// Towers in frame `seq`, in frame pixels, found in the frame turned
    /// clockwise on screen by `rotation` radians (the camera's roll, to set
    /// leaning towers upright; see [`Preprocessor::run_rotated`]).
    pub fn detect_turned(
        &mut self,
        frame: &RgbImage,
        seq: u64,
        rotation: f64,
    ) -> Result<Vec<Detection>, OnnxError> {
        let path = &self.info.path;
        let fail = |reason: String| OnnxError::Run {
            path: path.clone(),
            reason,
        };
        let (lb, input) = self
            .pre
            .run_rotated(frame, seq, rotation)
            .map_err(|e| fail(e.to_string()))?;
        let shape = [
            1usize,
            3,
            self.info.input_height as usize,
            self.info.input_width as usize,
        ];
        let tensor = TensorRef::from_array_view((shape, input)).map_err(|e| fail(e.to_string()))?;
        let outputs = self
            .session
            .run(ort::inputs![self.input_name.as_str() => tensor])
            .map_err(|e| fail(format!("frame {seq}: {e}")))?;
        let (out_shape, values) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| fail(format!("output is not float32: {e}")))?;
        let out_shape: Vec<usize> = out_shape.iter().map(|d| *d as usize).collect();
        let candidates = postprocess(
            values,
            &out_shape,
            &self.classes,
            &lb,
            frame.dimensions(),
            &self.post,
        )
        .map_err(|e| fail(e.to_string()))?;
        match &mut self.types {
            Some(types) => types.retype(frame, &candidates, &self.post),
            None => Ok(candidates.into_iter().map(|c| c.detection).collect()),
        }
    }
}
