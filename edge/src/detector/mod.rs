//! The detector's pure parts: letterbox pre-processing, decoding of
//! Ultralytics YOLO outputs, class names, and the mAP evaluator. Running the
//! model (ONNX Runtime) is the shell's.

pub mod classes;
pub mod decode;
pub mod letterbox;
pub mod map_eval;
pub mod postprocess;

pub use classes::{ClassError, ClassMap};
pub use decode::{Layout, LayoutError, RawDetection, decode, layout, nms};
pub use letterbox::{Letterbox, PreprocessError, Preprocessor};
pub use postprocess::{PostprocessParams, postprocess};
