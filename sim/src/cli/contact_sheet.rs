//! `towernav-sim render --randomized N`: a contact sheet of what the
//! randomized dataset draws, labels outlined, for a person to judge.

use std::path::{Path, PathBuf};

use anyhow::Context;
use image::RgbImage;
use image::imageops::FilterType;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use towernav_sim::world::WorldParams;
use towernav_sim::{Scenario, TruthBox};

use crate::cli::dataset::randomized_shot;
use crate::cli::overlay::draw_boxes;
use crate::cli::photos::PhotoLibrary;

const COLUMNS: u32 = 6;
const TILE: (u32, u32) = (320, 180);

/// `count` randomized frames from worlds drawn from `seed`, in one PNG.
pub fn write(out: &Path, count: usize, seed: u64, backgrounds: &[PathBuf]) -> anyhow::Result<()> {
    anyhow::ensure!(count >= 1, "--randomized needs at least one frame");
    let photos = PhotoLibrary::load(backgrounds)?;
    let rows = (count as u32).div_ceil(COLUMNS);
    let mut sheet = RgbImage::new(COLUMNS * TILE.0, rows * TILE.1);
    let mut scratch = Vec::new();
    for i in 0..count {
        let world_seed = seed.wrapping_mul(7919).wrapping_add(i as u64);
        let (scenario, _) = Scenario::random_crossing_in(world_seed, &WorldParams::cluttered());
        let renderer = scenario.renderer();
        let mut buffers = renderer.buffers();
        let mut rng = ChaCha8Rng::seed_from_u64(world_seed);
        let seq = (i as u64 * 37) % scenario.frame_count().max(1);
        let flight = scenario.truth(seq);
        let shot = randomized_shot(
            &scenario,
            &renderer,
            &mut buffers,
            &flight,
            &photos,
            &mut rng,
            &mut scratch,
        );
        let (width, height) = (
            f64::from(buffers.image.width()),
            f64::from(buffers.image.height()),
        );
        let labelled: Vec<TruthBox> = shot
            .truth
            .boxes
            .iter()
            .filter(|b| b.labelled())
            .map(|b| TruthBox {
                bbox: shot.lens.map_box(&b.bbox, width, height),
                ..b.clone()
            })
            .collect();
        let mut frame = buffers.image.clone();
        draw_boxes(&mut frame, &labelled);
        let tile = image::imageops::resize(&frame, TILE.0, TILE.1, FilterType::Triangle);
        let (x, y) = ((i as u32 % COLUMNS) * TILE.0, (i as u32 / COLUMNS) * TILE.1);
        image::imageops::replace(&mut sheet, &tile, i64::from(x), i64::from(y));
    }
    sheet
        .save(out)
        .with_context(|| format!("writing {}", out.display()))
}
