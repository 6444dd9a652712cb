//! When each frame was taken, on the camera's clock: a frame's attitude is
//! the flight log's at that time plus the camera-to-log offset, so frames
//! must carry their own capture times, not their index over a nominal rate.
//! The sources: the frame rate (index / fps), a video's presentation
//! timestamps, numbers in image file names, or a timestamps file.

use std::path::{Path, PathBuf};

/// How a source's frames get their times (`source.timestamps`).
#[derive(Debug, Clone, PartialEq)]
pub enum FrameTimes {
    /// Index over `source.fps`.
    Rate,
    /// A video file's presentation timestamps.
    Pts,
    /// The last number in each image's file name, in seconds divided by
    /// `per_second` (1 for `12.250.jpg`, 1e9 for ROS's nanosecond names).
    Names { per_second: f64 },
    /// A file with one time per image (seconds), in name order, or
    /// `name,time_s` lines.
    File(PathBuf),
}

impl FrameTimes {
    /// Reads `source.timestamps`: `rate`, `pts`, `names`, `names_ms`,
    /// `names_us`, `names_ns`, or a timestamps file's path.
    pub fn parse(spelled: &str) -> Self {
        match spelled {
            "rate" => Self::Rate,
            "pts" => Self::Pts,
            "names" => Self::Names { per_second: 1.0 },
            "names_ms" => Self::Names { per_second: 1e3 },
            "names_us" => Self::Names { per_second: 1e6 },
            "names_ns" => Self::Names { per_second: 1e9 },
            path => Self::File(PathBuf::from(path)),
        }
    }
}

/// The last run of digits (with a fractional part) in `name`'s stem.
fn number_in_name(path: &Path) -> Option<f64> {
    let stem = path.file_stem()?.to_str()?;
    let bytes = stem.as_bytes();
    let end = bytes.iter().rposition(u8::is_ascii_digit)? + 1;
    let mut start = end;
    let mut seen_point = false;
    while start > 0 {
        let c = bytes[start - 1];
        if c.is_ascii_digit() {
            start -= 1;
        } else if c == b'.' && !seen_point && start >= 2 && bytes[start - 2].is_ascii_digit() {
            seen_point = true;
            start -= 1;
        } else {
            break;
        }
    }
    stem[start..end].parse().ok()
}

/// Each image's time from its file name.
pub fn from_names(files: &[PathBuf], per_second: f64) -> Result<Vec<f64>, String> {
    files
        .iter()
        .map(|f| {
            number_in_name(f).map(|n| n / per_second).ok_or_else(|| {
                format!(
                    "{}: no number in the file name to read as its time",
                    f.display()
                )
            })
        })
        .collect()
}

/// Each image's time from a timestamps file's text (`what` names it in errors).
pub fn from_file(text: &str, what: &Path, files: &[PathBuf]) -> Result<Vec<f64>, String> {
    let bad = |line: usize, reason: String| format!("{} line {line}: {reason}", what.display());
    let mut by_order = Vec::new();
    let mut by_name = std::collections::HashMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line
            .split([',', ' ', '\t'])
            .filter(|f| !f.is_empty())
            .collect();
        let time = |s: &str| {
            s.parse::<f64>()
                .ok()
                .filter(|t| t.is_finite())
                .ok_or_else(|| bad(i + 1, format!("{s:?} is not a time in seconds")))
        };
        match fields.as_slice() {
            [t] => by_order.push(time(t)?),
            [name, t] => {
                // A header such as `file,time_s`.
                if by_name.is_empty() && by_order.is_empty() && t.parse::<f64>().is_err() {
                    continue;
                }
                by_name.insert(name.to_string(), time(t)?);
            }
            _ => {
                return Err(bad(i + 1, "expected `time_s` or `name,time_s`".into()));
            }
        }
    }
    if !by_order.is_empty() && !by_name.is_empty() {
        return Err(format!(
            "{}: mixes bare times with `name,time_s` lines",
            what.display()
        ));
    }
    if by_name.is_empty() {
        if by_order.len() != files.len() {
            return Err(format!(
                "{}: {} times for {} images",
                what.display(),
                by_order.len(),
                files.len()
            ));
        }
        return Ok(by_order);
    }
    files
        .iter()
        .map(|f| {
            let name = f.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            by_name
                .get(name)
                .copied()
                .ok_or_else(|| format!("{}: no time for image {name}", what.display()))
        })
        .collect()
}

