//! MOT-challenge ground truth: `gt/gt.txt` and `seqinfo.ini` per sequence, so
//! standard tools (TrackEval, py-motmetrics) can score trackers on it.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use towernav_sim::{FrameTruth, World};

/// Write one sequence. Track ids are tower indices + 1 (stable per tower); the
/// class column is the tower type (A=1 .. D=4); visibility is 1 - occluded.
pub fn write_sequence(
    dir: &Path,
    name: &str,
    world: &World,
    frames: &[FrameTruth],
    fps: f64,
    (width, height): (u32, u32),
) -> anyhow::Result<()> {
    let gt_dir = dir.join("gt");
    std::fs::create_dir_all(&gt_dir).with_context(|| format!("creating {}", gt_dir.display()))?;
    let path = gt_dir.join("gt.txt");
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(&path).with_context(|| format!("creating {}", path.display()))?,
    );
    for f in frames {
        for b in &f.boxes {
            let id = world
                .towers
                .iter()
                .position(|t| t.id == b.tower_id)
                .context("truth box names a tower the world lacks")?
                + 1;
            writeln!(
                out,
                "{},{},{:.2},{:.2},{:.2},{:.2},1,{},{:.3}",
                f.seq + 1,
                id,
                b.bbox.left,
                b.bbox.top,
                b.bbox.width(),
                b.bbox.height(),
                // MOT's class column: 1-4 for the rendered designs, 0 for any other.
                b.tower_type.rendered_index().map_or(0, |i| i + 1),
                1.0 - b.occluded
            )?;
        }
    }
    out.flush()
        .with_context(|| format!("writing {}", path.display()))?;
    let ini = format!(
        "[Sequence]\nname={name}\nimDir=img1\nframeRate={fps}\nseqLength={}\nimWidth={width}\nimHeight={height}\nimExt=.jpg\n",
        frames.len()
    );
    let ini_path = dir.join("seqinfo.ini");
    std::fs::write(&ini_path, ini).with_context(|| format!("writing {}", ini_path.display()))?;
    Ok(())
}
