//! `towernav-sim dataset`: YOLO images and labels from many random worlds,
//! split by world so validation and test worlds are never seen in training,
//! plus MOT-challenge truth for each world's flight.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use towernav_protocol::TowerType;
use towernav_sim::{FrameTruth, Scenario};

use crate::cli::flight_cmd::progress;
use crate::cli::mot;

pub struct DatasetOptions {
    pub worlds: usize,
    pub frames_per_world: usize,
    pub seed: u64,
    /// Shares of worlds for validation and test; the rest train.
    pub val_share: f64,
    pub test_share: f64,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Split {
    Train,
    Val,
    Test,
}

impl Split {
    fn name(self) -> &'static str {
        match self {
            Self::Train => "train",
            Self::Val => "val",
            Self::Test => "test",
        }
    }
}

/// World `i` of `n`: the last shares go to test, then val, so adding worlds grows train.
fn split_of(i: usize, n: usize, val_share: f64, test_share: f64) -> Split {
    let test = ((n as f64 * test_share).round() as usize).max(usize::from(test_share > 0.0));
    let val = ((n as f64 * val_share).round() as usize).max(usize::from(val_share > 0.0));
    if i + test >= n {
        Split::Test
    } else if i + test + val >= n {
        Split::Val
    } else {
        Split::Train
    }
}

pub fn write_dataset(out: &Path, options: &DatasetOptions) -> anyhow::Result<()> {
    anyhow::ensure!(
        options.worlds >= 3,
        "--worlds must be at least 3 (train, val and test each get one)"
    );
    anyhow::ensure!(
        options.frames_per_world >= 1,
        "--frames-per-world must be at least 1"
    );
    for split in [Split::Train, Split::Val, Split::Test] {
        for sub in ["images", "labels"] {
            let dir = out.join(sub).join(split.name());
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        }
    }
    let bar = progress(
        (options.worlds * options.frames_per_world) as u64,
        "dataset",
    );
    let mut counts = [[0usize; 4]; 3];
    let mut images = [0usize; 3];
    for w in 0..options.worlds {
        let world_seed = options.seed.wrapping_mul(1_000_003).wrapping_add(w as u64);
        let split = split_of(w, options.worlds, options.val_share, options.test_share);
        let (scenario, conditions) = Scenario::random_crossing(world_seed);
        let renderer = scenario.renderer();
        let mut buffers = renderer.buffers();
        let frames = scenario.frame_count().max(1);
        let stride = (frames / options.frames_per_world as u64).max(1);
        let name = format!("world{w:03}");
        let k = &scenario.camera.intrinsics;
        let mut truths = Vec::with_capacity(frames as usize);
        for (truth, _) in scenario.frames() {
            let seq = truth.seq;
            if seq % stride == 0 && seq / stride < options.frames_per_world as u64 {
                let mut look = conditions;
                look.exposure *= 1.0 + 0.05 * ((seq as f64) * 0.37).sin();
                scenario.render_into(&renderer, &mut buffers, &truth, &look);
                let stem = format!("{name}_{seq:05}");
                let img = out
                    .join("images")
                    .join(split.name())
                    .join(format!("{stem}.jpg"));
                buffers
                    .image
                    .save(&img)
                    .with_context(|| format!("writing {}", img.display()))?;
                let label = out
                    .join("labels")
                    .join(split.name())
                    .join(format!("{stem}.txt"));
                let size = (f64::from(k.width), f64::from(k.height));
                write_labels(&label, &truth, size, &mut counts[split as usize])?;
                images[split as usize] += 1;
                bar.inc(1);
            }
            truths.push(truth);
        }
        let seq_dir = out.join("mot").join(split.name()).join(&name);
        mot::write_sequence(
            &seq_dir,
            &name,
            &scenario.world,
            &truths,
            scenario.fps,
            (k.width, k.height),
        )?;
        let towers_csv = seq_dir.join("towers.csv");
        let file = std::fs::File::create(&towers_csv)
            .with_context(|| format!("creating {}", towers_csv.display()))?;
        towernav_landmark_db::export_csv(&scenario.world.landmarks(), file)
            .with_context(|| format!("writing {}", towers_csv.display()))?;
    }
    bar.finish();
    write_data_yaml(out, options.seed)?;
    for split in [Split::Train, Split::Val, Split::Test] {
        let c = counts[split as usize];
        eprintln!(
            "{:>5}: {:5} images, boxes A {} B {} C {} D {}",
            split.name(),
            images[split as usize],
            c[0],
            c[1],
            c[2],
            c[3]
        );
    }
    Ok(())
}

/// One image's YOLO labels (class, centre, size, normalized), counted per type.
fn write_labels(
    path: &Path,
    truth: &FrameTruth,
    (iw, ih): (f64, f64),
    counts: &mut [usize; 4],
) -> anyhow::Result<()> {
    let mut file = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    for b in truth.boxes.iter().filter(|b| b.labelled()) {
        writeln!(
            file,
            "{} {:.6} {:.6} {:.6} {:.6}",
            b.tower_type.index(),
            b.bbox.center_x() / iw,
            b.bbox.center_y() / ih,
            b.bbox.width() / iw,
            b.bbox.height() / ih
        )?;
        counts[b.tower_type.index()] += 1;
    }
    file.flush()
        .with_context(|| format!("writing {}", path.display()))
}

/// Ultralytics' `data.yaml`: the absolute root, the splits and the class names.
fn write_data_yaml(out: &Path, seed: u64) -> anyhow::Result<()> {
    let root =
        std::fs::canonicalize(out).with_context(|| format!("resolving {}", out.display()))?;
    let names: String = TowerType::ALL
        .iter()
        .map(|t| format!("  {}: {}\n", t.index(), t))
        .collect();
    let yaml = format!(
        "# Written by towernav-sim dataset --seed {seed}; worlds are split, never frames.\npath: {root}\ntrain: images/train\nval: images/val\ntest: images/test\nnames:\n{names}",
        root = root.display()
    );
    std::fs::write(out.join("data.yaml"), yaml).context("writing data.yaml")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_split_gets_a_world_and_train_the_rest() {
        let splits: Vec<Split> = (0..10).map(|i| split_of(i, 10, 0.1, 0.1)).collect();
        assert_eq!(splits.iter().filter(|s| **s == Split::Train).count(), 8);
        assert_eq!(splits[8], Split::Val);
        assert_eq!(splits[9], Split::Test);
        let small: Vec<Split> = (0..3).map(|i| split_of(i, 3, 0.1, 0.1)).collect();
        assert_eq!(small, vec![Split::Train, Split::Val, Split::Test]);
    }
}