/// Refuses times that do not increase, naming the frames.
pub fn check_increasing(times: &[f64], name: impl Fn(usize) -> String) -> Result<(), String> {
    for (i, pair) in times.windows(2).enumerate() {
        if pair[1] <= pair[0] {
            return Err(format!(
                "frame times must increase: {} at {:.6} s comes after {} at {:.6} s",
                name(i + 1),
                pair[1],
                name(i),
                pair[0]
            ));
        }
    }
    Ok(())
}

/// Parses `ffprobe -show_entries packet=pts_time -of csv=p=0` output into
/// presentation times in order (packets come in decoding order).
pub fn parse_pts(text: &str) -> Result<Vec<f64>, String> {
    let mut times = Vec::new();
    for line in text.lines() {
        let field = line.trim().trim_end_matches(',');
        if field.is_empty() || field == "N/A" {
            continue;
        }
        times.push(
            field
                .parse::<f64>()
                .map_err(|_| format!("ffprobe gave {field:?} for a presentation time"))?,
        );
    }
    times.sort_by(f64::total_cmp);
    Ok(times)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files(names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(|n| PathBuf::from("/f").join(n)).collect()
    }

    #[test]
    fn times_come_from_the_numbers_in_file_names() {
        let f = files(&["frame_12.250.jpg", "frame_12.300.jpg", "cam0-13.jpg"]);
        assert_eq!(from_names(&f, 1.0).expect("read"), vec![12.25, 12.3, 13.0]);
        let ros = files(&["1712000000123456789.png"]);
        let t = from_names(&ros, 1e9).expect("read");
        assert!((t[0] - 1_712_000_000.123_456_8).abs() < 1e-3);
        let err = from_names(&files(&["still.jpg"]), 1.0).expect_err("no number");
        assert!(err.contains("still.jpg"), "{err}");
    }

    #[test]
    fn a_timestamps_file_gives_times_in_order_or_by_name() {
        let f = files(&["a.jpg", "b.jpg"]);
        let what = Path::new("times.csv");
        assert_eq!(
            from_file("# t\n0.5\n0.55\n", what, &f).expect("ok"),
            vec![0.5, 0.55]
        );
        assert_eq!(
            from_file("file,time_s\nb.jpg,2\na.jpg,1\n", what, &f).expect("ok"),
            vec![1.0, 2.0]
        );
        let short = from_file("0.5\n", what, &f).expect_err("one short");
        assert!(short.contains("1 times for 2 images"), "{short}");
        let missing = from_file("a.jpg,1\n", what, &f).expect_err("b missing");
        assert!(missing.contains("no time for image b.jpg"), "{missing}");
        let bad = from_file("0.5\nsoon\n", what, &f).expect_err("bad");
        assert!(bad.contains("times.csv line 2"), "{bad}");
    }

    #[test]
    fn times_that_go_back_are_refused_naming_both_frames() {
        let err = check_increasing(&[0.0, 0.1, 0.1], |i| format!("#{i}")).expect_err("repeat");
        assert!(err.contains("#2") && err.contains("#1"), "{err}");
    }

    #[test]
    fn ffprobe_packets_are_sorted_into_presentation_order() {
        let text = "0.000000\n0.066667\n0.033333\nN/A\n0.100000,\n";
        assert_eq!(
            parse_pts(text).expect("parses"),
            vec![0.0, 0.033333, 0.066667, 0.1]
        );
    }
}
