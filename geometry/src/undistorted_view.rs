//! The ideal pinhole camera that sees what a real lens saw, and boxes moved
//! between the two images.
//!
//! The ideal camera keeps the real one's intrinsics and image size, so
//! undistorted points near the frame's sides can fall outside its image
//! (a barrel lens pushes them out). A box side that the real frame's edge
//! cuts is put on or past the ideal image's edge, so "cut" means in the
//! ideal image what it meant in the real one; a side the lens only pushed
//! out reads as cut there too, which costs identity that side's evidence.
//! The localizer measures in the real image, where such a box is whole.

#[cfg(test)]
use nalgebra::Point2;

use crate::camera::PinholeCamera;
use crate::image_edge::EDGE_MARGIN_PX as EDGE_PX;
use crate::pixel_box::PixelBox;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UndistortedView {
    /// The real camera, lens and all.
    pub real: PinholeCamera,
    /// The ideal pinhole: the real intrinsics, no distortion.
    pub ideal: PinholeCamera,
}

impl UndistortedView {
    pub fn new(real: &PinholeCamera) -> Self {
        Self {
            real: *real,
            ideal: real.ideal(),
        }
    }

    /// A detector's box in the ideal image ([`PinholeCamera::undistort_box`]);
    /// a side that the real image's edge cuts is put on the ideal image's
    /// edge, so it still reads as cut.
    pub fn to_ideal(&self, raw: &PixelBox) -> Option<PixelBox> {
        if self.real.distortion.is_none() {
            return Some(*raw);
        }
        let mut b = self.real.undistort_box(raw)?;
        let k = &self.real.intrinsics;
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        if raw.left <= EDGE_PX {
            b.left = b.left.min(0.0);
        }
        if raw.top <= EDGE_PX {
            b.top = b.top.min(0.0);
        }
        if raw.right >= w - EDGE_PX {
            b.right = b.right.max(w);
        }
        if raw.bottom >= h - EDGE_PX {
            b.bottom = b.bottom.max(h);
        }
        Some(b)
    }

    /// An ideal-image box back on the real image, for drawing.
    pub fn to_real(&self, ideal: &PixelBox) -> PixelBox {
        if self.real.distortion.is_none() {
            return *ideal;
        }
        let r = &self.real.intrinsics;
        self.real
            .distort_box(ideal)
            .clipped(f64::from(r.width), f64::from(r.height))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CameraMount, Distortion, Intrinsics};

    fn barrel() -> PinholeCamera {
        PinholeCamera {
            intrinsics: Intrinsics::from_hfov(1280, 720, 70.0),
            mount: CameraMount::default(),
            distortion: Distortion::RadialTangential {
                k1: -0.28,
                k2: 0.08,
                p1: 0.0,
                p2: 0.0,
                k3: 0.0,
            },
        }
    }

    #[test]
    fn a_side_the_frame_cuts_stays_cut() {
        let view = UndistortedView::new(&barrel());
        let cut = view
            .to_ideal(&PixelBox::new(1250.0, 300.0, 1280.0, 500.0))
            .expect("maps");
        assert!(cut.right >= 1280.0, "{cut:?}");
        let inside = view
            .to_ideal(&PixelBox::new(600.0, 300.0, 700.0, 500.0))
            .expect("maps");
        assert!(inside.left > 4.0 && inside.right < 1276.0);
    }

    #[test]
    fn ideal_rays_are_the_real_ones() {
        let view = UndistortedView::new(&barrel());
        let raw = PixelBox::new(1000.0, 100.0, 1010.0, 400.0);
        let ideal = view.to_ideal(&raw).expect("maps");
        let real_ray = view.real.ray(&Point2::new(1005.0, 100.0));
        let ideal_ray = view.ideal.ray(&Point2::new(ideal.center_x(), ideal.top));
        assert!((real_ray.y - ideal_ray.y).abs() < 1e-9);
        let back = view.to_real(&ideal);
        assert!((back.top - raw.top).abs() < 1.5 && (back.bottom - raw.bottom).abs() < 1.5);
    }
}
