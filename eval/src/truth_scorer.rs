//! The demo's scoring, from outside the daemon: each processed frame's
//! pipeline output is matched with the scenario's truth for that frame.

use std::collections::BTreeMap;
use std::sync::Arc;

use towernav_core::daemon::FrameObserver;
use towernav_core::{FrameOutput, LandmarkMap};
use towernav_sim::Scenario;

use crate::mot_metrics::MotAccumulator;
use crate::tracking_eval::{add_frame, pipeline_hypotheses};

pub struct TruthScorer {
    scenario: Arc<Scenario>,
    /// Tower identities scored against truth (binding accuracy, bound share).
    pub identity: MotAccumulator,
    /// True horizontal position of each processed frame, by `seq`.
    pub truth_en: BTreeMap<u64, (f64, f64)>,
}

impl TruthScorer {
    pub fn new(scenario: Arc<Scenario>) -> Self {
        Self {
            scenario,
            identity: MotAccumulator::default(),
            truth_en: BTreeMap::new(),
        }
    }
}

impl FrameObserver for TruthScorer {
    fn observe(&mut self, seq: u64, output: &FrameOutput, map: &LandmarkMap) {
        if seq >= self.scenario.frame_count() {
            return;
        }
        let truth = self.scenario.truth(seq);
        let p = truth.pose.position_in_world;
        self.truth_en.insert(seq, (p.x, p.y));
        add_frame(
            &mut self.identity,
            &self.scenario,
            &truth,
            &pipeline_hypotheses(output, map),
        );
    }
}
