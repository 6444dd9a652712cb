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

use super::frame_times::{self, FrameTimes};

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
    /// The barometer's height above take-off, metres, when the source knows it.
    pub barometric_height_m: Option<f64>,
}

/// A source of frames, read on its own thread. `None`: no more frames.
pub trait FrameSource: Send {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>>;
    /// For logs and the status: what this source reads.
    fn describe(&self) -> String;
    /// The first and last frames' times, when known before they are read
    /// (recordings): a flight log is checked against them at start.
    fn span_s(&self) -> Option<(f64, f64)> {
        None
    }
    /// How many frames a recording holds, when known before they are read.
    fn frame_count(&self) -> Option<u64> {
        None
    }
}

/// The first frames of another source: `--max-frames` for any camera or
/// recording, as for the simulator.
pub struct FirstFrames {
    inner: Box<dyn FrameSource>,
    limit: u64,
    given: u64,
}

impl FirstFrames {
    pub fn new(inner: Box<dyn FrameSource>, limit: u64) -> Self {
        Self {
            inner,
            limit,
            given: 0,
        }
    }
}

impl FrameSource for FirstFrames {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>> {
        if self.given >= self.limit {
            return None;
        }
        self.given += 1;
        self.inner.next_frame()
    }

    fn describe(&self) -> String {
        format!("{} (first {} frames)", self.inner.describe(), self.limit)
    }

    fn span_s(&self) -> Option<(f64, f64)> {
        self.inner.span_s()
    }

    fn frame_count(&self) -> Option<u64> {
        self.inner.frame_count().map(|n| n.min(self.limit))
    }
}

/// A folder of images (PNG, JPEG), in file-name order, each at its time.
pub struct ImageFolderSource {
    folder: PathBuf,
    files: Vec<PathBuf>,
    times: Vec<f64>,
    next: usize,
    fps: f64,
}

impl ImageFolderSource {
    /// The images of `folder`; their times as `times` says (`Rate`: at `fps`).
    pub fn open(folder: &Path, fps: f64, times: &FrameTimes) -> Result<Self, SourceError> {
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
        let times = match times {
            FrameTimes::Rate => (0..files.len()).map(|i| i as f64 / fps).collect(),
            FrameTimes::Pts => {
                return Err(bad(
                    "presentation timestamps are a video's; for images use rate, names or a file"
                        .into(),
                ));
            }
            FrameTimes::Names { per_second } => {
                frame_times::from_names(&files, *per_second).map_err(bad)?
            }
            FrameTimes::File(path) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| bad(format!("timestamps file {}: {e}", path.display())))?;
                frame_times::from_file(&text, path, &files).map_err(bad)?
            }
        };
        frame_times::check_increasing(&times, |i| files[i].display().to_string()).map_err(bad)?;
        Ok(Self {
            folder: folder.to_path_buf(),
            files,
            times,
            next: 0,
            fps,
        })
    }
}

