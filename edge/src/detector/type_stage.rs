//! The detector's second stage, pure parts: cutting each box out of the
//! full-resolution frame for the tower-type classifier, and giving the boxes
//! the types it reads.
//!
//! The detector sees the frame shrunk to its input (0.4x for 512x320), where a
//! 40 px tower's arms blur together: it finds towers far better than it tells
//! their types apart. The classifier looks again at full resolution.
//! `training/train_types.py` cuts its training crops the same way.

use image::RgbImage;
use image::imageops::FilterType;
use towernav_geometry::PixelBox;
use towernav_protocol::{Detection, TowerType};

use super::classes::ClassMap;
use super::decode::{RawDetection, nms};

/// Crop side over the box's longer edge (`PAD` in `training/train_types.py`).
pub const CROP_PAD: f64 = 1.15;
/// Outside the frame, as in the letterbox.
const GREY: [u8; 3] = [114, 114, 114];

/// The square around a box that the classifier sees: left, top, side, in
/// whole frame pixels (it may reach past the frame's edges).
pub fn crop_square(b: &PixelBox) -> (i64, i64, u32) {
    let side = CROP_PAD * b.width().max(b.height());
    let left = (b.center_x() - side / 2.0).round() as i64;
    let top = (b.center_y() - side / 2.0).round() as i64;
    (left, top, (side.round() as u32).max(1))
}

/// The crop of `b`: its square, grey past the frame, resized to `size` square.
pub fn type_crop(frame: &RgbImage, b: &PixelBox, size: u32) -> RgbImage {
    let (left, top, side) = crop_square(b);
    let (fw, fh) = (i64::from(frame.width()), i64::from(frame.height()));
    if left >= 0 && top >= 0 && left + i64::from(side) <= fw && top + i64::from(side) <= fh {
        // Inside the frame (the usual case): resize straight from it, no copy.
        let view = image::imageops::crop_imm(frame, left as u32, top as u32, side, side);
        return image::imageops::resize(&*view, size, size, FilterType::Triangle);
    }
    let mut square = RgbImage::from_pixel(side, side, image::Rgb(GREY));
    let (x0, y0) = (left.max(0), top.max(0));
    let (x1, y1) = (
        (left + i64::from(side)).min(fw),
        (top + i64::from(side)).min(fh),
    );
    if x1 > x0 && y1 > y0 {
        let part = image::imageops::crop_imm(
            frame,
            x0 as u32,
            y0 as u32,
            (x1 - x0) as u32,
            (y1 - y0) as u32,
        );
        image::imageops::replace(&mut square, &*part, x0 - left, y0 - top);
    }
    image::imageops::resize(&square, size, size, FilterType::Triangle)
}

/// Write `image` as crop `n` of an [N, 3, H, W] batch, RGB in 0..1.
pub fn write_nchw(image: &RgbImage, n: usize, batch: &mut [f32]) {
    let (w, h) = (image.width() as usize, image.height() as usize);
    for (x, y, p) in image.enumerate_pixels() {
        for c in 0..3 {
            batch[((n * 3 + c) * h + y as usize) * w + x as usize] = f32::from(p[c]) / 255.0;
        }
    }
}

/// Fill `batch` (reused frame to frame) with the crops of `boxes`.
pub fn crop_batch(frame: &RgbImage, boxes: &[PixelBox], size: u32, batch: &mut Vec<f32>) {
    let plane = 3 * (size as usize) * (size as usize);
    batch.clear();
    batch.resize(boxes.len() * plane, 0.0);
    for (n, b) in boxes.iter().enumerate() {
        write_nchw(&type_crop(frame, b, size), n, batch);
    }
}

