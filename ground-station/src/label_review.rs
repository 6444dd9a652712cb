//! Reviewing a labelled dataset (a survey flight's `towernav-edge label`
//! output, or any YOLO folder) frame by frame: each box accepted or
//! rejected, dragged to the tower's edges, or drawn where a tower has none.
//! A frame's labels are written back to its YOLO file when the reviewer
//! leaves it; rejected boxes are left out. Which frames were reviewed, and
//! what was done to them, is kept in `review.csv` beside `data.yaml`, so a
//! review can stop and go on later.
//!
//! Pure but for [`LabelReview::open`] and [`LabelReview::save`]: the box
//! geometry works in image pixels, and the view turns pointer positions
//! into them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use towernav_dataset::{FolderError, ImageFolder, YoloLabel, write_labels};
use towernav_geometry::PixelBox;

/// The smallest box a drag leaves, pixels a side.
pub const MIN_SIDE_PX: f64 = 3.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Not looked at yet.
    Open,
    Accepted,
    /// Left out of the label file.
    Rejected,
}

/// One box under review, in the image's pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct ReviewBox {
    pub class: usize,
    pub bbox: PixelBox,
    pub verdict: Verdict,
    /// Moved or resized by the reviewer, or drawn by them.
    pub edited: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ReviewFrame {
    pub image: PathBuf,
    pub label_path: PathBuf,
    /// The image's size in pixels, known once it has been read.
    pub size: Option<[f64; 2]>,
    /// The labels as the file holds them (normalized), until the size is known.
    labels: Vec<YoloLabel>,
    pub boxes: Vec<ReviewBox>,
    /// Changed since it was last written.
    pub dirty: bool,
    /// Written by a review (now or in an earlier one).
    pub reviewed: bool,
}

impl ReviewFrame {
    pub fn name(&self) -> String {
        self.image
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
    }

    /// Places the file's labels in pixels, once the image's size is known.
    pub fn set_size(&mut self, width: f64, height: f64) {
        if self.size.is_some() {
            return;
        }
        self.size = Some([width, height]);
        self.boxes = self
            .labels
            .iter()
            .map(|l| ReviewBox {
                class: l.class,
                bbox: l.pixels(width, height),
                verdict: Verdict::Open,
                edited: false,
            })
            .collect();
    }

    fn counts(&self) -> [usize; 3] {
        let n = |v| self.boxes.iter().filter(|b| b.verdict == v).count();
        let edited = self
            .boxes
            .iter()
            .filter(|b| b.edited && b.verdict != Verdict::Rejected)
            .count();
        [
            n(Verdict::Accepted) + n(Verdict::Open),
            n(Verdict::Rejected),
            edited,
        ]
    }
}

/// Which part of a box the pointer took hold of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handle {
    Left,
    Right,
    Top,
    Bottom,
    TopLeft,
    TopRight,
    BottomLeft,
    BottomRight,
    /// Inside, away from the edges: the whole box moves.
    Body,
}

impl Handle {
    fn moves(self) -> [bool; 4] {
        use Handle::*;
        // left, top, right, bottom
        match self {
            Left => [true, false, false, false],
            Right => [false, false, true, false],
            Top => [false, true, false, false],
            Bottom => [false, false, false, true],
            TopLeft => [true, true, false, false],
            TopRight => [false, true, true, false],
            BottomLeft => [true, false, false, true],
            BottomRight => [false, false, true, true],
            Body => [true, true, true, true],
        }
    }
}

/// The box and handle under `p`, within `tol` pixels of an edge; the
/// smallest box wins where they overlap, since it is the hardest to grab.
pub fn hit(boxes: &[ReviewBox], p: [f64; 2], tol: f64) -> Option<(usize, Handle)> {
    let mut best: Option<(usize, Handle, f64)> = None;
    for (i, b) in boxes.iter().enumerate() {
        let r = &b.bbox;
        if p[0] < r.left - tol
            || p[0] > r.right + tol
            || p[1] < r.top - tol
            || p[1] > r.bottom + tol
        {
            continue;
        }
        let near = |a: f64, edge: f64| (a - edge).abs() <= tol;
        let (l, rr, t, bt) = (
            near(p[0], r.left),
            near(p[0], r.right),
            near(p[1], r.top),
            near(p[1], r.bottom),
        );
        let handle = match (l, rr, t, bt) {
            (true, _, true, _) => Handle::TopLeft,
            (_, true, true, _) => Handle::TopRight,
            (true, _, _, true) => Handle::BottomLeft,
            (_, true, _, true) => Handle::BottomRight,
            (true, ..) => Handle::Left,
            (_, true, ..) => Handle::Right,
            (_, _, true, _) => Handle::Top,
            (.., true) => Handle::Bottom,
            _ => Handle::Body,
        };
        let area = r.width() * r.height();
        if best.is_none_or(|(_, _, a)| area < a) {
            best = Some((i, handle, area));
        }
    }
    best.map(|(i, h, _)| (i, h))
}

