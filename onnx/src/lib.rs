//! ONNX Runtime, loaded at run time through `ort`, around the core's pure
//! detector stages: the YOLO detector (`yolo`), the tower-type classifier on
//! full-resolution crops (`type_classifier`), and the session setup and
//! re-identification model they share (`runtime`).

pub mod runtime;
pub mod type_classifier;
pub mod yolo;

pub use runtime::OnnxError;
pub use yolo::{DetectorOptions, YoloDetector};
