//! Which sides of a box the image's edge cuts. A cut side is where the
//! image ends, not where the tower does, so it carries no measurement.

use crate::camera::Intrinsics;
use crate::pixel_box::PixelBox;

/// A box edge this close to the image border is taken to be the border: a
/// detector's edge noise pulls a cut box's edges a few pixels inside.
pub const EDGE_MARGIN_PX: f64 = 4.0;

/// The sides of one box that the image's edge cuts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Cut {
    pub left: bool,
    pub top: bool,
    pub right: bool,
    pub bottom: bool,
}

impl Cut {
    /// The sides of `b` within [`EDGE_MARGIN_PX`] of the border of an image of
    /// `width` by `height` pixels.
    pub fn in_image(b: &PixelBox, width: f64, height: f64) -> Self {
        Self::within(b, width, height, EDGE_MARGIN_PX)
    }

    /// The sides of `b` within `margin` pixels of the border of an image of
    /// `width` by `height` pixels.
    pub fn within(b: &PixelBox, width: f64, height: f64, margin: f64) -> Self {
        let m = margin;
        Self {
            left: b.left <= m,
            top: b.top <= m,
            right: b.right >= width - m,
            bottom: b.bottom >= height - m,
        }
    }

    /// [`Self::in_image`] for the image `k` describes.
    pub fn in_frame(b: &PixelBox, k: &Intrinsics) -> Self {
        Self::in_image(b, f64::from(k.width), f64::from(k.height))
    }

    /// [`Self::within`] for the image `k` describes.
    pub fn in_frame_within(b: &PixelBox, k: &Intrinsics, margin: f64) -> Self {
        Self::within(b, f64::from(k.width), f64::from(k.height), margin)
    }

    /// The image cuts the box somewhere.
    pub fn any(self) -> bool {
        self.side() || self.end()
    }

    /// The left or right side is cut: the box's centre is not the tower's.
    pub fn side(self) -> bool {
        self.left || self.right
    }

    /// The top or bottom is cut: the box's height is not the tower's.
    pub fn end(self) -> bool {
        self.top || self.bottom
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_sides_at_the_border_are_cut() {
        let whole = Cut::in_image(&PixelBox::new(10.0, 10.0, 50.0, 90.0), 100.0, 100.0);
        assert!(!whole.any());
        let left = Cut::in_image(&PixelBox::new(2.0, 10.0, 50.0, 90.0), 100.0, 100.0);
        assert!(left.left && left.side() && !left.end());
        let foot = Cut::in_image(&PixelBox::new(10.0, 10.0, 50.0, 97.0), 100.0, 100.0);
        assert!(foot.bottom && foot.end() && !foot.side());
    }

    /// A wider margin rules more sides cut, never fewer.
    #[test]
    fn a_wider_margin_cuts_the_sides_within_it() {
        let b = PixelBox::new(30.0, 12.0, 70.0, 80.0);
        assert!(!Cut::within(&b, 100.0, 100.0, EDGE_MARGIN_PX).any());
        let wide = Cut::within(&b, 100.0, 100.0, 25.0);
        assert!(wide.top && wide.bottom && !wide.side(), "{wide:?}");
        let wider = Cut::within(&b, 100.0, 100.0, 31.0);
        assert!(wider.left && wider.right && wider.end(), "{wider:?}");
    }
}
