//! Ultralytics-style letterbox: scale the frame to fit the model's input
//! keeping its aspect, pad with grey 114, RGB, NCHW float in 0..1.
//!
//! The model input may be rectangular (a 1280x720 frame fits a 512x320 input
//! with 16 rows of padding each side), which is a third less work than square.
//! Downscaling uses an area (box) filter, as Ultralytics' validation does, so
//! thin lattice members are averaged rather than aliased away.

use fast_image_resize::images::{Image, ImageRef};
use fast_image_resize::{FilterType, PixelType, ResizeAlg, ResizeOptions, Resizer};
use image::RgbImage;
use towernav_geometry::PixelBox;

/// How a frame maps into the model input, to map boxes back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    pub scale: f64,
    pub pad_x: f64,
    pub pad_y: f64,
    /// The model input, pixels.
    pub input_width: u32,
    pub input_height: u32,
    /// The scaled frame inside the input, pixels.
    pub inner_width: u32,
    pub inner_height: u32,
}

impl Letterbox {
    pub fn new(width: u32, height: u32, input_width: u32, input_height: u32) -> Self {
        let (w, h) = (f64::from(width.max(1)), f64::from(height.max(1)));
        let scale = (f64::from(input_width) / w).min(f64::from(input_height) / h);
        let inner_width = ((w * scale).round() as u32).clamp(1, input_width.max(1));
        let inner_height = ((h * scale).round() as u32).clamp(1, input_height.max(1));
        Self {
            scale,
            pad_x: f64::from((input_width - inner_width) / 2),
            pad_y: f64::from((input_height - inner_height) / 2),
            input_width,
            input_height,
            inner_width,
            inner_height,
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
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PreprocessError {
    #[error("frame {seq} is {width}x{height}; the detector needs at least 1x1 pixels")]
    EmptyFrame { seq: u64, width: u32, height: u32 },
    #[error("resizing frame {seq}: {reason}")]
    Resize { seq: u64, reason: String },
}

/// Turns frames into model input, reusing its buffers frame to frame.
pub struct Preprocessor {
    input_width: u32,
    input_height: u32,
    resizer: Resizer,
    resized: Image<'static>,
    input: Vec<f32>,
}

impl Preprocessor {
    pub fn new(input_width: u32, input_height: u32) -> Self {
        Self {
            input_width,
            input_height,
            resizer: Resizer::new(),
            resized: Image::new(1, 1, PixelType::U8x3),
            input: Vec::new(),
        }
    }

    /// Fill the NCHW input from `frame` (frame number `seq`, for errors);
    /// returns the mapping and the input (3 x input_height x input_width).
    pub fn run(
        &mut self,
        frame: &RgbImage,
        seq: u64,
    ) -> Result<(Letterbox, &[f32]), PreprocessError> {
        let (fw, fh) = frame.dimensions();
        if fw == 0 || fh == 0 {
            return Err(PreprocessError::EmptyFrame {
                seq,
                width: fw,
                height: fh,
            });
        }
        let lb = Letterbox::new(fw, fh, self.input_width, self.input_height);
        if self.resized.width() != lb.inner_width || self.resized.height() != lb.inner_height {
            self.resized = Image::new(lb.inner_width, lb.inner_height, PixelType::U8x3);
        }
        let resize_error = |e: &dyn std::fmt::Display| PreprocessError::Resize {
            seq,
            reason: e.to_string(),
        };
        let src =
            ImageRef::new(fw, fh, frame.as_raw(), PixelType::U8x3).map_err(|e| resize_error(&e))?;
        self.resizer
            .resize(
                &src,
                &mut self.resized,
                &ResizeOptions::new().resize_alg(ResizeAlg::Convolution(FilterType::Box)),
            )
            .map_err(|e| resize_error(&e))?;
        let (iw, ih) = (self.input_width as usize, self.input_height as usize);
        let plane = iw * ih;
        self.input.clear();
        self.input.resize(3 * plane, 114.0 / 255.0);
        let (x0, y0) = (lb.pad_x as usize, lb.pad_y as usize);
        let w = lb.inner_width as usize;
        let (r, rest) = self.input.split_at_mut(plane);
        let (g, b) = rest.split_at_mut(plane);
        for (y, row) in self.resized.buffer().chunks_exact(w * 3).enumerate() {
            let o = (y0 + y) * iw + x0;
            let (r, g, b) = (&mut r[o..o + w], &mut g[o..o + w], &mut b[o..o + w]);
            for (x, p) in row.chunks_exact(3).enumerate() {
                r[x] = f32::from(p[0]) * (1.0 / 255.0);
                g[x] = f32::from(p[1]) * (1.0 / 255.0);
                b[x] = f32::from(p[2]) * (1.0 / 255.0);
            }
        }
        Ok((lb, &self.input))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hd_frame_is_padded_top_and_bottom_and_boxes_map_back() {
        let lb = Letterbox::new(1280, 720, 640, 640);
        assert_eq!((lb.scale, lb.pad_x, lb.pad_y), (0.5, 0.0, 140.0));
        let mut pre = Preprocessor::new(640, 640);
        let frame = RgbImage::from_pixel(1280, 720, image::Rgb([255, 0, 0]));
        let (_, input) = pre.run(&frame, 0).expect("frame");
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

    #[test]
    fn a_rectangular_input_pads_only_what_the_aspect_leaves() {
        let lb = Letterbox::new(1280, 720, 512, 320);
        assert_eq!(lb.scale, 0.4);
        assert_eq!((lb.inner_width, lb.inner_height), (512, 288));
        assert_eq!((lb.pad_x, lb.pad_y), (0.0, 16.0));
        let mut pre = Preprocessor::new(512, 320);
        let mut frame = RgbImage::from_pixel(1280, 720, image::Rgb([0, 0, 0]));
        // A white bar 5 px wide (2 input pixels) survives the area filter.
        for y in 0..720 {
            for x in 600..605 {
                frame.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let (_, input) = pre.run(&frame, 7).expect("frame");
        let row = &input[(16 + 100) * 512..(16 + 101) * 512];
        let bright: f32 = row.iter().sum();
        assert!(
            (bright - 2.0).abs() < 0.05,
            "the bar's energy is kept: {bright}"
        );
        assert!((input[5 * 512] - 114.0 / 255.0).abs() < 1e-6, "top padding");
    }

    #[test]
    fn an_empty_frame_is_an_error_naming_the_frame() {
        let mut pre = Preprocessor::new(512, 320);
        let err = pre
            .run(&RgbImage::new(0, 0), 42)
            .expect_err("empty")
            .to_string();
        assert!(err.contains("frame 42"), "{err}");
    }
}
