//! The eval commands of `towernav-edge` (behind its `demo` feature): each
//! renders or replays its cases, scores them, and writes tables, files and
//! plots. They return `anyhow` errors, as the binary's commands do.

pub mod demo_plots;
pub mod detect_photos;
pub mod detector_eval;
pub mod loc_bench;
pub mod loc_eval;
pub mod loc_gaps;
pub mod loc_plots;
pub mod real_eval;
pub mod tracking_eval;