/// `b` with `handle` moved by `delta` pixels, kept inside a `size` image and
/// at least [`MIN_SIDE_PX`] a side; a whole box slides without changing size.
pub fn dragged(b: &PixelBox, handle: Handle, delta: [f64; 2], size: [f64; 2]) -> PixelBox {
    let [w, h] = size;
    if handle == Handle::Body {
        let dx = delta[0].clamp(-b.left, w - b.right);
        let dy = delta[1].clamp(-b.top, h - b.bottom);
        return PixelBox {
            left: b.left + dx,
            top: b.top + dy,
            right: b.right + dx,
            bottom: b.bottom + dy,
        };
    }
    let [ml, mt, mr, mb] = handle.moves();
    let mut out = *b;
    if ml {
        out.left = (b.left + delta[0]).clamp(0.0, b.right - MIN_SIDE_PX);
    }
    if mr {
        out.right = (b.right + delta[0]).clamp(b.left + MIN_SIDE_PX, w);
    }
    if mt {
        out.top = (b.top + delta[1]).clamp(0.0, b.bottom - MIN_SIDE_PX);
    }
    if mb {
        out.bottom = (b.bottom + delta[1]).clamp(b.top + MIN_SIDE_PX, h);
    }
    out
}

/// The box spanned by two corners, inside the image.
pub fn spanned(a: [f64; 2], b: [f64; 2], size: [f64; 2]) -> PixelBox {
    let cx = |x: f64| x.clamp(0.0, size[0]);
    let cy = |y: f64| y.clamp(0.0, size[1]);
    PixelBox {
        left: cx(a[0].min(b[0])),
        top: cy(a[1].min(b[1])),
        right: cx(a[0].max(b[0])),
        bottom: cy(a[1].max(b[1])),
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ReviewError {
    #[error(transparent)]
    Folder(#[from] FolderError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}, line {line}: {message}")]
    Log {
        path: PathBuf,
        line: usize,
        message: String,
    },
}

/// A dataset under review.
pub struct LabelReview {
    pub dir: PathBuf,
    pub names: Vec<String>,
    pub frames: Vec<ReviewFrame>,
    pub current: usize,
    /// What earlier reviews did, by frame name: kept, rejected, edited.
    log: BTreeMap<String, [usize; 3]>,
}

impl LabelReview {
    /// Opens `dir`: a `data.yaml` (its train split: the frames a model will
    /// learn from) or `images/` with `labels/`.
    pub fn open(dir: &Path) -> Result<Self, ReviewError> {
        let split = dir.join("data.yaml").is_file().then_some("train");
        let folder = ImageFolder::open(dir, split, None)?;
        let log_path = dir.join("review.csv");
        let log = match std::fs::read_to_string(&log_path) {
            Ok(text) => parse_log(&text, &log_path)?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => BTreeMap::new(),
            Err(source) => {
                return Err(ReviewError::Io {
                    path: log_path,
                    source,
                });
            }
        };
        let frames: Vec<ReviewFrame> = folder
            .images
            .into_iter()
            .map(|i| {
                let mut f = ReviewFrame {
                    image: i.image,
                    label_path: i.label_path,
                    size: None,
                    labels: i.labels,
                    boxes: Vec::new(),
                    dirty: false,
                    reviewed: false,
                };
                f.reviewed = log.contains_key(&f.name());
                f
            })
            .collect();
        let current = frames.iter().position(|f| !f.reviewed).unwrap_or(0);
        Ok(Self {
            dir: dir.to_path_buf(),
            names: folder.names,
            frames,
            current,
            log,
        })
    }

    pub fn frame(&self) -> Option<&ReviewFrame> {
        self.frames.get(self.current)
    }

    pub fn frame_mut(&mut self) -> Option<&mut ReviewFrame> {
        self.frames.get_mut(self.current)
    }

    pub fn reviewed(&self) -> usize {
        self.frames.iter().filter(|f| f.reviewed).count()
    }

    /// Sets box `i`'s verdict on the current frame.
    pub fn judge(&mut self, i: usize, verdict: Verdict) {
        if let Some(f) = self.frame_mut()
            && let Some(b) = f.boxes.get_mut(i)
            && b.verdict != verdict
        {
            b.verdict = verdict;
            f.dirty = true;
        }
    }

    /// Replaces box `i`'s geometry on the current frame.
    pub fn reshape(&mut self, i: usize, bbox: PixelBox) {
        if let Some(f) = self.frame_mut()
            && let Some(b) = f.boxes.get_mut(i)
            && b.bbox != bbox
        {
            b.bbox = bbox;
            b.edited = true;
            f.dirty = true;
        }
    }

    /// Adds a box the reviewer drew; too small a box is taken for a click and ignored.
    pub fn draw(&mut self, class: usize, bbox: PixelBox) -> Option<usize> {
        if bbox.width() < MIN_SIDE_PX || bbox.height() < MIN_SIDE_PX {
            return None;
        }
        let f = self.frame_mut()?;
        f.boxes.push(ReviewBox {
            class,
            bbox,
            verdict: Verdict::Accepted,
            edited: true,
        });
        f.dirty = true;
        Some(f.boxes.len() - 1)
    }

    /// Accepts every box not yet judged on the current frame.
    pub fn accept_rest(&mut self) {
        if let Some(f) = self.frame_mut() {
            for b in f.boxes.iter_mut().filter(|b| b.verdict == Verdict::Open) {
                b.verdict = Verdict::Accepted;
                f.dirty = true;
            }
            // Looking at a frame and finding it right is a review too.
            f.dirty |= !f.reviewed;
        }
    }

    /// Writes the current frame's kept boxes to its label file, and the
    /// review log, if anything changed. Returns whether it wrote.
    pub fn save(&mut self) -> Result<bool, ReviewError> {
        let Some(f) = self.frames.get_mut(self.current) else {
            return Ok(false);
        };
        let (Some([w, h]), true) = (f.size, f.dirty) else {
            return Ok(false);
        };
        let kept: Vec<YoloLabel> = f
            .boxes
            .iter()
            .filter(|b| b.verdict != Verdict::Rejected)
            .map(|b| YoloLabel::from_pixels(b.class, &b.bbox, w, h))
            .collect();
        write_labels(&f.label_path, &kept)?;
        f.dirty = false;
        f.reviewed = true;
        let name = f.name();
        let counts = f.counts();
        self.log.insert(name, counts);
        let path = self.dir.join("review.csv");
        let tmp = self.dir.join(".review.csv.tmp");
        std::fs::write(&tmp, format_log(&self.log))
            .and_then(|()| std::fs::rename(&tmp, &path))
            .map_err(|source| ReviewError::Io { path, source })?;
        Ok(true)
    }

    /// Saves the current frame and moves `step` frames on (or back).
    pub fn go(&mut self, step: isize) -> Result<(), ReviewError> {
        self.save()?;
        let last = self.frames.len().saturating_sub(1);
        self.current = self.current.saturating_add_signed(step).min(last);
        Ok(())
    }

    /// Saves the current frame and moves to the next frame not yet reviewed.
    pub fn next_open(&mut self) -> Result<(), ReviewError> {
        self.save()?;
        let n = self.frames.len();
        if let Some(i) = (1..n)
            .map(|k| (self.current + k) % n)
            .find(|&i| !self.frames[i].reviewed)
        {
            self.current = i;
        }
        Ok(())
    }
}

const LOG_HEADER: &str = "frame,kept,rejected,edited";

fn format_log(log: &BTreeMap<String, [usize; 3]>) -> String {
    let mut out = format!("{LOG_HEADER}\n");
    for (name, [k, r, e]) in log {
        out += &format!("{name},{k},{r},{e}\n");
    }
    out
}

fn parse_log(text: &str, path: &Path) -> Result<BTreeMap<String, [usize; 3]>, ReviewError> {
    let mut out = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() || (i == 0 && line.trim() == LOG_HEADER) {
            continue;
        }
        let fail = |message: String| ReviewError::Log {
            path: path.to_path_buf(),
            line: i + 1,
            message,
        };
        let c: Vec<&str> = line.split(',').collect();
        let [name, k, r, e] = c[..] else {
            return Err(fail(format!(
                "{} fields, expected 4 ({LOG_HEADER})",
                c.len()
            )));
        };
        let n = |s: &str| {
            s.trim()
                .parse::<usize>()
                .map_err(|_| fail(format!("{s:?} is not a count")))
        };
        out.insert(name.to_string(), [n(k)?, n(r)?, n(e)?]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn pbox(left: f64, top: f64, right: f64, bottom: f64) -> PixelBox {
        PixelBox {
            left,
            top,
            right,
            bottom,
        }
    }

    fn rbox(b: PixelBox) -> ReviewBox {
        ReviewBox {
            class: 0,
            bbox: b,
            verdict: Verdict::Open,
            edited: false,
        }
    }

    #[test]
    fn the_pointer_takes_the_edge_or_corner_it_is_near_and_the_smaller_box_first() {
        let boxes = [
            rbox(pbox(100.0, 100.0, 200.0, 400.0)),
            rbox(pbox(150.0, 150.0, 180.0, 250.0)),
        ];
        assert_eq!(hit(&boxes, [101.0, 250.0], 4.0), Some((0, Handle::Left)));
        assert_eq!(
            hit(&boxes, [198.0, 402.0], 4.0),
            Some((0, Handle::BottomRight))
        );
        assert_eq!(hit(&boxes, [120.0, 300.0], 4.0), Some((0, Handle::Body)));
        // Inside both: the small one, whose top edge is here.
        assert_eq!(hit(&boxes, [165.0, 151.0], 4.0), Some((1, Handle::Top)));
        assert_eq!(hit(&boxes, [50.0, 50.0], 4.0), None);
    }

    #[test]
    fn an_edge_drag_moves_that_edge_only_and_stops_short_of_the_other() {
        let b = pbox(100.0, 100.0, 200.0, 400.0);
        let size = [640.0, 480.0];
        assert_eq!(
            dragged(&b, Handle::Bottom, [30.0, 25.0], size),
            pbox(100.0, 100.0, 200.0, 425.0)
        );
        assert_eq!(
            dragged(&b, Handle::Left, [500.0, 0.0], size),
            pbox(200.0 - MIN_SIDE_PX, 100.0, 200.0, 400.0)
        );
        // A whole box stops at the image's edge, its size kept.
        assert_eq!(
            dragged(&b, Handle::Body, [-150.0, 200.0], size),
            pbox(0.0, 180.0, 100.0, 480.0)
        );
    }

    proptest! {
        /// Whatever the drag, the box stays inside the image, ordered, and
        /// at least the smallest side: a label Ultralytics will accept.
        #[test]
        fn a_dragged_box_stays_a_valid_label(
            l in 0.0f64..600.0, t in 0.0f64..400.0, w in 3.0f64..40.0, h in 3.0f64..80.0,
            dx in -1000.0f64..1000.0, dy in -1000.0f64..1000.0, k in 0usize..9,
        ) {
            let size = [640.0, 480.0];
            let b = pbox(l, t, l + w, t + h);
            let handle = [
                Handle::Left, Handle::Right, Handle::Top, Handle::Bottom, Handle::TopLeft,
                Handle::TopRight, Handle::BottomLeft, Handle::BottomRight, Handle::Body,
            ][k];
            let d = dragged(&b, handle, [dx, dy], size);
            prop_assert!(d.left >= 0.0 && d.top >= 0.0 && d.right <= size[0] && d.bottom <= size[1]);
            prop_assert!(d.width() >= MIN_SIDE_PX - 1e-9 && d.height() >= MIN_SIDE_PX - 1e-9);
            let label = YoloLabel::from_pixels(0, &d, size[0], size[1]);
            let text = format!("{label}\n");
            prop_assert!(towernav_dataset::parse_labels(&text, Path::new("f.txt"), Some(1)).is_ok());
            if handle == Handle::Body {
                prop_assert!((d.width() - b.width()).abs() < 1e-9);
                prop_assert!((d.height() - b.height()).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn the_review_log_reads_back_and_a_bad_line_is_named() {
        let mut log = BTreeMap::new();
        log.insert("frame_000010".to_string(), [3, 1, 2]);
        log.insert("frame_000015".to_string(), [0, 0, 0]);
        let p = Path::new("review.csv");
        assert_eq!(parse_log(&format_log(&log), p).unwrap(), log);
        let err = parse_log("frame,kept,rejected,edited\nf1,2,x,0\n", p)
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 2") && err.contains("\"x\""), "{err}");
    }
}
