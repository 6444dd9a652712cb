//! The detector's pure parts: letterbox pre-processing and decoding of
//! Ultralytics YOLO outputs, and the mAP evaluator. Running the model (ONNX
//! Runtime) is the shell's.

pub mod decode;
pub mod letterbox;
pub mod map_eval;

pub use decode::{Layout, LayoutError, RawDetection, decode, layout, nms};
pub use letterbox::Letterbox;
