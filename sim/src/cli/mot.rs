//! MOT-challenge ground truth on disk: `gt/gt.txt`, `gt/towers.csv` and
//! `seqinfo.ini` per sequence (the text from the library's `mot`), so
//! standard tools (TrackEval, py-motmetrics) can score trackers on it.

use std::path::Path;

use anyhow::Context;
use towernav_sim::{FrameTruth, Scenario, mot};

/// Write one sequence's ground truth into `dir`.
pub fn write_sequence(
    dir: &Path,
    name: &str,
    scenario: &Scenario,
    frames: &[FrameTruth],
) -> anyhow::Result<()> {
    for (file, text) in mot::sequence_files(name, scenario, frames)? {
        let path = dir.join(file);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
        }
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
