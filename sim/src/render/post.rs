//! What the sensor does to the optical image: motion blur over the shutter
//! time, exposure, clipping and per-pixel noise.

use image::RgbImage;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Average `taps` samples along `shift_px` (centred), in place via `scratch`.
pub fn motion_blur(rgba: &mut [u8], scratch: &mut Vec<u8>, width: usize, shift_px: (f64, f64)) {
    let len = shift_px.0.hypot(shift_px.1);
    if len < 0.75 {
        return;
    }
    let taps = (len.ceil() as usize + 1).clamp(2, 9);
    let height = rgba.len() / 4 / width;
    let offsets: Vec<(isize, isize)> = (0..taps)
        .map(|i| {
            let s = i as f64 / (taps - 1) as f64 - 0.5;
            (
                (shift_px.0 * s).round() as isize,
                (shift_px.1 * s).round() as isize,
            )
        })
        .collect();
    scratch.clear();
    scratch.extend_from_slice(rgba);
    let (w, h) = (width as isize, height as isize);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0u32; 3];
            for &(ox, oy) in &offsets {
                let sx = (x + ox).clamp(0, w - 1);
                let sy = (y + oy).clamp(0, h - 1);
                let i = ((sy * w + sx) * 4) as usize;
                acc[0] += u32::from(scratch[i]);
                acc[1] += u32::from(scratch[i + 1]);
                acc[2] += u32::from(scratch[i + 2]);
            }
            let o = ((y * w + x) * 4) as usize;
            for c in 0..3 {
                rgba[o + c] = (acc[c] / taps as u32) as u8;
            }
        }
    }
}

/// Standard-normal samples, drawn once; each frame reads them from a seeded
/// offset with a stride, which is far cheaper than a generator per pixel.
pub struct NoiseTable {
    values: Vec<f32>,
}

const NOISE_LEN: usize = 1 << 16;

impl NoiseTable {
    pub fn new(seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5e75_0a15);
        Self {
            values: (0..NOISE_LEN)
                .map(|_| rng.sample::<f32, _>(StandardNormal))
                .collect(),
        }
    }
}

/// Exposure, noise and clipping from opaque RGBA into RGB.
pub fn develop(
    rgba: &[u8],
    out: &mut RgbImage,
    exposure: f64,
    noise_sigma: f64,
    table: &NoiseTable,
    seed: u64,
) {
    let gain = (exposure.max(0.0) * 256.0) as u32;
    if noise_sigma <= 0.0 {
        let dst: &mut [u8] = out;
        for (o, i) in dst.chunks_exact_mut(3).zip(rgba.chunks_exact(4)) {
            for c in 0..3 {
                o[c] = ((u32::from(i[c]) * gain) >> 8).min(255) as u8;
            }
        }
        return;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let sigma = noise_sigma as f32;
    let mask = NOISE_LEN - 1;
    // An odd stride visits every entry before repeating; restart each row at a new offset.
    let stride = (rng.next_u32() as usize | 1) & mask;
    let width = (out.width() as usize).max(1);
    let dst: &mut [u8] = out;
    for (o_row, i_row) in dst.chunks_mut(width * 3).zip(rgba.chunks(width * 4)) {
        let mut k = rng.next_u32() as usize & mask;
        for (o, i) in o_row.chunks_exact_mut(3).zip(i_row.chunks_exact(4)) {
            for c in 0..3 {
                let v = ((u32::from(i[c]) * gain) >> 8) as f32 + sigma * table.values[k];
                k = (k + stride) & mask;
                o[c] = v.clamp(0.0, 255.0) as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_has_the_asked_spread_and_no_bias() {
        let grey = vec![128u8; 4 * 200 * 100];
        let mut out = RgbImage::new(200, 100);
        develop(&grey, &mut out, 1.0, 4.0, &NoiseTable::new(1), 9);
        let values: Vec<f64> = out.as_raw().iter().map(|&v| f64::from(v)).collect();
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let sd =
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64).sqrt();
        assert!((mean - 128.0).abs() < 0.6, "mean {mean}");
        assert!((sd - 4.0).abs() < 0.4, "sd {sd}");
    }

    #[test]
    fn blur_spreads_a_bright_column_along_the_motion() {
        let (w, h) = (20usize, 4usize);
        let mut rgba = vec![0u8; 4 * w * h];
        for y in 0..h {
            rgba[(y * w + 10) * 4] = 255;
        }
        let mut scratch = Vec::new();
        motion_blur(&mut rgba, &mut scratch, w, (4.0, 0.0));
        let row: Vec<u8> = (0..w).map(|x| rgba[(w + x) * 4]).collect();
        assert!(row[10] < 255 && row[8] > 0 && row[12] > 0, "{row:?}");
        assert_eq!(row[5], 0);
    }
}
