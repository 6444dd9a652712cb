//! Where frames come from: a folder of images, or anything ffmpeg reads (a video
//! file, an RTSP stream, a V4L2 camera); the simulator's source is
//! `sim_source.rs`, in the demo build. Every frame is stamped with its
//! capture instant (for latency) and its time on the source's clock.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::Instant;

use image::RgbImage;
use nalgebra::Point3;
use towernav_geometry::Attitude;
use towernav_protocol::Detection;

#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error("image folder {path}: {reason}")]
    Folder { path: PathBuf, reason: String },
    #[error("frame {seq} ({path}): {reason}")]
    Image {
        seq: u64,
        path: PathBuf,
        reason: String,
    },
    #[error("ffmpeg on {input}: {reason}")]
    Ffmpeg { input: String, reason: String },
}

/// One frame as the source delivers it.
pub struct CapturedFrame {
    pub seq: u64,
    /// Seconds on the source's clock (flight time, file timestamp, or since start).
    pub time_s: f64,
    /// When it entered the daemon, for frame-to-publish latency.
    pub captured: Instant,
    /// Pixels, unless the oracle stands in for the detector.
    pub image: Option<RgbImage>,
    /// The oracle's boxes, when there are no pixels to detect on.
    pub detections: Option<Vec<Detection>>,
    /// Attitude the source itself knows (the simulator's IMU).
    pub attitude: Option<Attitude>,
    /// Where the camera truly was (the simulator's truth), for the operator's
    /// map; the pipeline never reads it.
    pub truth_in_world: Option<Point3<f64>>,
}

/// A source of frames, read on its own thread. `None`: no more frames.
pub trait FrameSource: Send {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>>;
    /// For logs and the status: what this source reads.
    fn describe(&self) -> String;
}

/// A folder of images (PNG, JPEG), in file-name order, at `fps`.
pub struct ImageFolderSource {
    folder: PathBuf,
    files: Vec<PathBuf>,
    next: usize,
    fps: f64,
}

impl ImageFolderSource {
    pub fn open(folder: &Path, fps: f64) -> Result<Self, SourceError> {
        let bad = |reason: String| SourceError::Folder {
            path: folder.to_path_buf(),
            reason,
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(folder)
            .map_err(|e| bad(format!("cannot list it: {e}")))?
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg")
                })
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(bad("it holds no .png or .jpg images".into()));
        }
        if fps.is_nan() || fps <= 0.0 {
            return Err(bad(format!("the frame rate must be positive, got {fps}")));
        }
        Ok(Self {
            folder: folder.to_path_buf(),
            files,
            next: 0,
            fps,
        })
    }
}

impl FrameSource for ImageFolderSource {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>> {
        let path = self.files.get(self.next)?.clone();
        let seq = self.next as u64;
        self.next += 1;
        Some(
            image::open(&path)
                .map(|img| CapturedFrame {
                    seq,
                    time_s: seq as f64 / self.fps,
                    captured: Instant::now(),
                    image: Some(img.to_rgb8()),
                    detections: None,
                    attitude: None,
                    truth_in_world: None,
                })
                .map_err(|e| SourceError::Image {
                    seq,
                    path,
                    reason: e.to_string(),
                }),
        )
    }

    fn describe(&self) -> String {
        format!(
            "{} images in {} at {} Hz",
            self.files.len(),
            self.folder.display(),
            self.fps
        )
    }
}

/// Anything ffmpeg can open: a file, `rtsp://...`, or a V4L2 device
/// (`/dev/video0`, read with `-f v4l2`). Frames are scaled to the camera's
/// size, so the intrinsics hold, and read as raw RGB from its output.
pub struct FfmpegSource {
    input: String,
    child: Child,
    stdout: ChildStdout,
    width: u32,
    height: u32,
    fps: f64,
    live: bool,
    seq: u64,
    started: Instant,
}

impl FfmpegSource {
    pub fn open(input: &str, width: u32, height: u32, fps: f64) -> Result<Self, SourceError> {
        let bad = |reason: String| SourceError::Ffmpeg {
            input: input.to_string(),
            reason,
        };
        let live = input.starts_with("rtsp://") || input.starts_with("/dev/video");
        if !live && !Path::new(input).is_file() {
            return Err(bad("no such file".into()));
        }
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-hide_banner", "-loglevel", "error", "-nostdin"]);
        if input.starts_with("rtsp://") {
            cmd.args(["-rtsp_transport", "tcp"]);
        }
        if input.starts_with("/dev/video") {
            cmd.args(["-f", "v4l2"]);
        }
        cmd.args(["-i", input])
            .args(["-vf", &format!("scale={width}:{height}")])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let mut child = cmd.spawn().map_err(|e| {
            bad(format!(
                "cannot start ffmpeg ({e}); install it (`apt-get install ffmpeg`, which the project's setup does)"
            ))
        })?;
        let stdout = child
            .stdout
            .take()
            .ok_or_else(|| bad("ffmpeg gave no output pipe".into()))?;
        Ok(Self {
            input: input.to_string(),
            child,
            stdout,
            width,
            height,
            fps,
            live,
            seq: 0,
            started: Instant::now(),
        })
    }
}

impl FrameSource for FfmpegSource {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>> {
        let mut buf = vec![0u8; (self.width * self.height * 3) as usize];
        match self.stdout.read_exact(&mut buf) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                let status = self.child.wait().ok();
                return match status {
                    Some(s) if !s.success() => Some(Err(SourceError::Ffmpeg {
                        input: self.input.clone(),
                        reason: format!("ffmpeg ended with {s} (its message is above)"),
                    })),
                    _ => None,
                };
            }
            Err(e) => {
                return Some(Err(SourceError::Ffmpeg {
                    input: self.input.clone(),
                    reason: format!("reading frames: {e}"),
                }));
            }
        }
        let image = RgbImage::from_raw(self.width, self.height, buf)?;
        let seq = self.seq;
        self.seq += 1;
        let time_s = if self.live {
            self.started.elapsed().as_secs_f64()
        } else {
            seq as f64 / self.fps
        };
        Some(Ok(CapturedFrame {
            seq,
            time_s,
            captured: Instant::now(),
            image: Some(image),
            detections: None,
            attitude: None,
            truth_in_world: None,
        }))
    }

    fn describe(&self) -> String {
        format!("ffmpeg: {} ({}x{})", self.input, self.width, self.height)
    }
}

impl Drop for FfmpegSource {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
