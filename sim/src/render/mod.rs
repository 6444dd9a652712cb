//! The renderer: an RGB frame for any camera pose over a world, with no GPU.
//!
//! Sky and ground are computed per pixel (flat ground, tiling textures with mip
//! levels, haze by distance); towers, conductors and distractors are
//! antialiased vector strokes with perspective-correct widths (tiny-skia),
//! painted far to near; the sensor then adds blur, exposure and noise.

mod background;
pub mod conditions;
mod post;
mod scene;
mod textures;

use image::RgbImage;
use tiny_skia::Pixmap;
use towernav_geometry::{PinholeCamera, Pose};

pub use conditions::Conditions;
use scene::{Scene, Span, TowerGeometry};

use crate::world::{Distractor, World};

/// Holds what does not change between frames: geometry in world coordinates and textures.
pub struct Renderer {
    camera: PinholeCamera,
    towers: Vec<TowerGeometry>,
    spans: Vec<Span>,
    distractors: Vec<Distractor>,
    ground: textures::MipTexture,
    clouds: textures::CloudSheet,
    noise: post::NoiseTable,
}

/// Reusable per-frame buffers, so a flight renders without reallocating.
pub struct FrameBuffers {
    pixmap: Pixmap,
    scratch: Vec<u8>,
    half: Vec<u8>,
    pub image: RgbImage,
}

impl Renderer {
    pub fn new(world: &World, camera: PinholeCamera, texture_seed: u64) -> Self {
        Self {
            camera,
            towers: scene::tower_geometry(world),
            spans: scene::spans(world),
            distractors: world.distractors.clone(),
            ground: textures::farmland(texture_seed),
            clouds: textures::CloudSheet::new(texture_seed),
            noise: post::NoiseTable::new(texture_seed),
        }
    }

    pub fn camera(&self) -> &PinholeCamera {
        &self.camera
    }

    pub fn buffers(&self) -> FrameBuffers {
        let k = &self.camera.intrinsics;
        FrameBuffers {
            pixmap: Pixmap::new(k.width.max(1), k.height.max(1)).unwrap_or_else(|| {
                // Width and height are at least 1, so this cannot fail; keep a 1x1 fallback anyway.
                Pixmap::new(1, 1).expect("1x1 pixmap")
            }),
            scratch: Vec::new(),
            half: Vec::new(),
            image: RgbImage::new(k.width.max(1), k.height.max(1)),
        }
    }

    /// Render one frame into `buffers.image`. `attitude_rates` (roll, pitch, yaw,
    /// rad/s) drive the motion blur; `noise_seed` makes the sensor noise repeatable.
    pub fn render_into(
        &self,
        buffers: &mut FrameBuffers,
        pose: &Pose,
        conditions: &Conditions,
        attitude_rates: (f64, f64, f64),
        noise_seed: u64,
    ) {
        let k = &self.camera.intrinsics;
        let world_from_camera = self.camera.world_from_camera(pose);
        background::draw(
            buffers.pixmap.data_mut(),
            &mut buffers.half,
            k,
            &world_from_camera,
            conditions,
            &self.ground,
            &self.clouds,
        );
        let scene = Scene {
            camera: &self.camera,
            camera_from_world: world_from_camera.inverse(),
            conditions,
        };
        scene.draw(
            &mut buffers.pixmap,
            &self.towers,
            &self.spans,
            &self.distractors,
        );
        let shutter = conditions.shutter_s.max(0.0);
        let blur = (
            k.fx * attitude_rates.2 * shutter,
            k.fy * attitude_rates.1 * shutter,
        );
        post::motion_blur(
            buffers.pixmap.data_mut(),
            &mut buffers.scratch,
            k.width as usize,
            blur,
        );
        post::develop(
            buffers.pixmap.data(),
            &mut buffers.image,
            conditions.exposure,
            conditions.noise_sigma,
            &self.noise,
            noise_seed,
        );
    }

    /// Render one frame into a new image.
    pub fn render(
        &self,
        pose: &Pose,
        conditions: &Conditions,
        attitude_rates: (f64, f64, f64),
        noise_seed: u64,
    ) -> RgbImage {
        let mut buffers = self.buffers();
        self.render_into(&mut buffers, pose, conditions, attitude_rates, noise_seed);
        buffers.image
    }
}
