//! Ultralytics-style letterbox: scale the frame to fit the model's input
//! keeping its aspect, pad with grey 114, RGB, NCHW float in 0..1.
//!
//! The model input may be rectangular (a 1280x720 frame fits a 512x320 input
//! with 16 rows of padding each side), which is a third less work than square.
//! Downscaling uses an area (box) filter, as Ultralytics' validation does, so
//! thin lattice members are averaged rather than aliased away.
//!
//! The scaled frame may also be turned about its centre (`run_rotated`): in
//! a banked turn the towers lean by the camera's roll, and a detector trained
//! on upright towers finds them better turned back upright. The turn is done
//! on the scaled frame, a sixth of the pixels, straight into the input; boxes
//! found there are turned back by `Letterbox::to_frame`.

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
    /// How far the frame was turned clockwise (as seen on screen) about its
    /// centre before detection, radians.
    pub rotation: f64,
    /// The frame's size, pixels: its centre is the turn's.
    pub frame_width: f64,
    pub frame_height: f64,
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
            rotation: 0.0,
            frame_width: w,
            frame_height: h,
        }
    }

    /// A box in model-input pixels back in frame pixels: for a turned frame,
    /// its corners turned back and their bounds.
    pub fn to_frame(&self, b: &PixelBox) -> PixelBox {
        let unscaled = PixelBox::new(
            (b.left - self.pad_x) / self.scale,
            (b.top - self.pad_y) / self.scale,
            (b.right - self.pad_x) / self.scale,
            (b.bottom - self.pad_y) / self.scale,
        );
        if self.rotation == 0.0 {
            return unscaled;
        }
        let centre = (0.5 * self.frame_width, 0.5 * self.frame_height);
        let corners = [
            (unscaled.left, unscaled.top),
            (unscaled.right, unscaled.top),
            (unscaled.left, unscaled.bottom),
            (unscaled.right, unscaled.bottom),
        ]
        .map(|p| turn(p, centre, -self.rotation));
        let (xs, ys) = (corners.map(|c| c.0), corners.map(|c| c.1));
        PixelBox::new(
            xs.into_iter().fold(f64::INFINITY, f64::min),
            ys.into_iter().fold(f64::INFINITY, f64::min),
            xs.into_iter().fold(f64::NEG_INFINITY, f64::max),
            ys.into_iter().fold(f64::NEG_INFINITY, f64::max),
        )
    }
}

