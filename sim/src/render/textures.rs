//! Procedural textures made once per renderer: farmland seen from above, and clouds.
//! Both tile, and carry mip levels so distant ground does not shimmer.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Added before truncation so that `as i32` floors for coordinates above
/// -65536 texels; a multiple of every texture side, so tiling is unchanged.
const FLOOR_SHIFT: f32 = 65536.0;

/// A square, tiling RGB texture with its mip chain (level 0 is the finest).
/// Sides are powers of two so that tiling is a bit mask; texels are packed
/// 8-bit RGB so the finest level (4 MB) stays cache friendly.
pub struct MipTexture {
    /// Each level's side length and texels, 0x00BBGGRR.
    levels: Vec<(usize, Vec<u32>)>,
    /// Metres per texel at level 0.
    pub texel_m: f32,
}

fn pack(c: [f32; 3]) -> u32 {
    let b = |v: f32| (v * 255.0).round().clamp(0.0, 255.0) as u32;
    b(c[0]) | (b(c[1]) << 8) | (b(c[2]) << 16)
}

/// The texel as RGB in 0..1.
#[inline]
pub fn unpack(t: u32) -> [f32; 3] {
    const S: f32 = 1.0 / 255.0;
    [
        (t & 0xff) as f32 * S,
        ((t >> 8) & 0xff) as f32 * S,
        ((t >> 16) & 0xff) as f32 * S,
    ]
}

impl MipTexture {
    fn new(side: usize, texels: Vec<[f32; 3]>, texel_m: f32) -> Self {
        assert!(
            side.is_power_of_two(),
            "texture side {side} must be a power of two"
        );
        let mut float_levels = vec![(side, texels)];
        while float_levels[float_levels.len() - 1].0 > 1 {
            let (s, prev) = &float_levels[float_levels.len() - 1];
            let half = s / 2;
            let mut next = Vec::with_capacity(half * half);
            for y in 0..half {
                for x in 0..half {
                    let mut acc = [0.0f32; 3];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let t = prev[(2 * y + dy) * s + 2 * x + dx];
                        for c in 0..3 {
                            acc[c] += t[c] * 0.25;
                        }
                    }
                    next.push(acc);
                }
            }
            float_levels.push((half, next));
        }
        let levels = float_levels
            .into_iter()
            .map(|(s, t)| (s, t.into_iter().map(pack).collect()))
            .collect();
        Self { levels, texel_m }
    }

    /// Nearest texel at ground point (x, y) metres, at the level whose texel
    /// matches `footprint_m`, the size of one pixel on the ground.
    #[inline]
    pub fn sample(&self, x: f32, y: f32, footprint_m: f32) -> u32 {
        let ratio = (footprint_m / self.texel_m).max(1.0);
        // floor(log2(ratio)) straight from the float's exponent bits.
        let level = (((ratio.to_bits() >> 23) & 0xff) as usize)
            .saturating_sub(127)
            .min(self.levels.len() - 1);
        let (side, texels) = &self.levels[level];
        let inv_scale = 1.0 / (self.texel_m * (1u32 << level) as f32);
        let mask = (*side as i32) - 1;
        // Shift to positive before truncating: a floor without a libm call.
        let ix = ((x * inv_scale + FLOOR_SHIFT) as i32 & mask) as usize;
        let iy = ((y * inv_scale + FLOOR_SHIFT) as i32 & mask) as usize;
        texels[iy * side + ix]
    }
}

/// Value noise on a `period`-tiling lattice, in 0..1.
struct Noise {
    period: usize,
    values: Vec<f32>,
}

impl Noise {
    fn new(period: usize, rng: &mut ChaCha8Rng) -> Self {
        Self {
            period,
            values: (0..period * period).map(|_| rng.random::<f32>()).collect(),
        }
    }

