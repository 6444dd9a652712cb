//! What a cheap real lens and sensor add on top of the rendered image, for
//! training sets: colour casts, vignetting, defocus, colour fringes, radial
//! distortion, rolling-shutter skew and flare. Each is a pure function of the
//! image and its settings; boxes move with the distortion and the skew
//! through [`LensEffects::map_box`].

use image::RgbImage;
use rand::Rng;
use towernav_geometry::PixelBox;

/// One frame's lens and sensor defects; [`LensEffects::default`] is none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensEffects {
    /// Per-channel gain (white balance, dawn and dusk casts).
    pub white_balance: [f32; 3],
    /// Share of brightness lost in the corners.
    pub vignette: f32,
    /// Box-blur radius, pixels.
    pub defocus_px: u32,
    /// Red and blue pushed apart by this many pixels at the left and right edges.
    pub chroma_px: f32,
    /// Horizontal shift of the bottom row against the top one (a pan during readout), pixels.
    pub skew_px: f32,
    /// Radial distortion: an output pixel at normalized radius r (1 at the
    /// corners) shows the scene at r (1 + k r^2); negative is barrel.
    pub distortion: f32,
    /// A bright glow: centre (normalized 0..1) and strength (0..1).
    pub flare: Option<(f32, f32, f32)>,
}

impl Default for LensEffects {
    fn default() -> Self {
        Self {
            white_balance: [1.0; 3],
            vignette: 0.0,
            defocus_px: 0,
            chroma_px: 0.0,
            skew_px: 0.0,
            distortion: 0.0,
            flare: None,
        }
    }
}

impl LensEffects {
    /// A random mix: each defect present in some frames, mild to strong.
    pub fn random(rng: &mut impl Rng) -> Self {
        let mut wb = [1.0f32; 3];
        if rng.random_bool(0.5) {
            let warm: f32 = rng.random_range(-0.18..0.18);
            wb = [1.0 + warm, 1.0, 1.0 - warm];
        }
        Self {
            white_balance: wb,
            vignette: if rng.random_bool(0.5) {
                rng.random_range(0.1..0.55)
            } else {
                0.0
            },
            defocus_px: if rng.random_bool(0.25) {
                rng.random_range(1..=2)
            } else {
                0
            },
            chroma_px: if rng.random_bool(0.3) {
                rng.random_range(0.5..2.5)
            } else {
                0.0
            },
            skew_px: if rng.random_bool(0.3) {
                rng.random_range(-24.0..24.0)
            } else {
                0.0
            },
            distortion: if rng.random_bool(0.3) {
                rng.random_range(-0.12..0.06)
            } else {
                0.0
            },
            flare: rng.random_bool(0.15).then(|| {
                (
                    rng.random_range(0.0..1.0),
                    rng.random_range(0.0..0.5),
                    rng.random_range(0.2..0.7),
                )
            }),
        }
    }

    /// Apply every defect to `image`; `scratch` is reused between frames.
    pub fn apply(&self, image: &mut RgbImage, scratch: &mut Vec<u8>) {
        let (w, h) = (image.width() as usize, image.height() as usize);
        if w == 0 || h == 0 {
            return;
        }
        if self.skew_px != 0.0 || self.chroma_px != 0.0 || self.distortion != 0.0 {
            self.resample(image, scratch, w, h);
        }
        if self.defocus_px > 0 {
            box_blur(image, scratch, w, h, self.defocus_px as usize);
        }
        self.shade(image, w, h);
    }

    /// Where a box of the rendered image lies in the output: through the
    /// distortion (its edges sampled, as straight lines bend), then the skew.
    pub fn map_box(&self, b: &PixelBox, width: f64, height: f64) -> PixelBox {
        let b = if self.distortion == 0.0 {
            *b
        } else {
            let mut out = PixelBox {
                left: f64::MAX,
                top: f64::MAX,
                right: f64::MIN,
                bottom: f64::MIN,
            };
            for i in 0..=16 {
                let t = f64::from(i) / 16.0;
                let (x, y) = (b.left + t * b.width(), b.top + t * b.height());
                for (px, py) in [(x, b.top), (x, b.bottom), (b.left, y), (b.right, y)] {
                    let (dx, dy) = self.distorted(px, py, width, height);
                    out.left = out.left.min(dx);
                    out.right = out.right.max(dx);
                    out.top = out.top.min(dy);
                    out.bottom = out.bottom.max(dy);
                }
            }
            out
        };
        self.skew_box(&b, height)
    }

