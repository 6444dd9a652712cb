//! Evaluations: the pipeline's outputs scored from outside against the
//! simulator's truth. Detector mAP (`map_eval`, `confusion`), CLEAR MOT and
//! IDF1 (`mot_metrics`, `tracking_eval`), localization error (`loc_eval`,
//! `sim_eval`), the demo's report (`report`) and its scoring of the daemon's
//! outputs against truth (`truth_scorer`); the detector on real labelled
//! photographs and tower-free frames (`real_score`, with its box edges'
//! spread in `edge_precision`, over `towernav_dataset`'s folders); a
//! replayed real flight against its log's GNSS (`gnss_score`); `cmd` holds the eval commands
//! with their tables, files and plots.

pub mod annotate;
pub mod cmd;
pub mod confusion;
pub mod edge_precision;
pub mod gnss_score;
pub mod hota;
pub mod loc_eval;
pub mod map_eval;
pub mod mot_metrics;
pub mod progress;
pub mod real_score;
pub mod report;
pub mod sim_eval;
pub mod tracking_eval;
pub mod truth_scorer;