impl FrameSource for ImageFolderSource {
    fn next_frame(&mut self) -> Option<Result<CapturedFrame, SourceError>> {
        let path = self.files.get(self.next)?.clone();
        let time_s = self.times[self.next];
        let seq = self.next as u64;
        self.next += 1;
        Some(
            image::open(&path)
                .map(|img| CapturedFrame {
                    seq,
                    time_s,
                    captured: Instant::now(),
                    image: Some(img.to_rgb8()),
                    detections: None,
                    attitude: None,
                    truth_in_world: None,
                    barometric_height_m: None,
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
            "{} images in {} (nominal {} Hz)",
            self.files.len(),
            self.folder.display(),
            self.fps
        )
    }

    fn span_s(&self) -> Option<(f64, f64)> {
        Some((*self.times.first()?, *self.times.last()?))
    }

    fn frame_count(&self) -> Option<u64> {
        Some(self.files.len() as u64)
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
    /// A file's presentation timestamps, in order.
    pts: Option<Vec<f64>>,
    seq: u64,
    started: Instant,
}

impl FfmpegSource {
    /// `times`: `Pts` stamps a file's frames with their presentation
    /// timestamps (read first with ffprobe), `Rate` with index / `fps`; a
    /// live input is stamped on arrival.
    pub fn open(
        input: &str,
        width: u32,
        height: u32,
        fps: f64,
        times: &FrameTimes,
    ) -> Result<Self, SourceError> {
        let bad = |reason: String| SourceError::Ffmpeg {
            input: input.to_string(),
            reason,
        };
        let live = input.starts_with("rtsp://") || input.starts_with("/dev/video");
        if !live && !Path::new(input).is_file() {
            return Err(bad("no such file".into()));
        }
        let pts = match times {
            FrameTimes::Pts if !live => Some(video_pts(input).map_err(bad)?),
            FrameTimes::Pts | FrameTimes::Rate => None,
            other => {
                return Err(bad(format!(
                    "{other:?}: a video's frames are timed by its timestamps (pts) or the rate"
                )));
            }
        };
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
            // One output frame per decoded frame: no frame repeated or dropped
            // to meet a rate, so the n-th frame has the n-th timestamp.
            .args(["-fps_mode", "passthrough"])
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
            pts,
            seq: 0,
            started: Instant::now(),
        })
    }
}

/// The size of the images in `folder`: its first image's (the pipeline
/// refuses later ones of another size).
pub fn image_size(folder: &Path) -> Result<(u32, u32), SourceError> {
    let source = ImageFolderSource::open(folder, 1.0, &FrameTimes::Rate)?;
    let first = &source.files[0];
    image::image_dimensions(first).map_err(|e| SourceError::Image {
        seq: 0,
        path: first.clone(),
        reason: e.to_string(),
    })
}

/// A video file's frame size, from ffprobe.
pub fn video_size(input: &str) -> Result<(u32, u32), SourceError> {
    let bad = |reason: String| SourceError::Ffmpeg {
        input: input.to_string(),
        reason,
    };
    if !Path::new(input).is_file() {
        return Err(bad("no such file".into()));
    }
    let output = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=width,height",
            "-of",
            "csv=p=0",
            input,
        ])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| bad(format!("cannot start ffprobe ({e}); it comes with ffmpeg")))?;
    let text = String::from_utf8_lossy(&output.stdout);
    let mut fields = text.trim().trim_end_matches(',').split(',');
    match (
        fields.next().and_then(|w| w.parse().ok()),
        fields.next().and_then(|h| h.parse().ok()),
    ) {
        (Some(w), Some(h)) if output.status.success() => Ok((w, h)),
        _ => Err(bad(format!(
            "ffprobe found no video stream size: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ))),
    }
}

/// A video file's presentation timestamps, from ffprobe's packet list.
fn video_pts(input: &str) -> Result<Vec<f64>, String> {
    let output = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0"])
        .args(["-show_entries", "packet=pts_time", "-of", "csv=p=0", input])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot start ffprobe ({e}); it comes with ffmpeg"))?;
    if !output.status.success() {
        return Err(format!(
            "ffprobe could not read its timestamps: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let times = frame_times::parse_pts(&String::from_utf8_lossy(&output.stdout))?;
    if times.is_empty() {
        return Err("it has no video frames".into());
    }
    frame_times::check_increasing(&times, |i| format!("frame {i}"))?;
    Ok(times)
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
        let time_s = match &self.pts {
            Some(pts) => match pts.get(seq as usize) {
                Some(t) => *t,
                None => {
                    return Some(Err(SourceError::Ffmpeg {
                        input: self.input.clone(),
                        reason: format!(
                            "frame {seq} decoded, but ffprobe listed only {} timestamps",
                            pts.len()
                        ),
                    }));
                }
            },
            None if self.live => self.started.elapsed().as_secs_f64(),
            None => seq as f64 / self.fps,
        };
        Some(Ok(CapturedFrame {
            seq,
            time_s,
            captured: Instant::now(),
            image: Some(image),
            detections: None,
            attitude: None,
            truth_in_world: None,
            barometric_height_m: None,
        }))
    }

    fn describe(&self) -> String {
        format!("ffmpeg: {} ({}x{})", self.input, self.width, self.height)
    }

    fn span_s(&self) -> Option<(f64, f64)> {
        let pts = self.pts.as_ref()?;
        Some((*pts.first()?, *pts.last()?))
    }

    fn frame_count(&self) -> Option<u64> {
        self.pts.as_ref().map(|p| p.len() as u64)
    }
}

impl Drop for FfmpegSource {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(names: &[&str]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().expect("tempdir");
        for name in names {
            RgbImage::new(40, 30)
                .save(dir.path().join(name))
                .expect("image");
        }
        dir
    }

    #[test]
    fn max_frames_stops_any_source_after_its_first_frames() {
        let dir = folder(&["a.png", "b.png", "c.png"]);
        let inner = ImageFolderSource::open(dir.path(), 30.0, &FrameTimes::Rate).expect("opens");
        let mut source = FirstFrames::new(Box::new(inner), 2);
        assert_eq!(source.frame_count(), Some(2));
        assert_eq!(std::iter::from_fn(|| source.next_frame()).count(), 2);
    }

    #[test]
    fn an_image_folder_times_its_frames_by_their_names_or_a_file() {
        let dir = folder(&["cam_100.250.png", "cam_100.300.png", "cam_100.400.png"]);
        let names = FrameTimes::Names { per_second: 1.0 };
        let mut source = ImageFolderSource::open(dir.path(), 30.0, &names).expect("opens");
        assert_eq!(source.span_s(), Some((100.25, 100.4)));
        let times: Vec<f64> = std::iter::from_fn(|| source.next_frame())
            .map(|f| f.expect("frame").time_s)
            .collect();
        assert_eq!(times, vec![100.25, 100.3, 100.4]);
        assert_eq!(image_size(dir.path()).expect("size"), (40, 30));

        let list = dir.path().join("times.txt");
        std::fs::write(
            &list,
            "cam_100.400.png 7\ncam_100.250.png 5\ncam_100.300.png 6\n",
        )
        .expect("write");
        let source =
            ImageFolderSource::open(dir.path(), 30.0, &FrameTimes::File(list)).expect("opens");
        assert_eq!(source.span_s(), Some((5.0, 7.0)));
    }

    #[test]
    fn names_that_go_back_in_time_are_refused_naming_the_images() {
        // Name order is not time order here: 9 sorts after 10.
        let dir = folder(&["f_10.png", "f_9.png"]);
        let err = ImageFolderSource::open(dir.path(), 30.0, &FrameTimes::Names { per_second: 1.0 })
            .err()
            .expect("refused");
        let text = err.to_string();
        assert!(
            text.contains("f_9.png") && text.contains("f_10.png"),
            "{text}"
        );
        let err = ImageFolderSource::open(dir.path(), 30.0, &FrameTimes::Pts)
            .err()
            .expect("pts are a video's");
        assert!(err.to_string().contains("video"), "{err}");
    }
}
