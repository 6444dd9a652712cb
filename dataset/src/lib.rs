//! Labelled image folders as Ultralytics and the labelling tools keep them:
//! `data.yaml` (or `images/` beside `labels/`), one YOLO text file per image.
//! Read by the detector's evaluation and the ground station's label review,
//! written by the survey labeller, the COCO import and the review. Parsing
//! and formatting are pure; the folder functions do the file I/O.

pub mod folder;
pub mod label_file;

pub use folder::{
    DataYaml, FolderError, ImageFolder, LabelledImage, YoloLabel, images_under, labels_for,
    parse_data_yaml, parse_labels,
};
pub use label_file::{format_labels, write_labels};
