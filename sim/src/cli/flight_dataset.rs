//! `towernav-sim flight --dataset-every N`: every Nth frame of the flight with
//! its exact truth boxes, as a YOLO dataset. A detector is then scored on the
//! very flight a replay localizes on (`towernav-edge eval-detector --images`),
//! against the renderer's boxes rather than labels projected from a pose.

use std::path::{Path, PathBuf};

use anyhow::Context;
use image::RgbImage;
use towernav_sim::{FrameTruth, LensEffects};

use crate::cli::dataset::{save_jpeg, write_data_yaml, write_labels};

/// The frames a flight's camera recorded are lightly compressed, as these are.
const JPEG_QUALITY: u8 = 95;

/// `dataset/` beside a flight: `images/`, `labels/` and `data.yaml`.
pub struct FlightDataset {
    root: PathBuf,
    every: u64,
    images: usize,
    boxes: [usize; 4],
}

impl FlightDataset {
    /// A dataset in `out/dataset` that keeps one frame in `every`.
    pub fn create(out: &Path, every: u64) -> anyhow::Result<Self> {
        anyhow::ensure!(every > 0, "--dataset-every must be 1 or more");
        let root = out.join("dataset");
        for dir in ["images", "labels"] {
            let dir = root.join(dir);
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        Ok(Self {
            root,
            every,
            images: 0,
            boxes: [0; 4],
        })
    }

    /// Whether frame `seq` goes into the dataset.
    pub fn wants(&self, seq: u64) -> bool {
        seq.is_multiple_of(self.every)
    }

    /// Frame `truth.seq`'s image and its labelled truth boxes.
    pub fn push(&mut self, truth: &FrameTruth, image: &RgbImage) -> anyhow::Result<()> {
        let stem = format!("{:06}", truth.seq + 1);
        save_jpeg(
            image,
            &self.root.join("images").join(format!("{stem}.jpg")),
            JPEG_QUALITY,
        )?;
        let size = (f64::from(image.width()), f64::from(image.height()));
        write_labels(
            &self.root.join("labels").join(format!("{stem}.txt")),
            truth,
            // The flight's frames are drawn through its lens, and its truth
            // boxes with them; no further defects move the pixels.
            &LensEffects::default(),
            size,
            &mut self.boxes,
        )?;
        self.images += 1;
        Ok(())
    }

    /// Writes `data.yaml`: every split is the flight's frames, so any tool
    /// that asks for one scores them all.
    pub fn finish(self) -> anyhow::Result<(usize, usize)> {
        write_data_yaml(
            &self.root,
            &format!(
                "Written by towernav-sim flight --dataset-every {every}: truth boxes, one frame in {every}.",
                every = self.every
            ),
            ["images"; 3],
        )?;
        Ok((self.images, self.boxes.iter().sum()))
    }
}
