//! The detector's pure parts: letterbox pre-processing, decoding of
//! Ultralytics YOLO outputs, class names, second-stage crops. Running the
//! model (ONNX Runtime) is `towernav-onnx`'s; scoring it is `towernav-eval`'s.

pub mod classes;
pub mod crop_batch;
pub mod decode;
pub mod letterbox;
pub mod postprocess;
pub mod type_stage;

pub use classes::{ClassError, ClassMap};
pub use crop_batch::{CropBatch, CropError, Region};
pub use decode::{ClassScores, Layout, LayoutError, RawDetection, ScoreMode, decode, layout, nms};
pub use letterbox::{Letterbox, PreprocessError, Preprocessor};
pub use postprocess::{Candidate, PostprocessParams, postprocess};
