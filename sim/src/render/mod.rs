//! The renderer: an RGB frame for any camera pose over a world, with no GPU.
//!
//! Sky and ground are computed per pixel (flat ground, tiling textures with mip
//! levels, haze by distance); towers, conductors and distractors are
//! antialiased vector strokes with perspective-correct widths (tiny-skia),
//! painted far to near; the sensor then adds blur, exposure and noise.

mod background;
mod clutter;
pub mod conditions;
pub mod lens;
mod lens_warp;
mod post;
mod scene;
mod textures;

use image::RgbImage;
use tiny_skia::Pixmap;
use towernav_geometry::{PinholeCamera, Pose};

pub use conditions::{Conditions, TowerPaint};
pub use lens_warp::LensWarp;
use scene::{Scene, Span, TowerGeometry};

use crate::world::{Distractor, World};

/// Holds what does not change between frames: geometry in world coordinates and textures.
pub struct Renderer {
    /// The ideal pinhole the scene is drawn through (the lens's canvas when
    /// `warp` bends it into `camera`).
    canvas: PinholeCamera,
    camera: PinholeCamera,
    warp: Option<LensWarp>,
    towers: Vec<TowerGeometry>,
    spans: Vec<Span>,
    distractors: Vec<Distractor>,
    ground: textures::MipTexture,
    clouds: textures::CloudSheet,
    noise: post::NoiseTable,
}

/// A real photograph, already the frame's size, to draw the scene over.
#[derive(Debug, Clone, Copy)]
pub struct Backdrop<'a> {
    pub photo: &'a RgbImage,
    /// Cover the sky too, not only the ground below the horizon.
    pub whole_frame: bool,
}

/// Reusable per-frame buffers, so a flight renders without reallocating.
pub struct FrameBuffers {
    pixmap: Pixmap,
    scratch: Vec<u8>,
    half: Vec<u8>,
    /// The ideal canvas before a lens bends it.
    canvas: RgbImage,
    pub image: RgbImage,
}

impl Renderer {
    /// A renderer for `camera`, its lens included: a distorted camera's frames
    /// are drawn ideal and then bent (`LensWarp`).
    pub fn new(world: &World, camera: PinholeCamera, texture_seed: u64) -> Self {
        let warp = LensWarp::new(&camera);
        Self {
            canvas: warp.as_ref().map_or(camera, |w| *w.canvas()),
            camera,
            warp,
            towers: scene::tower_geometry(world),
            spans: scene::spans(world),
            distractors: world.distractors.clone(),
            ground: textures::farmland(texture_seed),
            clouds: textures::CloudSheet::new(texture_seed),
            noise: post::NoiseTable::new(texture_seed),
        }
    }

    /// The camera the frames are seen through, lens included.
    pub fn camera(&self) -> &PinholeCamera {
        &self.camera
    }

    pub fn buffers(&self) -> FrameBuffers {
        let k = &self.canvas.intrinsics;
        let out = &self.camera.intrinsics;
        FrameBuffers {
            pixmap: Pixmap::new(k.width.max(1), k.height.max(1)).unwrap_or_else(|| {
                // Width and height are at least 1, so this cannot fail; keep a 1x1 fallback anyway.
                Pixmap::new(1, 1).expect("1x1 pixmap")
            }),
            scratch: Vec::new(),
            half: Vec::new(),
            canvas: match self.warp {
                Some(_) => RgbImage::new(k.width.max(1), k.height.max(1)),
                None => RgbImage::new(0, 0),
            },
            image: RgbImage::new(out.width.max(1), out.height.max(1)),
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
        self.render_over(buffers, pose, conditions, attitude_rates, noise_seed, None);
    }

    /// [`Renderer::render_into`] with a real photograph behind the scene
    /// instead of the drawn ground (or sky and ground).
    pub fn render_over(
        &self,
        buffers: &mut FrameBuffers,
        pose: &Pose,
        conditions: &Conditions,
        attitude_rates: (f64, f64, f64),
        noise_seed: u64,
        backdrop: Option<Backdrop<'_>>,
    ) {
        let k = &self.canvas.intrinsics;
        let world_from_camera = self.canvas.world_from_camera(pose);
        background::draw(
            buffers.pixmap.data_mut(),
            &mut buffers.half,
            k,
            &world_from_camera,
            conditions,
            &self.ground,
            &self.clouds,
        );
        if let Some(backdrop) = backdrop {
            background::paste(
                buffers.pixmap.data_mut(),
                &self.canvas,
                &world_from_camera,
                conditions,
                &backdrop,
            );
        }
        let scene = Scene {
            camera: &self.canvas,
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
        let developed = match self.warp {
            Some(_) => &mut buffers.canvas,
            None => &mut buffers.image,
        };
        post::develop(
            buffers.pixmap.data(),
            developed,
            conditions.exposure,
            conditions.noise_sigma,
            &self.noise,
            noise_seed,
        );
        if let Some(warp) = &self.warp {
            warp.apply(&buffers.canvas, &mut buffers.image);
        }
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

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;
    use crate::Scenario;

    /// Counts tiny-skia's warnings: it logs and draws nothing when a path
    /// cannot be stroked, filled or transformed.
    struct SkiaWarnings(AtomicUsize);

    impl log::Log for SkiaWarnings {
        fn enabled(&self, metadata: &log::Metadata) -> bool {
            metadata.target().starts_with("tiny_skia")
        }
        fn log(&self, record: &log::Record) {
            if self.enabled(record.metadata()) && record.level() <= log::Level::Warn {
                self.0.fetch_add(1, Ordering::Relaxed);
            }
        }
        fn flush(&self) {}
    }

    static WARNINGS: SkiaWarnings = SkiaWarnings(AtomicUsize::new(0));

    fn count_warnings() -> usize {
        // Another test may have installed it already; either way it is ours.
        let _ = log::set_logger(&WARNINGS);
        log::set_max_level(log::LevelFilter::Warn);
        WARNINGS.0.load(Ordering::Relaxed)
    }

    /// Every `stride`-th frame of a flight's vector scene, as the renderer draws it.
    fn draw_flight(scenario: &Scenario, stride: usize) {
        let renderer = scenario.renderer();
        let mut pixmap = renderer.buffers().pixmap;
        let conditions = Conditions::default();
        for seq in (0..scenario.frame_count()).step_by(stride) {
            let pose = scenario.flight.pose_at(seq as f64 / scenario.fps);
            let scene = Scene {
                camera: &renderer.camera,
                camera_from_world: renderer.camera.world_from_camera(&pose).inverse(),
                conditions: &conditions,
            };
            scene.draw(
                &mut pixmap,
                &renderer.towers,
                &renderer.spans,
                &renderer.distractors,
            );
        }
    }

    #[test]
    fn the_demo_flight_and_the_presets_draw_every_stroke() {
        let before = count_warnings();
        // The demo's flight frame by frame (it had 112 refusals), the presets sampled.
        draw_flight(&Scenario::paper(1), 1);
        for (name, _) in crate::waypoints::PRESETS {
            let scenario = Scenario::preset(crate::World::paper_field(), name, 1).expect("preset");
            draw_flight(&scenario, 20);
        }
        assert_eq!(count_warnings() - before, 0, "tiny-skia refused strokes");
    }
}
