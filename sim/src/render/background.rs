//! Sky and ground for every pixel: ray through the pixel, flat ground plane at
//! z = 0, a cloud layer above, haze by distance.

use nalgebra::Isometry3;
use towernav_geometry::{CameraMount, Intrinsics, PinholeCamera};

use super::Backdrop;
use super::conditions::Conditions;
use super::textures::{CloudSheet, MipTexture, unpack};

const CLOUD_BASE_M: f32 = 900.0;

/// Fill `rgba` (premultiplied, opaque) with sky and ground as seen from
/// `world_from_camera`. Both are smooth at pixel scale, so they are computed at
/// half resolution into `half` and upsampled; towers are drawn on top at full resolution.
pub fn draw(
    rgba: &mut [u8],
    half: &mut Vec<u8>,
    k: &Intrinsics,
    world_from_camera: &Isometry3<f64>,
    conditions: &Conditions,
    ground: &MipTexture,
    clouds: &CloudSheet,
) {
    let (w, h) = (k.width as usize, k.height as usize);
    let half_camera = PinholeCamera::pinhole(k.scaled(0.5), CameraMount::default());
    let (hw, hh) = (
        half_camera.intrinsics.width as usize,
        half_camera.intrinsics.height as usize,
    );
    half.resize(hw * hh * 4, 0);
    draw_full(
        half,
        &half_camera,
        world_from_camera,
        conditions,
        ground,
        clouds,
    );
    upsample_2x(half, hw, hh, rgba, w, h);
}

/// Bilinear 2x upsampling: each output pixel mixes its nearest source pixel
/// 3:1 with the next one toward it, along each axis.
fn upsample_2x(src: &[u8], sw: usize, sh: usize, dst: &mut [u8], w: usize, h: usize) {
    let mut rows = [vec![0u16; w * 4], vec![0u16; w * 4]];
    let widen = |sy: usize, row: &mut Vec<u16>| {
        let line = &src[sy * sw * 4..(sy + 1) * sw * 4];
        for x in 0..w {
            let near = x / 2;
            let other = if x % 2 == 0 {
                near.saturating_sub(1)
            } else {
                (near + 1).min(sw - 1)
            };
            for c in 0..4 {
                row[x * 4 + c] = 3 * u16::from(line[near * 4 + c]) + u16::from(line[other * 4 + c]);
            }
        }
    };
    let mut cached = [usize::MAX, usize::MAX];
    for y in 0..h {
        let near = y / 2;
        let other = if y % 2 == 0 {
            near.saturating_sub(1)
        } else {
            (near + 1).min(sh - 1)
        };
        for (slot, sy) in [near, other].into_iter().enumerate() {
            if cached[slot] != sy {
                if cached[1 - slot] == sy {
                    rows.swap(0, 1);
                    cached.swap(0, 1);
                } else {
                    widen(sy, &mut rows[slot]);
                    cached[slot] = sy;
                }
            }
        }
        let out = &mut dst[y * w * 4..(y + 1) * w * 4];
        for (i, o) in out.iter_mut().enumerate() {
            *o = ((3 * u32::from(rows[0][i]) + u32::from(rows[1][i]) + 8) >> 4) as u8;
        }
    }
}

