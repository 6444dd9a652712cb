//! Truth boxes drawn onto a frame, for people to look at.

use image::{Rgb, RgbImage};
use towernav_protocol::TowerType;
use towernav_sim::TruthBox;

/// Box colour per tower type; the README's legend uses the same.
pub fn type_colour(t: TowerType) -> Rgb<u8> {
    match t {
        TowerType::A => Rgb([255, 64, 64]),
        TowerType::B => Rgb([255, 220, 0]),
        TowerType::C => Rgb([0, 220, 255]),
        TowerType::D => Rgb([255, 0, 255]),
        _ => Rgb([255, 255, 255]),
    }
}

/// Outline each box two pixels wide, clipped to the image; dashed when the
/// image edge cuts the tower.
pub fn draw_boxes(image: &mut RgbImage, boxes: &[TruthBox]) {
    let (w, h) = (image.width() as i64, image.height() as i64);
    for b in boxes {
        let colour = type_colour(b.tower_type);
        let (l, t) = (b.bbox.left.round() as i64, b.bbox.top.round() as i64);
        let (r, btm) = (b.bbox.right.round() as i64, b.bbox.bottom.round() as i64);
        let mut put = |x: i64, y: i64, i: i64| {
            if (0..w).contains(&x) && (0..h).contains(&y) && (!b.truncated || (i / 6) % 2 == 0) {
                image.put_pixel(x as u32, y as u32, colour);
            }
        };
        for k in 0..2 {
            for x in l..=r {
                put(x, t + k, x);
                put(x, btm - k, x);
            }
            for y in t..=btm {
                put(l + k, y, y);
                put(r - k, y, y);
            }
        }
    }
}
