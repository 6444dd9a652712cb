//! The onboard build has no simulator: `Sim` has no values, so every path
//! that would fly one is refused where the config asks for it.

use std::sync::Arc;

use towernav_geometry::{Datum, PinholeCamera};
use towernav_protocol::LandmarkRecord;

use crate::daemon::config::{EdgeConfig, SourceSection};
use crate::daemon::source::FrameSource;

/// A simulated flight; none exists in this build.
pub enum Sim {}

impl Sim {
    pub fn from_config(_source: &SourceSection) -> anyhow::Result<Arc<Self>> {
        anyhow::bail!(
            "source.kind = \"sim\": this build of towernav-edge has no simulator \
             (build it with `--features demo`, as `cargo xtask demo` does)"
        )
    }

    pub fn camera(&self) -> PinholeCamera {
        match *self {}
    }

    pub fn datum(&self) -> Datum {
        match *self {}
    }

    pub fn takeoff_in_world(&self) -> nalgebra::Point3<f64> {
        match *self {}
    }

    pub fn landmarks(&self) -> Vec<LandmarkRecord> {
        match *self {}
    }

    pub fn frame_count(&self) -> u64 {
        match *self {}
    }

    pub fn source(&self, _config: &EdgeConfig) -> Box<dyn FrameSource> {
        match *self {}
    }
}
