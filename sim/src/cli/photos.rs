//! Real tower-free photographs to draw rendered scenes over: loaded once,
//! then cropped, flipped and scaled to the frame for each use.

use std::path::{Path, PathBuf};

use anyhow::Context;
use image::RgbImage;
use image::imageops::FilterType;
use rand::Rng;

pub struct PhotoLibrary {
    pub photos: Vec<(PathBuf, RgbImage)>,
}

impl PhotoLibrary {
    /// Every JPEG and PNG directly inside each of `dirs`, in name order.
    pub fn load(dirs: &[PathBuf]) -> anyhow::Result<Self> {
        let mut photos = Vec::new();
        for dir in dirs {
            let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
                .with_context(|| format!("reading background folder {}", dir.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| is_photo(p))
                .collect();
            paths.sort();
            anyhow::ensure!(
                !paths.is_empty(),
                "background folder {} holds no .jpg, .jpeg or .png",
                dir.display()
            );
            for path in paths {
                let photo = image::open(&path)
                    .with_context(|| format!("decoding background photo {}", path.display()))?
                    .to_rgb8();
                photos.push((path, photo));
            }
        }
        Ok(Self { photos })
    }

    /// A random crop of a random photo with the frame's aspect, 40-100 % of
    /// the photo's size, mirrored half the time, scaled to `width` x `height`.
    pub fn pick(&self, rng: &mut impl Rng, width: u32, height: u32) -> Option<RgbImage> {
        if self.photos.is_empty() || width == 0 || height == 0 {
            return None;
        }
        let (_, photo) = &self.photos[rng.random_range(0..self.photos.len())];
        let (pw, ph) = (f64::from(photo.width()), f64::from(photo.height()));
        let aspect = f64::from(width) / f64::from(height);
        let (full_w, full_h) = if pw / ph > aspect {
            (ph * aspect, ph)
        } else {
            (pw, pw / aspect)
        };
        let share = rng.random_range(0.4..1.0);
        let (cw, ch) = ((full_w * share).max(1.0), (full_h * share).max(1.0));
        let x = rng.random_range(0.0..=(pw - cw).max(0.0));
        let y = rng.random_range(0.0..=(ph - ch).max(0.0));
        let crop =
            image::imageops::crop_imm(photo, x as u32, y as u32, cw as u32, ch as u32).to_image();
        let mut out = image::imageops::resize(&crop, width, height, FilterType::Triangle);
        if rng.random_bool(0.5) {
            image::imageops::flip_horizontal_in_place(&mut out);
        }
        Some(out)
    }
}

fn is_photo(p: &Path) -> bool {
    p.is_file()
        && p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "jpg" | "jpeg" | "png"))
}
