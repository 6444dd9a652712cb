//! The simulator as a frame source (demo build only): frames rendered for
//! the detector, or the oracle's boxes with an occasional rendered frame for
//! the preview.

use std::sync::Arc;
use std::time::Instant;

use towernav_sim::{Conditions, FrameTruth, Scenario};

use super::source::{CapturedFrame, FrameSource, SourceError};

/// What the simulator renders.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimRender {
    /// Every frame, for the detector.
    Detector,
    /// The oracle's boxes, with one frame in `n` rendered for the operator's preview.
    PreviewEvery(u64),
    /// The oracle's boxes only.
    Never,
}

/// The simulator: frames rendered for the detector, or the oracle's boxes
/// (with an occasional rendered frame for the preview).
pub struct SimSource {
    scenario: Arc<Scenario>,
    frames: Box<dyn Iterator<Item = (FrameTruth, towernav_protocol::DetectionFrame)> + Send>,
    render: Option<(
        towernav_sim::Renderer,
        towernav_sim::FrameBuffers,
        Conditions,
    )>,
    mode: SimRender,
    max_frames: u64,
    barometer: towernav_sim::Barometer,
    /// A camera failure to rehearse: from this flight time, this long.
    stall: Option<Stall>,
}

/// The simulated camera stops at `at_s` of the flight for `for_s` seconds
/// of wall time; the frames it would have taken meanwhile are lost, as a
/// real camera's are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stall {
    pub at_s: f64,
    pub for_s: f64,
    pub done: bool,
}

impl SimSource {
    pub fn new(scenario: Arc<Scenario>, mode: SimRender, max_frames: Option<u64>) -> Self {
        let render = (mode != SimRender::Never).then(|| {
            let renderer = scenario.renderer();
            let buffers = renderer.buffers();
            (renderer, buffers, Conditions::default())
        });
        let barometer = towernav_sim::Barometer::new(
            towernav_sim::BarometerParams::default(),
            scenario.seed,
            scenario.start_in_world().z,
        );
        Self {
            barometer,
            frames: Box::new(scenario.frames_shared()),
            scenario,
            render,
            mode,
            max_frames: max_frames.unwrap_or(u64::MAX),
            stall: None,
        }
    }

    /// With a camera stall to rehearse, `[at_s, for_s]`.
    pub fn with_stall(mut self, stall: Option<[f64; 2]>) -> Self {
        self.stall = stall.map(|[at_s, for_s]| Stall {
            at_s,
            for_s,
            done: false,
        });
        self
    }
}

impl FrameSource for SimSource {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>> {
        let (truth, frame) = loop {
            let (truth, frame) = self.frames.next()?;
            match &mut self.stall {
                Some(stall)
                    if frame.time_s >= stall.at_s && frame.time_s < stall.at_s + stall.for_s =>
                {
                    if !stall.done {
                        stall.done = true;
                        tracing::warn!(
                            at_s = stall.at_s,
                            for_s = stall.for_s,
                            "simulated camera stalls"
                        );
                        std::thread::sleep(std::time::Duration::from_secs_f64(stall.for_s));
                    }
                }
                _ => break (truth, frame),
            }
        };
        if frame.seq >= self.max_frames {
            return None;
        }
        let oracle = match self.mode {
            SimRender::Detector => None,
            SimRender::PreviewEvery(_) | SimRender::Never => Some(frame.detections),
        };
        let draw = match self.mode {
            SimRender::Detector => true,
            SimRender::PreviewEvery(n) => frame.seq % n.max(1) == 0,
            SimRender::Never => false,
        };
        let image = match &mut self.render {
            Some((renderer, buffers, conditions)) if draw => {
                self.scenario
                    .render_into(renderer, buffers, &truth, conditions);
                Some(buffers.image.clone())
            }
            _ => None,
        };
        let detections = oracle;
        Some(Ok(CapturedFrame {
            seq: frame.seq,
            time_s: frame.time_s,
            captured: Instant::now(),
            image,
            detections,
            attitude: Some(frame.imu_attitude),
            truth_in_world: Some(truth.pose.position_in_world),
            barometric_height_m: Some(self.barometer.read(truth.pose.position_in_world.z)),
        }))
    }

    fn describe(&self) -> String {
        format!(
            "simulator ({} frames at {} Hz, {})",
            self.scenario.frame_count(),
            self.scenario.fps,
            match self.mode {
                SimRender::Detector => "rendered",
                SimRender::PreviewEvery(_) => "oracle boxes, rendered previews",
                SimRender::Never => "oracle boxes",
            }
        )
    }
}
