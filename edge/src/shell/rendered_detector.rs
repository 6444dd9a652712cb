//! The real detector on the simulator's rendered frames: what the demo runs
//! when it is not using the oracle.

use image::RgbImage;
use towernav_protocol::Detection;
use towernav_sim::render::FrameBuffers;
use towernav_sim::{Conditions, FrameTruth, Renderer, Scenario};

use super::onnx::OnnxError;
use super::yolo::YoloDetector;

pub struct RenderedDetector {
    renderer: Renderer,
    buffers: FrameBuffers,
    conditions: Conditions,
    detector: YoloDetector,
    /// Seconds spent rendering and detecting, summed, for the report.
    pub render_seconds: f64,
    pub detect_seconds: f64,
}

impl RenderedDetector {
    pub fn new(scenario: &Scenario, detector: YoloDetector, conditions: Conditions) -> Self {
        let renderer = scenario.renderer();
        Self {
            buffers: renderer.buffers(),
            renderer,
            conditions,
            detector,
            render_seconds: 0.0,
            detect_seconds: 0.0,
        }
    }

    /// Render the frame `truth` describes and detect its towers.
    pub fn detect(
        &mut self,
        scenario: &Scenario,
        truth: &FrameTruth,
    ) -> Result<Vec<Detection>, OnnxError> {
        let t0 = std::time::Instant::now();
        scenario.render_into(&self.renderer, &mut self.buffers, truth, &self.conditions);
        let t1 = std::time::Instant::now();
        let dets = self.detector.detect(&self.buffers.image, truth.seq);
        self.render_seconds += (t1 - t0).as_secs_f64();
        self.detect_seconds += t1.elapsed().as_secs_f64();
        dets
    }

    /// The last rendered frame.
    pub fn image(&self) -> &RgbImage {
        &self.buffers.image
    }

    pub fn detector(&self) -> &YoloDetector {
        &self.detector
    }
}
