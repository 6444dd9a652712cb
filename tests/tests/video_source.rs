//! The ffmpeg frame source (video files; RTSP and V4L2 use the same path): a
//! clip made here decodes to its frames, scaled and timestamped, and bad input
//! gets an error naming it. Needs the `ffmpeg` program, which the project's
//! setup (`cargo xtask test`, `cargo xtask demo`) installs from Debian's packages.

use std::process::Command;

use towernav_edge::daemon::frame_times::FrameTimes;
use towernav_edge::daemon::source::{FfmpegSource, FrameSource};

fn ffmpeg() -> anyhow::Result<()> {
    let found = Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    anyhow::ensure!(
        found,
        "the ffmpeg program is missing: `cargo xtask test` installs it (apt-get install ffmpeg)"
    );
    Ok(())
}

#[test]
fn a_video_file_decodes_to_scaled_timestamped_frames() -> anyhow::Result<()> {
    ffmpeg()?;
    let dir = tempfile::tempdir()?;
    // Five frames, each brighter than the last, at 320x180.
    for i in 0..5u8 {
        image::RgbImage::from_pixel(
            320,
            180,
            image::Rgb([40 * (i + 1), 40 * (i + 1), 40 * (i + 1)]),
        )
        .save(dir.path().join(format!("{i:04}.png")))?;
    }
    let clip = dir.path().join("clip.avi");
    let status = Command::new("ffmpeg")
        .args([
            "-hide_banner",
            "-loglevel",
            "error",
            "-framerate",
            "10",
            "-i",
        ])
        .arg(dir.path().join("%04d.png"))
        .args(["-c:v", "mjpeg", "-q:v", "2"])
        .arg(&clip)
        .status()?;
    anyhow::ensure!(status.success(), "encoding the clip failed");

    // Its own timestamps, not the nominal rate given (30 Hz), time the frames.
    let mut source = FfmpegSource::open(
        &clip.display().to_string(),
        640,
        360,
        30.0,
        &FrameTimes::Pts,
    )?;
    assert_eq!(source.span_s(), Some((0.0, 0.4)));
    let mut frames = Vec::new();
    while let Some(frame) = source.next_frame() {
        frames.push(frame?);
    }
    assert_eq!(frames.len(), 5);
    let mut last_brightness = 0.0;
    for (i, f) in frames.iter().enumerate() {
        let image = f.image.as_ref().expect("pixels");
        assert_eq!(
            image.dimensions(),
            (640, 360),
            "scaled to the configured size"
        );
        assert_eq!(f.seq, i as u64);
        assert!((f.time_s - i as f64 / 10.0).abs() < 1e-9, "{}", f.time_s);
        let mean = image.pixels().map(|p| f64::from(p[0])).sum::<f64>() / (640.0 * 360.0);
        assert!(
            mean > last_brightness + 20.0,
            "frame {i}: {mean} after {last_brightness}"
        );
        last_brightness = mean;
    }
    Ok(())
}

#[test]
fn a_missing_or_broken_video_is_an_error_naming_it() -> anyhow::Result<()> {
    ffmpeg()?;
    let err = FfmpegSource::open("/nonexistent/flight.mp4", 640, 360, 30.0, &FrameTimes::Pts)
        .err()
        .expect("missing file");
    assert!(err.to_string().contains("/nonexistent/flight.mp4"), "{err}");

    let dir = tempfile::tempdir()?;
    let junk = dir.path().join("junk.mp4");
    std::fs::write(&junk, b"this is not a video")?;
    let err = FfmpegSource::open(
        &junk.display().to_string(),
        640,
        360,
        30.0,
        &FrameTimes::Pts,
    )
    .err()
    .expect("no timestamps to read");
    assert!(err.to_string().contains("junk.mp4"), "{err}");
    let mut source = FfmpegSource::open(
        &junk.display().to_string(),
        640,
        360,
        30.0,
        &FrameTimes::Rate,
    )?;
    match source.next_frame() {
        Some(Err(e)) => assert!(e.to_string().contains("junk.mp4"), "{e}"),
        other => panic!(
            "expected an error, got {:?}",
            other.map(|r| r.map(|f| f.seq))
        ),
    }
    Ok(())
}