fn draw_full(
    rgba: &mut [u8],
    camera: &PinholeCamera,
    world_from_camera: &Isometry3<f64>,
    conditions: &Conditions,
    ground: &MipTexture,
    clouds: &CloudSheet,
) {
    let k = &camera.intrinsics;
    let grid = camera.ray_grid(world_from_camera);
    let (d0, du, dv) = (grid.at_origin, grid.per_u, grid.per_v);
    let eye = world_from_camera.translation.vector;
    let (ex, ey, ez) = (eye.x as f32, eye.y as f32, (eye.z as f32).max(0.1));
    let sun = conditions.sun_in_world();
    let light = conditions.daylight();
    let haze = conditions.haze_colour();
    let ground_light = light * (0.55 + 0.45 * sun[2].max(0.0));
    let inv_visibility = if conditions.visibility_m.is_finite() && conditions.visibility_m > 0.0 {
        (1.0 / conditions.visibility_m) as f32
    } else {
        0.0
    };
    let zenith = [0.30 * light, 0.48 * light, 0.80 * light];
    let cover = conditions.cloud_cover.clamp(0.0, 1.0) as f32;
    let pixel_angle = (1.0 / k.fx) as f32;
    let width = k.width as usize;
    for (row, line) in rgba.chunks_exact_mut(width * 4).enumerate() {
        let start = d0 + dv * (row as f64 + 0.5) + du * 0.5;
        let (mut dx, mut dy, mut dz) = (start.x as f32, start.y as f32, start.z as f32);
        let (sx, sy, sz) = (du.x as f32, du.y as f32, du.z as f32);
        for px in line.chunks_exact_mut(4) {
            let len = (dx * dx + dy * dy + dz * dz).sqrt();
            let colour = if dz < -1e-6 {
                let t = -ez / dz;
                let (gx, gy) = (ex + t * dx, ey + t * dy);
                let dist = t * len;
                let grazing = (-dz / len).max(0.02);
                let tex = unpack(ground.sample(gx, gy, dist * pixel_angle / grazing.sqrt()));
                let keep = if inv_visibility > 0.0 {
                    (-dist * inv_visibility).exp()
                } else {
                    1.0
                };
                [0, 1, 2].map(|c| tex[c] * ground_light * keep + haze[c] * (1.0 - keep))
            } else {
                let up = (dz / len).max(0.0);
                let blend = up.sqrt();
                let mut sky = [0, 1, 2].map(|c| haze[c] + (zenith[c] - haze[c]) * blend);
                let toward_sun = (dx * sun[0] + dy * sun[1] + dz * sun[2]) / len;
                let g2 = toward_sun.max(0.0) * toward_sun.max(0.0);
                let g8 = g2 * g2 * g2 * g2;
                let glow = g8 * g8 * 0.35;
                if cover > 0.0 && up > 0.01 {
                    let t = (CLOUD_BASE_M - ez) / dz;
                    let d = clouds.density(ex + t * dx, ey + t * dy);
                    let alpha = ((d - (1.0 - cover)) * 4.0).clamp(0.0, 1.0) * (up * 8.0).min(1.0);
                    let white = 0.95 * light;
                    sky = sky.map(|s| s + (white - s) * alpha);
                }
                sky.map(|s| s + glow)
            };
            px[0] = to_u8(colour[0]);
            px[1] = to_u8(colour[1]);
            px[2] = to_u8(colour[2]);
            px[3] = 255;
            dx += sx;
            dy += sy;
            dz += sz;
        }
    }
}

/// Put `backdrop`'s photo where the ground is (every pixel whose ray points
/// down), hazed by the ground's distance like the drawn one; or over the
/// whole frame, as it is.
pub fn paste(
    rgba: &mut [u8],
    camera: &PinholeCamera,
    world_from_camera: &Isometry3<f64>,
    conditions: &Conditions,
    backdrop: &Backdrop<'_>,
) {
    let k = &camera.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    let photo = backdrop.photo;
    if photo.width() as usize != w || photo.height() as usize != h {
        return;
    }
    let grid = camera.ray_grid(world_from_camera);
    let ez = world_from_camera.translation.vector.z.max(0.1);
    let haze = conditions.haze_colour().map(|c| c * 255.0);
    let src = photo.as_raw();
    for y in 0..h {
        for x in 0..w {
            let d = grid.at_origin + grid.per_v * (y as f64 + 0.5) + grid.per_u * (x as f64 + 0.5);
            let keep = if backdrop.whole_frame {
                1.0
            } else if d.z < -1e-6 {
                conditions.transmittance(ez / -d.z * d.norm())
            } else {
                continue;
            };
            let (i, o) = ((y * w + x) * 3, (y * w + x) * 4);
            for c in 0..3 {
                let v = f32::from(src[i + c]) * keep + haze[c] * (1.0 - keep);
                rgba[o + c] = v.clamp(0.0, 255.0) as u8;
            }
        }
    }
}

#[inline]
pub fn to_u8(c: f32) -> u8 {
    (c * 255.0).clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upsampling_keeps_flat_areas_and_blends_edges() {
        let (sw, sh) = (4, 2);
        let mut src = vec![0u8; sw * sh * 4];
        for y in 0..sh {
            for x in 2..sw {
                src[(y * sw + x) * 4] = 200;
            }
        }
        let mut dst = vec![0u8; 8 * 4 * 4];
        upsample_2x(&src, sw, sh, &mut dst, 8, 4);
        let red: Vec<u8> = (0..8).map(|x| dst[(8 + x) * 4]).collect();
        assert_eq!(red[0], 0);
        assert_eq!(red[7], 200);
        assert!(
            red[3] > 0 && red[3] < 100 && red[4] > 100 && red[4] < 200,
            "{red:?}"
        );
    }
}