    /// The output pixel that shows rendered point (x, y): the inverse of
    /// [`LensEffects::undistorted`], by fixed-point iteration.
    fn distorted(&self, x: f64, y: f64, width: f64, height: f64) -> (f64, f64) {
        let (cx, cy) = (width / 2.0, height / 2.0);
        let norm2 = cx * cx + cy * cy;
        let (ux, uy) = (x - cx, y - cy);
        let (mut dx, mut dy) = (ux, uy);
        for _ in 0..20 {
            let scale = 1.0 + f64::from(self.distortion) * (dx * dx + dy * dy) / norm2;
            (dx, dy) = (ux / scale, uy / scale);
        }
        (dx + cx, dy + cy)
    }

    /// The rendered point that output pixel (x, y) shows.
    fn undistorted(&self, x: f32, y: f32, cx: f32, cy: f32) -> (f32, f32) {
        let (dx, dy) = (x - cx, y - cy);
        let scale = 1.0 + self.distortion * (dx * dx + dy * dy) / (cx * cx + cy * cy);
        (cx + dx * scale, cy + dy * scale)
    }

    /// Where a box drawn before the skew lies after it.
    fn skew_box(&self, b: &PixelBox, height: f64) -> PixelBox {
        let s = f64::from(self.skew_px) / height.max(1.0);
        let (l1, r1) = (b.left + s * b.top, b.right + s * b.top);
        let (l2, r2) = (b.left + s * b.bottom, b.right + s * b.bottom);
        PixelBox {
            left: l1.min(l2),
            top: b.top,
            right: r1.max(r2),
            bottom: b.bottom,
        }
    }

    /// Distortion, rolling-shutter skew and lateral colour, one
    /// nearest-pixel lookup per channel.
    fn resample(&self, image: &mut RgbImage, scratch: &mut Vec<u8>, w: usize, h: usize) {
        scratch.clear();
        scratch.extend_from_slice(image.as_raw());
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        let out: &mut [u8] = image;
        for y in 0..h {
            let shift = self.skew_px * y as f32 / h as f32;
            for x in 0..w {
                let (ux, uy) = self.undistorted(x as f32 - shift + 0.5, y as f32 + 0.5, cx, cy);
                let sy = (uy - 0.5).round().clamp(0.0, (h - 1) as f32) as usize;
                let spread = self.chroma_px * (ux - cx) / cx;
                for (c, push) in [(0, spread), (1, 0.0), (2, -spread)] {
                    let sx = (ux - 0.5 - push).round().clamp(0.0, (w - 1) as f32) as usize;
                    out[(y * w + x) * 3 + c] = scratch[(sy * w + sx) * 3 + c];
                }
            }
        }
    }

