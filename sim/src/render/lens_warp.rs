//! A calibrated lens in rendered frames. The scene is drawn through an ideal
//! pinhole on a canvas wide enough for every ray the lens takes in, then each
//! output pixel samples the canvas where its undistorted ray lands. The map
//! is computed once per lens, so a frame costs one bilinear lookup a pixel,
//! and the truth boxes (projected through the same lens) fit the pixels.

use image::RgbImage;
use nalgebra::Point2;
use towernav_geometry::{Distortion, Intrinsics, PinholeCamera};

/// The largest canvas side, as a multiple of the output's: a lens wider than
/// this (a fisheye past about 140 degrees) keeps its centre and loses its rim.
const MAX_CANVAS_SCALE: f64 = 3.0;

/// The output camera's lens as a pixel map from an ideal canvas.
#[derive(Debug, Clone)]
pub struct LensWarp {
    canvas: PinholeCamera,
    width: u32,
    height: u32,
    /// Canvas coordinates (pixel index space, centres at integers) of each
    /// output pixel, row by row; NaN where the lens model has no inverse.
    map: Vec<[f32; 2]>,
}

impl LensWarp {
    /// The warp for `camera`'s lens; `None` for an ideal pinhole.
    pub fn new(camera: &PinholeCamera) -> Option<Self> {
        if camera.distortion == Distortion::None {
            return None;
        }
        let k = camera.intrinsics;
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        let ideal = |x: f64, y: f64| camera.undistort_pixel(&Point2::new(x, y));
        // The canvas spans what the frame's border sees (barrel lenses bulge
        // outwards, so the border, not the corners alone, bounds it).
        let (mut lo, mut hi) = (Point2::<f64>::new(0.0, 0.0), Point2::new(w, h));
        let steps = 64;
        for i in 0..=steps {
            let t = f64::from(i) / f64::from(steps);
            for p in [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)] {
                if let Some(q) = ideal(p.0, p.1) {
                    lo = Point2::new(lo.x.min(q.x), lo.y.min(q.y));
                    hi = Point2::new(hi.x.max(q.x), hi.y.max(q.y));
                }
            }
        }
        let margin = 2.0;
        let left = (-lo.x).min(w * (MAX_CANVAS_SCALE - 1.0) / 2.0).max(0.0) + margin;
        let top = (-lo.y).min(h * (MAX_CANVAS_SCALE - 1.0) / 2.0).max(0.0) + margin;
        let right = (hi.x - w).min(w * (MAX_CANVAS_SCALE - 1.0) / 2.0).max(0.0) + margin;
        let bottom = (hi.y - h).min(h * (MAX_CANVAS_SCALE - 1.0) / 2.0).max(0.0) + margin;
        let (left, top) = (left.ceil(), top.ceil());
        let canvas = PinholeCamera::pinhole(
            Intrinsics {
                width: (w + left + right).ceil() as u32,
                height: (h + top + bottom).ceil() as u32,
                cx: k.cx + left,
                cy: k.cy + top,
                ..k
            },
            camera.mount,
        );
        let mut map = Vec::with_capacity((k.width * k.height) as usize);
        for y in 0..k.height {
            for x in 0..k.width {
                let at = ideal(f64::from(x) + 0.5, f64::from(y) + 0.5)
                    .map_or([f32::NAN, f32::NAN], |q| {
                        [(q.x + left - 0.5) as f32, (q.y + top - 0.5) as f32]
                    });
                map.push(at);
            }
        }
        Some(Self {
            canvas,
            width: k.width,
            height: k.height,
            map,
        })
    }

    /// The ideal camera the scene is drawn through.
    pub fn canvas(&self) -> &PinholeCamera {
        &self.canvas
    }

    /// Bend `canvas` (the canvas camera's size) into `out` (the lens's size).
    pub fn apply(&self, canvas: &RgbImage, out: &mut RgbImage) {
        if out.dimensions() != (self.width, self.height) {
            *out = RgbImage::new(self.width, self.height);
        }
        let (cw, ch) = (canvas.width() as usize, canvas.height() as usize);
        let src = canvas.as_raw();
        let max_x = (cw - 1) as f32;
        let max_y = (ch - 1) as f32;
        for (px, at) in out.as_mut().chunks_exact_mut(3).zip(&self.map) {
            if at[0].is_nan() {
                px.copy_from_slice(&[0, 0, 0]);
                continue;
            }
            let x = at[0].clamp(0.0, max_x);
            let y = at[1].clamp(0.0, max_y);
            let (x0, y0) = (x.floor() as usize, y.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
            let (fx, fy) = (x - x0 as f32, y - y0 as f32);
            for (c, value) in px.iter_mut().enumerate() {
                let at = |xx: usize, yy: usize| f32::from(src[(yy * cw + xx) * 3 + c]);
                let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
                let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
                *value = (top * (1.0 - fy) + bottom * fy).round() as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;
    use towernav_geometry::CameraMount;

    fn barrel() -> PinholeCamera {
        PinholeCamera {
            distortion: Distortion::RadialTangential {
                k1: -0.28,
                k2: 0.08,
                p1: 1e-3,
                p2: -2e-3,
                k3: -0.01,
            },
            ..PinholeCamera::pinhole(
                Intrinsics::from_hfov(320, 180, 70.0),
                CameraMount::default(),
            )
        }
    }

    #[test]
    fn an_ideal_lens_needs_no_warp() {
        assert!(LensWarp::new(&PinholeCamera::default_hd()).is_none());
    }

    #[test]
    fn a_point_drawn_on_the_canvas_lands_where_the_lens_projects_it() {
        let camera = barrel();
        let warp = LensWarp::new(&camera).expect("a lens");
        let canvas_camera = warp.canvas();
        assert!(canvas_camera.intrinsics.width > camera.intrinsics.width);
        // A point near the frame's corner, where the barrel moves it most.
        let point = Point3::new(0.55, 0.3, 1.0);
        let through_lens = camera.project(&point).expect("in view");
        let on_canvas = canvas_camera.project(&point).expect("on the canvas");
        let k = canvas_camera.intrinsics;
        let mut canvas = RgbImage::new(k.width, k.height);
        let (cx, cy) = (on_canvas.x.floor() as u32, on_canvas.y.floor() as u32);
        for y in cy.saturating_sub(1)..=cy + 1 {
            for x in cx.saturating_sub(1)..=cx + 1 {
                canvas.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let mut out = RgbImage::new(1, 1);
        warp.apply(&canvas, &mut out);
        let (mut sx, mut sy, mut total) = (0.0, 0.0, 0.0);
        for (x, y, p) in out.enumerate_pixels() {
            let v = f64::from(p.0[0]);
            sx += v * (f64::from(x) + 0.5);
            sy += v * (f64::from(y) + 0.5);
            total += v;
        }
        assert!(total > 0.0, "the spot reaches the output");
        let spot = Point2::new(sx / total, sy / total);
        assert!(
            (spot - through_lens).norm() < 1.0,
            "spot at {spot:?}, the lens projects to {through_lens:?}"
        );
        // Far from where an ideal lens would put it.
        let ideal = camera.ideal().project(&point).expect("in view");
        assert!((ideal - through_lens).norm() > 5.0);
    }
}
