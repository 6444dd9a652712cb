//! An appearance descriptor of a detection's crop, computed in Rust: colour,
//! a coarse luminance layout and the lattice's edge density by height band,
//! L2-normalised so that cosine distance compares them. (An ONNX
//! re-identification model can stand in for it through the same `Vec<f32>`.)

use image::RgbImage;
use towernav_geometry::PixelBox;

const COLS: usize = 4;
const ROWS: usize = 8;
/// Length of a descriptor.
pub const DIM: usize = 3 + COLS * ROWS + ROWS;

/// Descriptor of `bbox` in `image` (clamped to it); `None` if nothing of it is inside.
pub fn describe(image: &RgbImage, bbox: &PixelBox) -> Option<Vec<f32>> {
    let (w, h) = (f64::from(image.width()), f64::from(image.height()));
    let b = bbox.clipped(w, h);
    if b.width() < 1.0 || b.height() < 2.0 {
        return None;
    }
    let (x0, y0) = (b.left as u32, b.top as u32);
    let x1 = (b.right as u32).clamp(x0 + 1, image.width());
    let y1 = (b.bottom as u32).clamp(y0 + 1, image.height());
    let mut colour = [0f32; 3];
    let mut cells = [0f32; COLS * ROWS];
    let mut cell_n = [0f32; COLS * ROWS];
    let mut edges = [0f32; ROWS];
    let (cw, ch) = (
        f64::from(x1 - x0) / COLS as f64,
        f64::from(y1 - y0) / ROWS as f64,
    );
    // Sample at most ~32x64 pixels: plenty for a coarse descriptor, cheap for a big box.
    let step_x = ((x1 - x0) / 32).max(1);
    let step_y = ((y1 - y0) / 64).max(1);
    let mut n = 0f32;
    let mut y = y0;
    while y < y1 {
        let row = ((f64::from(y - y0) / ch) as usize).min(ROWS - 1);
        let mut prev_l: Option<f32> = None;
        let mut x = x0;
        while x < x1 {
            let p = image.get_pixel(x, y).0;
            let l = 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]);
            for c in 0..3 {
                colour[c] += f32::from(p[c]);
            }
            let col = ((f64::from(x - x0) / cw) as usize).min(COLS - 1);
            cells[row * COLS + col] += l;
            cell_n[row * COLS + col] += 1.0;
            if let Some(pl) = prev_l {
                edges[row] += (l - pl).abs();
            }
            prev_l = Some(l);
            n += 1.0;
            x += step_x;
        }
        y += step_y;
    }
    let mut v = Vec::with_capacity(DIM);
    let mean_l = cells.iter().sum::<f32>() / cell_n.iter().sum::<f32>().max(1.0);
    v.extend(colour.iter().map(|c| c / n.max(1.0) / 255.0));
    v.extend(
        cells
            .iter()
            .zip(&cell_n)
            .map(|(s, k)| (s / k.max(1.0) - mean_l) / 64.0),
    );
    v.extend(edges.iter().map(|e| e / n.max(1.0) * ROWS as f32 / 32.0));
    let norm = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    if norm <= f32::EPSILON {
        return None;
    }
    Some(v.into_iter().map(|x| x / norm).collect())
}

/// 1 - cosine similarity of two normalised descriptors.
pub fn cosine_distance(a: &[f32], b: &[f32]) -> f32 {
    1.0 - a.iter().zip(b).map(|(x, y)| x * y).sum::<f32>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_crop_matches_itself_and_differs_from_another() {
        let mut img = RgbImage::from_pixel(200, 100, image::Rgb([120, 160, 220]));
        for y in 20..90 {
            img.put_pixel(50, y, image::Rgb([90, 90, 90]));
            if y % 6 == 0 {
                for x in 40..60 {
                    img.put_pixel(x, y, image::Rgb([90, 90, 90]));
                }
            }
        }
        let tower = PixelBox::new(38.0, 18.0, 62.0, 92.0);
        let sky = PixelBox::new(138.0, 18.0, 162.0, 92.0);
        let a = describe(&img, &tower).expect("inside");
        assert_eq!(a.len(), DIM);
        assert!(cosine_distance(&a, &a).abs() < 1e-5);
        let b = describe(&img, &sky).expect("inside");
        assert!(cosine_distance(&a, &b) > 0.05);
        assert!(describe(&img, &PixelBox::new(300.0, 0.0, 310.0, 10.0)).is_none());
    }
}