    /// Smoothly interpolated at (u, v) in lattice units.
    fn at(&self, u: f32, v: f32) -> f32 {
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
        let p = self.period as i64;
        let idx = |x: f32, y: f32| {
            let xi = (x as i64).rem_euclid(p) as usize;
            let yi = (y as i64).rem_euclid(p) as usize;
            self.values[yi * self.period + xi]
        };
        let a = idx(x0, y0) + (idx(x0 + 1.0, y0) - idx(x0, y0)) * sx;
        let b = idx(x0, y0 + 1.0) + (idx(x0 + 1.0, y0 + 1.0) - idx(x0, y0 + 1.0)) * sx;
        a + (b - a) * sy
    }
}

const FIELD_COLOURS: [[f32; 3]; 6] = [
    [0.33, 0.45, 0.20],
    [0.42, 0.50, 0.24],
    [0.52, 0.48, 0.30],
    [0.28, 0.38, 0.18],
    [0.58, 0.54, 0.36],
    [0.38, 0.42, 0.22],
];

/// Fields of different crops in a jittered grid, with grain and tracks between them.
pub fn farmland(seed: u64) -> MipTexture {
    const SIDE: usize = 1024;
    const FIELD: usize = 96;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let grain = Noise::new(256, &mut rng);
    let patches = Noise::new(16, &mut rng);
    let cells = SIDE / FIELD;
    let colours: Vec<[f32; 3]> = (0..cells * cells)
        .map(|_| FIELD_COLOURS[rng.random_range(0..FIELD_COLOURS.len())])
        .collect();
    let mut texels = Vec::with_capacity(SIDE * SIDE);
    for y in 0..SIDE {
        for x in 0..SIDE {
            let (cx, cy) = (x / FIELD % cells, y / FIELD % cells);
            let base = colours[cy * cells + cx];
            let edge = x % FIELD < 2 || y % FIELD < 2;
            let g = 0.8 + 0.4 * grain.at(x as f32 / 4.0, y as f32 / 4.0);
            let p = 0.85 + 0.3 * patches.at(x as f32 / 64.0, y as f32 / 64.0);
            let texel = if edge {
                [0.55, 0.50, 0.42]
            } else {
                base.map(|c| (c * g * p).min(1.0))
            };
            texels.push(texel);
        }
    }
    MipTexture::new(SIDE, texels, 0.5)
}

/// Cloud cover density in 0..1 on a tiling sheet; `coverage` is thresholded at render time.
pub struct CloudSheet {
    side: usize,
    density: Vec<f32>,
    /// Metres per texel on the cloud layer.
    pub texel_m: f32,
}

impl CloudSheet {
    pub fn new(seed: u64) -> Self {
        const SIDE: usize = 512;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xc10d);
        let octaves: Vec<(Noise, f32, f32)> = [(8, 0.55), (32, 0.3), (128, 0.15)]
            .into_iter()
            .map(|(period, weight)| {
                (
                    Noise::new(period, &mut rng),
                    period as f32 / SIDE as f32,
                    weight,
                )
            })
            .collect();
        let density = (0..SIDE * SIDE)
            .map(|i| {
                let (x, y) = ((i % SIDE) as f32, (i / SIDE) as f32);
                octaves.iter().map(|(n, f, w)| w * n.at(x * f, y * f)).sum()
            })
            .collect();
        Self {
            side: SIDE,
            density,
            texel_m: 8.0,
        }
    }

    #[inline]
    pub fn density(&self, x: f32, y: f32) -> f32 {
        let s = self.side as i64;
        let ix = ((x / self.texel_m + FLOOR_SHIFT) as i64).rem_euclid(s) as usize;
        let iy = ((y / self.texel_m + FLOOR_SHIFT) as i64).rem_euclid(s) as usize;
        self.density[iy * self.side + ix]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_levels_halve_down_to_one_texel_and_keep_the_mean() {
        let tex = farmland(1);
        assert_eq!(tex.levels.len(), 11);
        let mean = |t: &Vec<u32>| t.iter().map(|&p| unpack(p)[1]).sum::<f32>() / t.len() as f32;
        let (fine, coarse) = (&tex.levels[0].1, &tex.levels[10].1);
        assert!((mean(fine) - unpack(coarse[0])[1]).abs() < 3e-3);
        // Far away, a pixel covers many texels and sees their average.
        assert_eq!(tex.sample(3.0, 7.0, 1e6), coarse[0]);
    }
}
