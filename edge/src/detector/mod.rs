//! The detector's pure parts: letterbox pre-processing, decoding of
//! Ultralytics YOLO outputs, class names, second-stage crops, the mAP evaluator and its confusion matrix. Running the
//! model (ONNX Runtime) is the shell's.

pub mod classes;
pub mod confusion;
pub mod crop_batch;
pub mod decode;
pub mod letterbox;
pub mod map_eval;
pub mod postprocess;
pub mod type_stage;

pub use classes::{ClassError, ClassMap};
pub use crop_batch::{CropBatch, CropError, Region};
pub use decode::{ClassScores, Layout, LayoutError, RawDetection, ScoreMode, decode, layout, nms};
pub use letterbox::{Letterbox, PreprocessError, Preprocessor};
pub use postprocess::{Candidate, PostprocessParams, postprocess};