/// Give each box the classifier's type. `probs` holds one row of class
/// probabilities per box, in `classes`' order. The score becomes the
/// detector's (how sure it is of a tower) times the type's probability, and
/// boxes the new types made duplicates of one another are suppressed.
pub fn retype(
    dets: &[Detection],
    probs: &[f32],
    classes: &ClassMap,
    nms_iou: f64,
) -> Vec<Detection> {
    let k = classes.len();
    let raw: Vec<RawDetection> = dets
        .iter()
        .zip(probs.chunks_exact(k))
        .filter_map(|(d, p)| {
            let (class, prob) = p.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
            let tower_type = classes.tower_type(class)?;
            Some(RawDetection {
                bbox: d.bbox,
                class: tower_type.index(),
                score: (d.score as f32) * prob,
            })
        })
        .collect();
    nms(raw, nms_iou)
        .into_iter()
        .map(|r| Detection {
            bbox: r.bbox,
            tower_type: TowerType::ALL[r.class],
            score: f64::from(r.score),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn classes() -> ClassMap {
        ClassMap::from_metadata(Some("{0: 'A', 1: 'B', 2: 'C', 3: 'D'}")).expect("classes")
    }

    #[test]
    fn the_crop_is_the_padded_square_around_the_box_grey_past_the_edge() {
        // Inside the frame, the crop is the frame's own pixels.
        let mut frame = RgbImage::from_pixel(200, 100, image::Rgb([10, 20, 30]));
        frame.put_pixel(60, 40, image::Rgb([200, 0, 0]));
        let inside = PixelBox::new(50.0, 30.0, 70.0, 50.0);
        let (x, y, side) = crop_square(&inside);
        let crop = type_crop(&frame, &inside, side);
        assert_eq!(
            crop.get_pixel((60 - x) as u32, (40 - y) as u32).0,
            [200, 0, 0]
        );
        assert_eq!(crop.get_pixel(0, 0).0, [10, 20, 30]);
        // A white frame: inside the frame the crop is white, past it grey.
        let frame = RgbImage::from_pixel(200, 100, image::Rgb([255, 255, 255]));
        let b = PixelBox::new(0.0, 20.0, 20.0, 60.0);
        assert_eq!(crop_square(&b), (-13, 17, 46));
        let crop = type_crop(&frame, &b, 46);
        assert_eq!(crop.get_pixel(0, 20).0, GREY, "left of the frame");
        assert_eq!(crop.get_pixel(30, 20).0, [255, 255, 255]);
    }

    #[test]
    fn the_batch_is_planar_rgb_in_unit_range() {
        let mut frame = RgbImage::from_pixel(64, 64, image::Rgb([255, 0, 51]));
        frame.put_pixel(0, 0, image::Rgb([0, 0, 0]));
        let mut batch = vec![7.0; 3];
        let b = PixelBox::new(10.0, 10.0, 30.0, 40.0);
        crop_batch(&frame, &[b, b], 8, &mut batch);
        assert_eq!(batch.len(), 2 * 3 * 64);
        let plane = 64;
        assert!((batch[3 * plane + 5] - 1.0).abs() < 1e-6, "crop 1, red");
        assert!(batch[3 * plane + plane + 5].abs() < 1e-6, "crop 1, green");
        assert!(
            (batch[3 * plane + 2 * plane + 5] - 0.2).abs() < 1e-6,
            "crop 1, blue"
        );
    }

    #[test]
    fn boxes_take_the_classifier_type_and_new_duplicates_go() {
        let b = PixelBox::new(100.0, 100.0, 120.0, 180.0);
        let shifted = PixelBox::new(101.0, 100.0, 121.0, 180.0);
        let dets = [
            Detection {
                bbox: b,
                tower_type: TowerType::C,
                score: 0.8,
            },
            // The detector's second guess at the same tower.
            Detection {
                bbox: shifted,
                tower_type: TowerType::D,
                score: 0.6,
            },
        ];
        let probs = [0.0, 0.9, 0.1, 0.0, 0.1, 0.7, 0.2, 0.0];
        let out = retype(&dets, &probs, &classes(), 0.5);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].tower_type, TowerType::B);
        assert!((out[0].score - 0.72).abs() < 1e-6);
        assert_eq!(out[0].bbox, b);
    }

    proptest! {
        #[test]
        fn the_square_holds_the_box(
            left in -50.0..1300.0f64, top in -50.0..700.0f64,
            w in 1.0..400.0f64, h in 1.0..700.0f64,
        ) {
            let b = PixelBox::new(left, top, left + w, top + h);
            let (x, y, side) = crop_square(&b);
            let side = f64::from(side);
            prop_assert!(x as f64 <= b.left + 0.5 && y as f64 <= b.top + 0.5);
            prop_assert!(x as f64 + side >= b.right - 0.5 && y as f64 + side >= b.bottom - 0.5);
            prop_assert!((side - CROP_PAD * w.max(h)).abs() <= 0.5);
        }
    }
}