/// `p` turned clockwise on screen (x right, y down) by `angle` about `centre`.
pub fn turn(p: (f64, f64), centre: (f64, f64), angle: f64) -> (f64, f64) {
    let (sin, cos) = angle.sin_cos();
    let (dx, dy) = (p.0 - centre.0, p.1 - centre.1);
    (
        centre.0 + cos * dx - sin * dy,
        centre.1 + sin * dx + cos * dy,
    )
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
        self.run_rotated(frame, seq, 0.0)
    }

    /// `run`, with the frame turned clockwise on screen by `rotation`
    /// radians about its centre; what the turn brings in from outside the
    /// frame is grey, as the padding is.
    pub fn run_rotated(
        &mut self,
        frame: &RgbImage,
        seq: u64,
        rotation: f64,
    ) -> Result<(Letterbox, &[f32]), PreprocessError> {
        let (fw, fh) = frame.dimensions();
        if fw == 0 || fh == 0 {
            return Err(PreprocessError::EmptyFrame {
                seq,
                width: fw,
                height: fh,
            });
        }
        let rotation = if rotation.is_finite() { rotation } else { 0.0 };
        let lb = Letterbox {
            rotation,
            ..Letterbox::new(fw, fh, self.input_width, self.input_height)
        };
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
        if rotation != 0.0 {
            let inner = (w, lb.inner_height as usize);
            turn_into(
                self.resized.buffer(),
                inner,
                rotation,
                [r, g, b],
                (x0, y0, iw),
            );
            return Ok((lb, &self.input));
        }
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

/// Writes the `inner` (width, height) RGB image `src` turned clockwise by
/// `rotation` about its centre into the planes at (x0, y0) of rows `stride`
/// long: each output pixel samples the source bilinearly where the turn
/// brings it from; pixels from outside keep the planes' grey.
fn turn_into(
    src: &[u8],
    inner: (usize, usize),
    rotation: f64,
    planes: [&mut [f32]; 3],
    (x0, y0, stride): (usize, usize, usize),
) {
    let (w, h) = inner;
    let centre = (0.5 * w as f64, 0.5 * h as f64);
    let [r, g, b] = planes;
    let (sin, cos) = (-rotation).sin_cos();
    let at = |x: usize, y: usize, c: usize| f32::from(src[(y * w + x) * 3 + c]);
    for y in 0..h {
        for x in 0..w {
            // Where this output pixel's centre comes from, in source pixel centres.
            let (dx, dy) = (x as f64 + 0.5 - centre.0, y as f64 + 0.5 - centre.1);
            let sx = centre.0 + cos * dx - sin * dy - 0.5;
            let sy = centre.1 + sin * dx + cos * dy - 0.5;
            if !(sx >= 0.0 && sy >= 0.0 && sx <= (w - 1) as f64 && sy <= (h - 1) as f64) {
                continue;
            }
            let (ix, iy) = (sx as usize, sy as usize);
            let (jx, jy) = ((ix + 1).min(w - 1), (iy + 1).min(h - 1));
            let (fx, fy) = ((sx - ix as f64) as f32, (sy - iy as f64) as f32);
            let o = (y0 + y) * stride + x0 + x;
            for (c, plane) in [&mut *r, &mut *g, &mut *b].into_iter().enumerate() {
                let top = at(ix, iy, c) * (1.0 - fx) + at(jx, iy, c) * fx;
                let bottom = at(ix, jy, c) * (1.0 - fx) + at(jx, jy, c) * fx;
                plane[o] = (top * (1.0 - fy) + bottom * fy) * (1.0 / 255.0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A white square in a black frame, turned: it lands where `turn` says,
    /// and a box about it there maps back onto the square in the frame.
    #[test]
    fn a_turned_frame_puts_things_where_turn_says_and_boxes_map_back() {
        let mut frame = RgbImage::new(1280, 720);
        let (px, py) = (1000.0, 200.0);
        for y in 190..210 {
            for x in 990..1010 {
                frame.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let mut pre = Preprocessor::new(512, 320);
        let angle = 20f64.to_radians();
        let (lb, input) = pre.run_rotated(&frame, 0, angle).expect("frame");
        // The brightest input pixel, in input coordinates.
        let (mut best, mut at) = (0.0f32, (0usize, 0usize));
        for y in 0..320 {
            for x in 0..512 {
                if input[y * 512 + x] > best {
                    (best, at) = (input[y * 512 + x], (x, y));
                }
            }
        }
        assert!(best > 0.5, "the square survives the turn: {best}");
        let expected = turn((px, py), (640.0, 360.0), angle);
        let expected_in = (
            expected.0 * lb.scale + lb.pad_x,
            expected.1 * lb.scale + lb.pad_y,
        );
        assert!(
            (at.0 as f64 + 0.5 - expected_in.0).abs() < 3.0
                && (at.1 as f64 + 0.5 - expected_in.1).abs() < 3.0,
            "found at {at:?}, expected {expected_in:?}"
        );
        let found = PixelBox::new(
            at.0 as f64 - 2.0,
            at.1 as f64 - 2.0,
            at.0 as f64 + 3.0,
            at.1 as f64 + 3.0,
        );
        let back = lb.to_frame(&found);
        assert!(
            back.left < px && px < back.right && back.top < py && py < back.bottom,
            "{back:?}"
        );
        // Corners brought in from outside the frame are grey, as padding is.
        let corner = input[(lb.pad_y as usize + 1) * 512 + 1];
        assert!((corner - 114.0 / 255.0).abs() < 1e-6, "{corner}");
        // No turn: the plain letterbox, unchanged.
        let (plain, _) = pre.run(&frame, 0).expect("frame");
        assert_eq!(
            plain.to_frame(&found),
            Letterbox::new(1280, 720, 512, 320).to_frame(&found)
        );
    }

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
