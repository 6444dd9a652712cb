//! `towernav-edge detect --images DIR --out DIR`: the detector on a folder of
//! a user's own photographs, before they fly their line: every photo
//! annotated with its boxes, a contact sheet of them all, and the boxes as
//! CSV. A photo that cannot be read is listed with its reason; the others
//! go on.

use std::path::{Path, PathBuf};

use anyhow::Context;
use image::RgbImage;
use plotters::prelude::*;
use serde::Serialize;
use towernav_dataset::images_under;
use towernav_onnx::yolo::{DetectorOptions, YoloDetector};
use towernav_protocol::Detection;

use crate::cmd::loc_plots::register_font;
use crate::cmd::real_eval::load_upright;
use crate::progress::bar;

/// The contact sheet's tile width and columns.
const TILE_W: u32 = 320;
const COLUMNS: u32 = 5;
/// Tile caption band height, pixels.
const CAPTION_H: u32 = 22;

#[derive(Debug, Clone, Serialize)]
pub struct PhotoResult {
    /// Relative to the images folder.
    pub image: String,
    pub width: u32,
    pub height: u32,
    pub boxes: usize,
    pub best_score: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct DetectSummary {
    pub model: String,
    pub classes: Vec<String>,
    pub min_score: f32,
    pub photos: Vec<PhotoResult>,
    /// Photos that could not be read or run, with the reason.
    pub failed: Vec<(String, String)>,
    pub contact_sheet: PathBuf,
}

impl DetectSummary {
    pub fn with_boxes(&self) -> usize {
        self.photos.iter().filter(|p| p.boxes > 0).count()
    }
}

pub fn run(
    model: &Path,
    type_model: Option<&Path>,
    options: &DetectorOptions,
    images: &Path,
    out: &Path,
) -> anyhow::Result<DetectSummary> {
    let mut detector = YoloDetector::load_with_types(model, type_model, options)?;
    let paths = images_under(images).with_context(|| format!("listing {}", images.display()))?;
    let annotated_dir = out.join("annotated");
    std::fs::create_dir_all(&annotated_dir)
        .with_context(|| format!("creating {}", annotated_dir.display()))?;
    let csv_path = out.join("detections.csv");
    let mut csv = csv::Writer::from_path(&csv_path)
        .with_context(|| format!("creating {}", csv_path.display()))?;
    csv.write_record([
        "image", "class", "score", "x1", "y1", "x2", "y2", "width", "height",
    ])?;
    let progress = bar(paths.len() as u64, "photos");
    let mut photos = Vec::new();
    let mut failed = Vec::new();
    let mut tiles = Vec::new();
    for (seq, path) in paths.iter().enumerate() {
        progress.inc(1);
        let name = path
            .strip_prefix(images)
            .unwrap_or(path)
            .display()
            .to_string();
        let mut frame = match load_upright(path) {
            Ok(frame) => frame,
            Err(e) => {
                failed.push((name, format!("{e:#}")));
                continue;
            }
        };
        let boxes = match detector.detect(&frame, seq as u64) {
            Ok(boxes) => boxes,
            Err(e) => {
                failed.push((name, e.to_string()));
                continue;
            }
        };
        let (width, height) = frame.dimensions();
        for d in &boxes {
            let b = &d.bbox;
            csv.write_record([
                name.clone(),
                d.tower_type.to_string(),
                format!("{:.3}", d.score),
                format!("{:.1}", b.left),
                format!("{:.1}", b.top),
                format!("{:.1}", b.right),
                format!("{:.1}", b.bottom),
                width.to_string(),
                height.to_string(),
            ])?;
        }
        draw_boxes(&mut frame, &boxes)?;
        let file = annotated_dir.join(flat_name(&name));
        frame
            .save(&file)
            .with_context(|| format!("writing {}", file.display()))?;
        let best_score = boxes.iter().map(|d| d.score).reduce(f64::max);
        let caption = match best_score {
            Some(s) => format!("{name}: {} box(es), best {s:.2}", boxes.len()),
            None => format!("{name}: no box"),
        };
        tiles.push((caption, image::imageops::thumbnail(&frame, TILE_W, TILE_W)));
        photos.push(PhotoResult {
            image: name,
            width,
            height,
            boxes: boxes.len(),
            best_score,
        });
    }
    progress.finish_and_clear();
    csv.flush()
        .with_context(|| format!("writing {}", csv_path.display()))?;
    let sheet = contact_sheet(&tiles)?;
    let contact_sheet = out.join("contact-sheet.jpg");
    sheet
        .save(&contact_sheet)
        .with_context(|| format!("writing {}", contact_sheet.display()))?;
    let summary = DetectSummary {
        model: model.display().to_string(),
        classes: detector.info().classes.clone(),
        min_score: options.post.min_score,
        photos,
        failed,
        contact_sheet,
    };
    let json = out.join("detect.json");
    std::fs::write(&json, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("writing {}", json.display()))?;
    Ok(summary)
}

/// `a/b.png` as `a__b.jpg`: one flat folder of JPEGs, names kept apart.
fn flat_name(relative: &str) -> String {
    let stem = Path::new(relative).with_extension("");
    format!(
        "{}.jpg",
        stem.display().to_string().replace(['/', '\\'], "__")
    )
}

/// Each box drawn onto `image` with its class and score.
pub fn draw_boxes(image: &mut RgbImage, boxes: &[Detection]) -> anyhow::Result<()> {
    register_font()?;
    let (w, h) = image.dimensions();
    // Lines and labels that stay legible from a phone photo down to a thumbnail.
    let stroke = (w.max(h) / 400).max(2);
    let font_px = (w.max(h) / 45).max(14);
    let root = BitMapBackend::with_buffer(image.as_mut(), (w, h)).into_drawing_area();
    let colour = RGBColor(255, 40, 200);
    let font = ("sans-serif", font_px).into_font().color(&colour);
    for d in boxes {
        let b = &d.bbox;
        let (x0, y0, x1, y1) = (b.left as i32, b.top as i32, b.right as i32, b.bottom as i32);
        root.draw(&Rectangle::new(
            [(x0, y0), (x1, y1)],
            colour.stroke_width(stroke),
        ))
        .map_err(|e| anyhow::anyhow!("drawing a box: {e:?}"))?;
        let label_y = if y0 > font_px as i32 {
            y0 - font_px as i32
        } else {
            y1.min(h as i32 - font_px as i32)
        };
        root.draw(&Text::new(
            format!("{} {:.2}", d.tower_type, d.score),
            (x0, label_y),
            font.clone(),
        ))
        .map_err(|e| anyhow::anyhow!("drawing a label: {e:?}"))?;
    }
    root.present()
        .map_err(|e| anyhow::anyhow!("drawing the boxes: {e:?}"))?;
    Ok(())
}

/// Tiles (caption, thumbnail no wider or taller than `TILE_W`) on a grid of
/// `COLUMNS`, each with its caption below it.
pub fn contact_sheet(tiles: &[(String, RgbImage)]) -> anyhow::Result<RgbImage> {
    let columns = COLUMNS.min(tiles.len().max(1) as u32);
    let rows = (tiles.len() as u32).div_ceil(columns).max(1);
    let cell_h = TILE_W + CAPTION_H;
    let mut sheet = RgbImage::from_pixel(columns * TILE_W, rows * cell_h, image::Rgb([32, 32, 32]));
    for (i, (_, thumb)) in tiles.iter().enumerate() {
        let (col, row) = (i as u32 % columns, i as u32 / columns);
        let x = col * TILE_W + (TILE_W - thumb.width()) / 2;
        let y = row * cell_h + (TILE_W - thumb.height()) / 2;
        image::imageops::replace(&mut sheet, thumb, x.into(), y.into());
    }
    register_font()?;
    let (w, h) = sheet.dimensions();
    {
        let root = BitMapBackend::with_buffer(sheet.as_mut(), (w, h)).into_drawing_area();
        let font = ("sans-serif", 14).into_font().color(&WHITE);
        for (i, (caption, _)) in tiles.iter().enumerate() {
            let (col, row) = (i as u32 % columns, i as u32 / columns);
            let shown: String = caption.chars().take(44).collect();
            root.draw(&Text::new(
                shown,
                (
                    (col * TILE_W + 4) as i32,
                    (row * cell_h + TILE_W + 3) as i32,
                ),
                font.clone(),
            ))
            .map_err(|e| anyhow::anyhow!("drawing a caption: {e:?}"))?;
        }
        root.present()
            .map_err(|e| anyhow::anyhow!("drawing the contact sheet: {e:?}"))?;
    }
    Ok(sheet)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;
    use towernav_geometry::PixelBox;
    use towernav_protocol::TowerType;

    #[test]
    fn the_sheet_has_a_cell_per_photo_in_rows_of_five() {
        let tiles: Vec<(String, RgbImage)> = (0..7)
            .map(|i| {
                (
                    format!("p{i}"),
                    RgbImage::from_pixel(TILE_W, 180, Rgb([200, 0, 0])),
                )
            })
            .collect();
        let sheet = contact_sheet(&tiles).expect("draws");
        assert_eq!(sheet.dimensions(), (5 * TILE_W, 2 * (TILE_W + CAPTION_H)));
        // The seventh tile (row 2, column 2) is drawn; the eighth cell is empty.
        let cell = TILE_W + CAPTION_H;
        assert_eq!(
            sheet.get_pixel(TILE_W + TILE_W / 2, cell + TILE_W / 2),
            &Rgb([200, 0, 0])
        );
        assert_eq!(
            sheet.get_pixel(2 * TILE_W + TILE_W / 2, cell + TILE_W / 2),
            &Rgb([32, 32, 32])
        );
    }

    #[test]
    fn a_box_is_drawn_where_the_detector_put_it() {
        let mut image = RgbImage::from_pixel(400, 300, Rgb([0, 0, 0]));
        let boxes = [Detection {
            bbox: PixelBox::new(100.0, 120.0, 200.0, 280.0),
            tower_type: TowerType::new("tower").expect("a name"),
            score: 0.9,
        }];
        draw_boxes(&mut image, &boxes).expect("draws");
        assert_ne!(image.get_pixel(100, 200), &Rgb([0, 0, 0]), "left edge");
        assert_eq!(
            image.get_pixel(150, 200),
            &Rgb([0, 0, 0]),
            "inside stays clear"
        );
    }

    #[test]
    fn nested_photos_keep_apart_in_one_flat_folder() {
        assert_eq!(flat_name("a/b.png"), "a__b.jpg");
        assert_eq!(flat_name("c.JPG"), "c.jpg");
    }
}
