//! Frames to an H.264 video through ffmpeg, as a UAV's camera records them:
//! raw RGB in on its standard input, presentation times at the flight's rate.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

use anyhow::{Context, bail};
use image::RgbImage;

pub struct VideoWriter {
    path: PathBuf,
    child: Child,
    stdin: Option<ChildStdin>,
    size: (u32, u32),
}

impl VideoWriter {
    pub fn create(path: &Path, width: u32, height: u32, fps: f64) -> anyhow::Result<Self> {
        let mut child = Command::new("ffmpeg")
            .args(["-hide_banner", "-loglevel", "error", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24"])
            .args(["-s", &format!("{width}x{height}"), "-r", &format!("{fps}")])
            .args(["-i", "-"])
            .args(["-c:v", "libx264", "-preset", "veryfast", "-crf", "18"])
            .args(["-pix_fmt", "yuv420p"])
            .arg(path)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .context("starting ffmpeg for --video (install it: `apt-get install ffmpeg`)")?;
        let stdin = child.stdin.take();
        Ok(Self {
            path: path.to_path_buf(),
            child,
            stdin,
            size: (width, height),
        })
    }

    pub fn push(&mut self, frame: &RgbImage) -> anyhow::Result<()> {
        if frame.dimensions() != self.size {
            bail!(
                "frame of {:?} for a {:?} video {}",
                frame.dimensions(),
                self.size,
                self.path.display()
            );
        }
        let stdin = self.stdin.as_mut().context("ffmpeg's input is closed")?;
        stdin.write_all(frame.as_raw()).with_context(|| {
            format!(
                "ffmpeg writing {} (its message is above)",
                self.path.display()
            )
        })
    }

    pub fn finish(mut self) -> anyhow::Result<()> {
        drop(self.stdin.take());
        let status = self.child.wait().context("waiting for ffmpeg")?;
        if !status.success() {
            bail!("ffmpeg writing {} ended with {status}", self.path.display());
        }
        Ok(())
    }
}
