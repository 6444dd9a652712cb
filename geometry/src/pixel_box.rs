//! Axis-aligned boxes in image pixels, as detectors and trackers use them.

use serde::{Deserialize, Serialize};

/// A box in pixels: `left <= right`, `top <= bottom`, y grows downwards.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PixelBox {
    pub left: f64,
    pub top: f64,
    pub right: f64,
    pub bottom: f64,
}

impl PixelBox {
    pub fn new(left: f64, top: f64, right: f64, bottom: f64) -> Self {
        Self {
            left: left.min(right),
            top: top.min(bottom),
            right: left.max(right),
            bottom: top.max(bottom),
        }
    }

    /// The smallest box holding every point; `None` for no points.
    /// (Folding from an "empty" infinite box does not work: `new` orders its edges.)
    pub fn enclosing(points: impl IntoIterator<Item = nalgebra::Point2<f64>>) -> Option<Self> {
        let mut it = points.into_iter();
        let first = it.next()?;
        let (mut l, mut t, mut r, mut b) = (first.x, first.y, first.x, first.y);
        for p in it {
            (l, t, r, b) = (l.min(p.x), t.min(p.y), r.max(p.x), b.max(p.y));
        }
        Some(Self::new(l, t, r, b))
    }

    pub fn width(&self) -> f64 {
        self.right - self.left
    }

    pub fn height(&self) -> f64 {
        self.bottom - self.top
    }

    pub fn area(&self) -> f64 {
        self.width().max(0.0) * self.height().max(0.0)
    }

    pub fn center_x(&self) -> f64 {
        0.5 * (self.left + self.right)
    }

    pub fn center_y(&self) -> f64 {
        0.5 * (self.top + self.bottom)
    }

    pub fn is_finite(&self) -> bool {
        self.left.is_finite()
            && self.top.is_finite()
            && self.right.is_finite()
            && self.bottom.is_finite()
    }

    /// The area both boxes cover.
    pub fn intersection_area(&self, other: &PixelBox) -> f64 {
        let w = (self.right.min(other.right) - self.left.max(other.left)).max(0.0);
        let h = (self.bottom.min(other.bottom) - self.top.max(other.top)).max(0.0);
        w * h
    }

    /// Intersection over union; 0 for disjoint or empty boxes.
    pub fn iou(&self, other: &PixelBox) -> f64 {
        let inter = self.intersection_area(other);
        let union = self.area() + other.area() - inter;
        if union <= 0.0 { 0.0 } else { inter / union }
    }

    /// The smallest box around both.
    pub fn union(&self, other: &PixelBox) -> PixelBox {
        PixelBox {
            left: self.left.min(other.left),
            top: self.top.min(other.top),
            right: self.right.max(other.right),
            bottom: self.bottom.max(other.bottom),
        }
    }

    /// The part inside a `width` x `height` image.
    pub fn clipped(&self, width: f64, height: f64) -> PixelBox {
        PixelBox {
            left: self.left.clamp(0.0, width),
            top: self.top.clamp(0.0, height),
            right: self.right.clamp(0.0, width),
            bottom: self.bottom.clamp(0.0, height),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn iou_of_half_overlap() {
        let a = PixelBox::new(0.0, 0.0, 10.0, 10.0);
        let b = PixelBox::new(5.0, 0.0, 15.0, 10.0);
        assert!((a.iou(&b) - 50.0 / 150.0).abs() < 1e-12);
        assert_eq!(a.iou(&PixelBox::new(20.0, 20.0, 30.0, 30.0)), 0.0);
    }

    fn any_box() -> impl Strategy<Value = PixelBox> {
        (0.0f64..1000.0, 0.0f64..1000.0, 0.0f64..300.0, 0.0f64..300.0)
            .prop_map(|(x, y, w, h)| PixelBox::new(x, y, x + w, y + h))
    }

    proptest! {
        #[test]
        fn iou_is_symmetric_and_bounded(a in any_box(), b in any_box()) {
            let ab = a.iou(&b);
            prop_assert!((ab - b.iou(&a)).abs() < 1e-12);
            prop_assert!((0.0..=1.0 + 1e-12).contains(&ab));
        }

        #[test]
        fn clipped_box_lies_inside_the_image(b in any_box()) {
            let c = b.clipped(640.0, 480.0);
            prop_assert!(c.left >= 0.0 && c.right <= 640.0 && c.top >= 0.0 && c.bottom <= 480.0);
            prop_assert!(c.area() <= b.area() + 1e-9);
        }
    }

    #[test]
    fn enclosing_holds_its_points() {
        use nalgebra::Point2;
        let b = PixelBox::enclosing([
            Point2::new(5.0, 7.0),
            Point2::new(1.0, 9.0),
            Point2::new(3.0, 2.0),
        ])
        .expect("points");
        assert_eq!(b, PixelBox::new(1.0, 2.0, 5.0, 9.0));
        assert!(PixelBox::enclosing(std::iter::empty()).is_none());
    }
}
