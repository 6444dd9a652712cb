//! `towernav-sim dataset`: YOLO images and labels from many random worlds,
//! split by world so validation and test worlds are never seen in training,
//! plus MOT-challenge truth for each world's flight.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use image::RgbImage;
use image::codecs::jpeg::JpegEncoder;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use towernav_protocol::TowerType;
use towernav_sim::viewpoint::random_viewpoint;
use towernav_sim::world::WorldParams;
use towernav_sim::{
    Backdrop, Conditions, FrameBuffers, FrameTruth, LensEffects, Renderer, Scenario,
};

use crate::cli::mot;
use crate::cli::photos::PhotoLibrary;
use crate::cli::progress::progress;

pub struct DatasetOptions {
    pub worlds: usize,
    pub frames_per_world: usize,
    pub seed: u64,
    /// Shares of worlds for validation and test; the rest train.
    pub val_share: f64,
    pub test_share: f64,
    /// Share of frames drawn with domain randomization (see [`randomized_shot`]); 0 renders
    /// every frame as the flight sees it.
    pub randomize: f64,
    /// Folders of real tower-free photographs: backgrounds for randomized
    /// frames, and each one a training image with no tower.
    pub backgrounds: Vec<PathBuf>,
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

/// One image as written: what it shows, what the lens did to it, how it was compressed.
pub struct Shot {
    pub truth: FrameTruth,
    pub lens: LensEffects,
    pub jpeg_quality: u8,
}

/// Render one frame of `scenario` with its look randomized: from the flight's
/// pose or a random viewpoint, under randomized light and paint, over a real
/// photo when `photos` has one, through random lens defects and compression.
pub fn randomized_shot(
    scenario: &Scenario,
    renderer: &Renderer,
    buffers: &mut FrameBuffers,
    flight_truth: &FrameTruth,
    photos: &PhotoLibrary,
    rng: &mut ChaCha8Rng,
    scratch: &mut Vec<u8>,
) -> Shot {
    let k = &scenario.camera.intrinsics;
    let hfov = 2.0 * (f64::from(k.width) / 2.0 / k.fx).atan();
    let pose = if rng.random_bool(0.5) {
        flight_truth.pose
    } else {
        random_viewpoint(&scenario.world, hfov, scenario.camera.mount.pitch, rng)
            .unwrap_or(flight_truth.pose)
    };
    let truth = scenario.truth_from(flight_truth.seq, pose);
    let conditions = Conditions::randomized(rng, pose.attitude.yaw);
    let photo = if rng.random_bool(0.6) {
        photos.pick(rng, k.width, k.height)
    } else {
        None
    };
    let backdrop = photo.as_ref().map(|photo| Backdrop {
        photo,
        whole_frame: rng.random_bool(0.25),
    });
    renderer.render_over(
        buffers,
        &pose,
        &conditions,
        scenario.flight.attitude_rates(truth.time_s),
        scenario.seed ^ truth.seq,
        backdrop,
    );
    let lens = LensEffects::random(rng);
    lens.apply(&mut buffers.image, scratch);
    Shot {
        truth,
        lens,
        jpeg_quality: rng.random_range(35..=95),
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
    anyhow::ensure!(
        (0.0..=1.0).contains(&options.randomize),
        "--randomize is a share of frames, 0 to 1 (got {})",
        options.randomize
    );
    for split in [Split::Train, Split::Val, Split::Test] {
        for sub in ["images", "labels"] {
            let dir = out.join(sub).join(split.name());
            std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        }
    }
    let photos = PhotoLibrary::load(&options.backgrounds)?;
    let bar = progress(
        (options.worlds * options.frames_per_world) as u64,
        "dataset",
    );
    let mut counts = Counts::default();
    for w in 0..options.worlds {
        let split = split_of(w, options.worlds, options.val_share, options.test_share);
        write_world(out, options, w, split, &photos, &mut counts, &bar)?;
    }
    bar.finish();
    counts.images[Split::Train as usize] += write_photos(out, &photos)?;
    write_data_yaml(
        out,
        &format!(
            "Written by towernav-sim dataset --seed {}; worlds are split, never frames.",
            options.seed
        ),
        ["images/train", "images/val", "images/test"],
    )?;
    for split in [Split::Train, Split::Val, Split::Test] {
        let c = counts.boxes[split as usize];
        eprintln!(
            "{:>5}: {:5} images, boxes A {} B {} C {} D {}",
            split.name(),
            counts.images[split as usize],
            c[0],
            c[1],
            c[2],
            c[3]
        );
    }
    Ok(())
}

#[derive(Default)]
struct Counts {
    boxes: [[usize; 4]; 3],
    images: [usize; 3],
}

/// World `w`'s sampled frames (images and labels) and its MOT sequence.
fn write_world(
    out: &Path,
    options: &DatasetOptions,
    w: usize,
    split: Split,
    photos: &PhotoLibrary,
    counts: &mut Counts,
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<()> {
    let world_seed = options.seed.wrapping_mul(1_000_003).wrapping_add(w as u64);
    let params = if options.randomize > 0.0 {
        WorldParams::cluttered()
    } else {
        WorldParams::default()
    };
    let (scenario, conditions) = Scenario::random_crossing_in(world_seed, &params);
    let renderer = scenario.renderer();
    let mut buffers = renderer.buffers();
    let mut scratch = Vec::new();
    let frames = scenario.frame_count().max(1);
    let stride = (frames / options.frames_per_world as u64).max(1);
    let name = format!("world{w:03}");
    let k = &scenario.camera.intrinsics;
    let size = (f64::from(k.width), f64::from(k.height));
    let mut truths = Vec::with_capacity(frames as usize);
    for (truth, _) in scenario.frames() {
        let seq = truth.seq;
        if seq % stride == 0 && seq / stride < options.frames_per_world as u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(world_seed ^ seq.rotate_left(29));
            let shot = if rng.random_bool(options.randomize) {
                randomized_shot(
                    &scenario,
                    &renderer,
                    &mut buffers,
                    &truth,
                    photos,
                    &mut rng,
                    &mut scratch,
                )
            } else {
                let mut look = conditions;
                look.exposure *= 1.0 + 0.05 * ((seq as f64) * 0.37).sin();
                scenario.render_into(&renderer, &mut buffers, &truth, &look);
                Shot {
                    truth: truth.clone(),
                    lens: LensEffects::default(),
                    jpeg_quality: 90,
                }
            };
            let stem = format!("{name}_{seq:05}");
            let img = out
                .join("images")
                .join(split.name())
                .join(format!("{stem}.jpg"));
            save_jpeg(&buffers.image, &img, shot.jpeg_quality)?;
            let label = out
                .join("labels")
                .join(split.name())
                .join(format!("{stem}.txt"));
            write_labels(
                &label,
                &shot.truth,
                &shot.lens,
                size,
                &mut counts.boxes[split as usize],
            )?;
            counts.images[split as usize] += 1;
            bar.inc(1);
        }
        truths.push(truth);
    }
    let seq_dir = out.join("mot").join(split.name()).join(&name);
    mot::write_sequence(&seq_dir, &name, &scenario, &truths)?;
    let towers_csv = seq_dir.join("towers.csv");
    let file = std::fs::File::create(&towers_csv)
        .with_context(|| format!("creating {}", towers_csv.display()))?;
    towernav_landmark_db::export_csv(&scenario.world.landmarks(), file)
        .with_context(|| format!("writing {}", towers_csv.display()))
}

/// Each background photo once more as a training image of its own, with an
/// empty label file: real frames with nothing to find.
fn write_photos(out: &Path, photos: &PhotoLibrary) -> anyhow::Result<usize> {
    for (i, (_, photo)) in photos.photos.iter().enumerate() {
        let stem = format!("photo{i:04}");
        let img = out.join("images").join("train").join(format!("{stem}.jpg"));
        save_jpeg(photo, &img, 92)?;
        let label = out.join("labels").join("train").join(format!("{stem}.txt"));
        std::fs::write(&label, "").with_context(|| format!("writing {}", label.display()))?;
    }
    Ok(photos.photos.len())
}

pub(crate) fn save_jpeg(image: &RgbImage, path: &Path, quality: u8) -> anyhow::Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut writer = std::io::BufWriter::new(file);
    JpegEncoder::new_with_quality(&mut writer, quality)
        .encode_image(image)
        .with_context(|| format!("writing {}", path.display()))?;
    writer
        .flush()
        .with_context(|| format!("writing {}", path.display()))
}

/// One image's YOLO labels (class, centre, size, normalized), counted per type.
pub(crate) fn write_labels(
    path: &Path,
    truth: &FrameTruth,
    lens: &LensEffects,
    (iw, ih): (f64, f64),
    counts: &mut [usize; 4],
) -> anyhow::Result<()> {
    let mut file = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    for b in truth.boxes.iter().filter(|b| b.labelled()) {
        // Random worlds hold the four rendered designs, the dataset's classes.
        let class = b.tower_type.rendered_index().with_context(|| {
            format!(
                "tower {} is of type {}, not one of A-D",
                b.tower_id, b.tower_type
            )
        })?;
        let bbox = lens.map_box(&b.bbox, iw, ih).clipped(iw, ih);
        // The lens may bend or skew a tower at the edge out of the frame.
        if bbox.width() < 1.0 || bbox.height() < 1.0 {
            continue;
        }
        writeln!(
            file,
            "{} {:.6} {:.6} {:.6} {:.6}",
            class,
            bbox.center_x() / iw,
            bbox.center_y() / ih,
            bbox.width() / iw,
            bbox.height() / ih
        )?;
        counts[class] += 1;
    }
    file.flush()
        .with_context(|| format!("writing {}", path.display()))
}

/// Ultralytics' `data.yaml`: a comment saying what wrote it, the absolute
/// root, the train, val and test folders under it, and the class names.
pub(crate) fn write_data_yaml(
    out: &Path,
    comment: &str,
    [train, val, test]: [&str; 3],
) -> anyhow::Result<()> {
    let root =
        std::fs::canonicalize(out).with_context(|| format!("resolving {}", out.display()))?;
    let names: String = TowerType::ALL
        .iter()
        .enumerate()
        .map(|(i, t)| format!("  {i}: {t}\n"))
        .collect();
    let yaml = format!(
        "# {comment}\npath: {root}\ntrain: {train}\nval: {val}\ntest: {test}\nnames:\n{names}",
        root = root.display()
    );
    let path = out.join("data.yaml");
    std::fs::write(&path, yaml).with_context(|| format!("writing {}", path.display()))
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
