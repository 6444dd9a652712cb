//! Ultralytics-style letterbox: scale the frame to fit the model's square
//! input keeping its aspect, pad with grey 114, RGB, NCHW float in 0..1.
//! The buffer is reused frame to frame.

use image::RgbImage;
use towernav_geometry::PixelBox;

/// How a frame maps into the model input, to map boxes back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    pub scale: f64,
    pub pad_x: f64,
    pub pad_y: f64,
    pub size: u32,
}

impl Letterbox {
    pub fn new(width: u32, height: u32, size: u32) -> Self {
        let scale = f64::from(size) / f64::from(width.max(height).max(1));
        let (w, h) = (
            (f64::from(width) * scale).round(),
            (f64::from(height) * scale).round(),
        );
        Self {
            scale,
            pad_x: ((f64::from(size) - w) / 2.0).floor(),
            pad_y: ((f64::from(size) - h) / 2.0).floor(),
            size,
        }
    }

    /// A box in model-input pixels back in frame pixels.
    pub fn to_frame(&self, b: &PixelBox) -> PixelBox {
        PixelBox::new(
            (b.left - self.pad_x) / self.scale,
            (b.top - self.pad_y) / self.scale,
            (b.right - self.pad_x) / self.scale,
            (b.bottom - self.pad_y) / self.scale,
        )
    }

    /// Fill `input` (resized to 3 x size x size) from `frame`, nearest-neighbour
    /// sampling (cheap, and what the detector sees is already smooth at this scale).
    pub fn fill(&self, frame: &RgbImage, input: &mut Vec<f32>) {
        let s = self.size as usize;
        input.clear();
        input.resize(3 * s * s, 114.0 / 255.0);
        let (fw, fh) = (frame.width() as usize, frame.height() as usize);
        let inv = 1.0 / self.scale;
        let (x0, y0) = (self.pad_x as usize, self.pad_y as usize);
        let w = ((fw as f64 * self.scale).round() as usize).min(s - x0);
        let h = ((fh as f64 * self.scale).round() as usize).min(s - y0);
        let raw = frame.as_raw();
        for y in 0..h {
            let sy = (((y as f64 + 0.5) * inv) as usize).min(fh - 1);
            for x in 0..w {
                let sx = (((x as f64 + 0.5) * inv) as usize).min(fw - 1);
                let i = (sy * fw + sx) * 3;
                let o = (y0 + y) * s + x0 + x;
                for c in 0..3 {
                    input[c * s * s + o] = f32::from(raw[i + c]) / 255.0;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hd_frame_is_padded_top_and_bottom_and_boxes_map_back() {
        let lb = Letterbox::new(1280, 720, 640);
        assert_eq!((lb.scale, lb.pad_x, lb.pad_y), (0.5, 0.0, 140.0));
        let frame = RgbImage::from_pixel(1280, 720, image::Rgb([255, 0, 0]));
        let mut input = Vec::new();
        lb.fill(&frame, &mut input);
        assert_eq!(input.len(), 3 * 640 * 640);
        let at = |c: usize, x: usize, y: usize| input[c * 640 * 640 + y * 640 + x];
        assert!(
            (at(0, 10, 10) - 114.0 / 255.0).abs() < 1e-6,
            "padding is grey 114"
        );
        assert_eq!(
            (at(0, 10, 320), at(1, 10, 320)),
            (1.0, 0.0),
            "the frame is RGB"
        );
        let back = lb.to_frame(&PixelBox::new(100.0, 240.0, 120.0, 340.0));
        assert_eq!(back, PixelBox::new(200.0, 200.0, 240.0, 400.0));
    }
}