    /// White balance, vignetting and flare, per pixel.
    fn shade(&self, image: &mut RgbImage, w: usize, h: usize) {
        let identity = self.white_balance == [1.0; 3] && self.vignette == 0.0;
        if identity && self.flare.is_none() {
            return;
        }
        let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
        let corner2 = cx * cx + cy * cy;
        let flare = self
            .flare
            .map(|(fx, fy, s)| (fx * w as f32, fy * h as f32, s, (0.35 * w as f32).powi(2)));
        let out: &mut [u8] = image;
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                let gain = 1.0 - self.vignette * (dx * dx + dy * dy) / corner2;
                let glow = flare.map_or(0.0, |(fx, fy, s, r2)| {
                    let d2 = (x as f32 - fx).powi(2) + (y as f32 - fy).powi(2);
                    255.0 * s * (-d2 / r2).exp()
                });
                let i = (y * w + x) * 3;
                for c in 0..3 {
                    let v = f32::from(out[i + c]) * self.white_balance[c] * gain + glow;
                    out[i + c] = v.clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

/// A separable box blur of radius `r`.
fn box_blur(image: &mut RgbImage, scratch: &mut Vec<u8>, w: usize, h: usize, r: usize) {
    let n = (2 * r + 1) as u32;
    for horizontal in [true, false] {
        scratch.clear();
        scratch.extend_from_slice(image.as_raw());
        let out: &mut [u8] = image;
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let mut acc = 0u32;
                    for k in 0..=2 * r {
                        let (sx, sy) = if horizontal {
                            ((x + k).saturating_sub(r).min(w - 1), y)
                        } else {
                            (x, (y + k).saturating_sub(r).min(h - 1))
                        };
                        acc += u32::from(scratch[(sy * w + sx) * 3 + c]);
                    }
                    out[(y * w + x) * 3 + c] = (acc / n) as u8;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn column(w: u32, h: u32, at: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, _| {
            if x == at {
                image::Rgb([255, 255, 255])
            } else {
                image::Rgb([0, 0, 0])
            }
        })
    }

    #[test]
    fn skew_moves_the_bottom_rows_and_the_box_follows() {
        let mut img = column(100, 50, 40);
        let lens = LensEffects {
            skew_px: 20.0,
            ..LensEffects::default()
        };
        lens.apply(&mut img, &mut Vec::new());
        let lit = |y: u32| (0..100).find(|&x| img.get_pixel(x, y)[1] == 255);
        assert_eq!(lit(0), Some(40));
        assert_eq!(lit(49), Some(60));
        let b = lens.map_box(
            &PixelBox {
                left: 39.5,
                top: 0.0,
                right: 40.5,
                bottom: 50.0,
            },
            100.0,
            50.0,
        );
        assert!(
            (b.left - 39.5).abs() < 1e-9 && (b.right - 60.5).abs() < 1e-9,
            "{b:?}"
        );
    }

    #[test]
    fn a_distorted_box_holds_what_was_inside_it() {
        // A bright rectangle drawn in the scene; barrel distortion bends it;
        // the mapped box still holds every bright output pixel, snugly.
        let (w, h) = (160u32, 90u32);
        let inside = |x: f64, y: f64| (100.0..140.0).contains(&x) && (10.0..60.0).contains(&y);
        let mut img = RgbImage::from_fn(w, h, |x, y| {
            let v = if inside(f64::from(x) + 0.5, f64::from(y) + 0.5) {
                255
            } else {
                0
            };
            image::Rgb([v, v, v])
        });
        let lens = LensEffects {
            distortion: -0.12,
            ..LensEffects::default()
        };
        lens.apply(&mut img, &mut Vec::new());
        let b = lens.map_box(
            &PixelBox {
                left: 100.0,
                top: 10.0,
                right: 140.0,
                bottom: 60.0,
            },
            f64::from(w),
            f64::from(h),
        );
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for (x, y, p) in img.enumerate_pixels() {
            if p[1] == 255 {
                let (x, y) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                lo = (lo.0.min(x), lo.1.min(y));
                hi = (hi.0.max(x), hi.1.max(y));
            }
        }
        assert!(b.right > 140.0, "barrel moves the edge outward: {b:?}");
        for (got, want) in [
            (lo.0, b.left),
            (lo.1, b.top),
            (hi.0, b.right),
            (hi.1, b.bottom),
        ] {
            assert!(
                (got - want).abs() <= 1.5,
                "pixels {lo:?}..{hi:?}, box {b:?}"
            );
        }
    }

    #[test]
    fn vignetting_darkens_corners_not_the_centre() {
        let mut img = RgbImage::from_pixel(64, 48, image::Rgb([200, 200, 200]));
        LensEffects {
            vignette: 0.5,
            ..LensEffects::default()
        }
        .apply(&mut img, &mut Vec::new());
        assert!(img.get_pixel(32, 24)[0] >= 198);
        assert!(img.get_pixel(0, 0)[0] <= 105);
    }

    #[test]
    fn defocus_spreads_a_line_and_keeps_its_energy() {
        let mut img = column(21, 5, 10);
        LensEffects {
            defocus_px: 2,
            ..LensEffects::default()
        }
        .apply(&mut img, &mut Vec::new());
        let row: Vec<u32> = (0..21).map(|x| u32::from(img.get_pixel(x, 2)[0])).collect();
        assert_eq!(row[10], 51);
        assert_eq!(row[8], 51);
        assert_eq!(row[7], 0);
    }
}
