//! Background tiles from a local folder in the slippy-map layout
//! (`<dir>/<zoom>/<x>/<y>.png`, as tile downloaders and `gdal2tiles --xyz` write
//! them). Nothing is fetched: without a folder the map keeps its plain grid.

use std::path::{Path, PathBuf};

use egui_plot::{PlotImage, PlotPoint, PlotUi};
use towernav_geometry::web_mercator::{tile_corner, tile_of};
use towernav_geometry::{Datum, Geodetic};

/// Tiles farther than this from the datum are not loaded.
const RADIUS_M: f64 = 3000.0;
/// At most this many tiles are loaded (a 3 km radius at zoom 16 is about 100).
const MAX_TILES: usize = 400;

#[derive(Debug, thiserror::Error)]
pub enum TileError {
    #[error("tile folder {0}: not a folder")]
    NotAFolder(PathBuf),
    #[error("tile folder {dir}: no zoom level folder (0 to 19) with tiles")]
    NoZoom { dir: PathBuf },
}

struct LoadedTile {
    center: PlotPoint,
    size: egui::Vec2,
    texture: egui::TextureHandle,
}

pub struct TileLayer {
    dir: PathBuf,
    zoom: u8,
    datum: Datum,
    loaded: Option<Vec<LoadedTile>>,
}

impl TileLayer {
    /// Uses the deepest zoom level the folder has.
    pub fn open(dir: &Path, datum: Datum) -> Result<Self, TileError> {
        if !dir.is_dir() {
            return Err(TileError::NotAFolder(dir.into()));
        }
        let zoom = (0..=19u8)
            .rev()
            .find(|z| dir.join(z.to_string()).is_dir())
            .ok_or_else(|| TileError::NoZoom { dir: dir.into() })?;
        Ok(Self {
            dir: dir.into(),
            zoom,
            datum,
            loaded: None,
        })
    }

    fn en(&self, lat_deg: f64, lon_deg: f64) -> [f64; 2] {
        let p = self.datum.to_enu(&Geodetic {
            lat_deg,
            lon_deg,
            height_m: self.datum.origin.height_m,
        });
        [p.x, p.y]
    }

    fn load(&self, ctx: &egui::Context) -> Vec<LoadedTile> {
        let o = self.datum.origin;
        let (cx, cy) = tile_of(o.lat_deg, o.lon_deg, self.zoom);
        let (lat0, lon0) = tile_corner(cx, cy, self.zoom);
        let (lat1, lon1) = tile_corner(cx + 1, cy + 1, self.zoom);
        let [w, h] = {
            let (a, b) = (self.en(lat0, lon0), self.en(lat1, lon1));
            [(b[0] - a[0]).abs(), (a[1] - b[1]).abs()]
        };
        let reach = (RADIUS_M / w.min(h).max(1.0)).ceil() as i64;
        let mut tiles = Vec::new();
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                let (Ok(x), Ok(y)) = (
                    u32::try_from(i64::from(cx) + dx),
                    u32::try_from(i64::from(cy) + dy),
                ) else {
                    continue;
                };
                let path = self
                    .dir
                    .join(self.zoom.to_string())
                    .join(x.to_string())
                    .join(format!("{y}.png"));
                let Ok(img) = image::open(&path) else {
                    continue; // A tile the folder lacks stays grid.
                };
                let rgba = img.to_rgba8();
                let size = [rgba.width() as usize, rgba.height() as usize];
                let color = egui::ColorImage::from_rgba_unmultiplied(size, rgba.as_raw());
                let (lat_a, lon_a) = tile_corner(x, y, self.zoom);
                let (lat_b, lon_b) = tile_corner(x + 1, y + 1, self.zoom);
                let (a, b) = (self.en(lat_a, lon_a), self.en(lat_b, lon_b));
                tiles.push(LoadedTile {
                    center: PlotPoint::new(0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])),
                    size: egui::vec2((b[0] - a[0]).abs() as f32, (a[1] - b[1]).abs() as f32),
                    texture: ctx.load_texture(
                        format!("tile {}/{x}/{y}", self.zoom),
                        color,
                        egui::TextureOptions::LINEAR,
                    ),
                });
                if tiles.len() >= MAX_TILES {
                    return tiles;
                }
            }
        }
        tracing::info!(tiles = tiles.len(), zoom = self.zoom, dir = %self.dir.display(), "map tiles loaded");
        tiles
    }

    pub fn draw(&mut self, plot: &mut PlotUi<'_>) {
        if self.loaded.is_none() {
            self.loaded = Some(self.load(plot.ctx()));
        }
        for t in self.loaded.iter().flatten() {
            plot.image(PlotImage::new("tiles", t.texture.id(), t.center, t.size));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_without_zoom_levels_is_refused_with_its_path() {
        let dir = tempfile::tempdir().expect("tempdir");
        let datum = Datum::new(Geodetic {
            lat_deg: 30.0,
            lon_deg: 114.0,
            height_m: 0.0,
        });
        let err = TileLayer::open(dir.path(), datum).err().expect("no zoom");
        assert!(err.to_string().contains("no zoom level"), "{err}");
        std::fs::create_dir_all(dir.path().join("16").join("1")).expect("mkdir");
        assert_eq!(TileLayer::open(dir.path(), datum).expect("open").zoom, 16);
    }
}
