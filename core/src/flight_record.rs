//! What a flight through the daemon did, frame by frame, for the report.

#[derive(Debug, Clone, Default)]
pub struct FlightRecord {
    pub frames: u64,
    pub poses_published: u64,
    /// Seconds spent in the pure pipeline, summed.
    pub core_seconds: f64,
    pub wall_seconds: f64,
    /// Seconds in the detector (pre-processing, inference, post-processing),
    /// and frames that failed (skipped).
    pub detect_seconds: f64,
    pub detector_errors: u64,
    /// The real detector's name; `None` for the oracle.
    pub detector: Option<String>,
}
