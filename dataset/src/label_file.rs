//! Label files written back: the survey labeller, the COCO import and the
//! ground station's review all write the same text, and a reviewed file
//! replaces the old one whole or not at all.

use std::io::Write;
use std::path::Path;

use crate::folder::{FolderError, YoloLabel};

/// A label file's text: one line per box, newline-terminated; empty for an
/// image with no tower.
pub fn format_labels(labels: &[YoloLabel]) -> String {
    labels.iter().map(|l| format!("{l}\n")).collect()
}

/// Writes `labels` to `path` through a temporary file in the same folder and
/// a rename, so a crash or a full disk never leaves a half-written file that
/// training would read as fewer towers.
pub fn write_labels(path: &Path, labels: &[YoloLabel]) -> Result<(), FolderError> {
    let io = |source| FolderError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(io)?;
    let mut tmp = tempfile_in(dir, path).map_err(io)?;
    let result = (|| {
        tmp.1.write_all(format_labels(labels).as_bytes())?;
        tmp.1.sync_all()?;
        std::fs::rename(&tmp.0, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp.0);
    }
    result.map_err(io)
}

/// A new file beside `path`, named after it and this process.
fn tempfile_in(dir: &Path, path: &Path) -> std::io::Result<(std::path::PathBuf, std::fs::File)> {
    let name = path
        .file_name()
        .map_or_else(|| "labels".into(), |n| n.to_string_lossy().into_owned());
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let file = std::fs::File::create(&tmp)?;
    Ok((tmp, file))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folder::parse_labels;
    use proptest::prelude::*;

    proptest! {
        /// What is written reads back as the same boxes, to the six decimals written.
        #[test]
        fn written_labels_read_back(
            boxes in prop::collection::vec(
                (0usize..8, 0.05f64..0.95, 0.05f64..0.95, 0.01f64..0.1, 0.01f64..0.1),
                0..12,
            )
        ) {
            let labels: Vec<YoloLabel> = boxes
                .iter()
                .map(|&(class, cx, cy, w, h)| YoloLabel { class, cx, cy, w, h })
                .collect();
            let text = format_labels(&labels);
            let back = parse_labels(&text, Path::new("x.txt"), Some(8)).unwrap();
            prop_assert_eq!(back.len(), labels.len());
            for (a, b) in labels.iter().zip(&back) {
                prop_assert_eq!(a.class, b.class);
                for (x, y) in [(a.cx, b.cx), (a.cy, b.cy), (a.w, b.w), (a.h, b.h)] {
                    prop_assert!((x - y).abs() <= 5e-7);
                }
            }
        }
    }

    #[test]
    fn a_written_file_replaces_the_old_one_and_leaves_nothing_beside_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels").join("f1.txt");
        let one = YoloLabel {
            class: 1,
            cx: 0.5,
            cy: 0.5,
            w: 0.1,
            h: 0.3,
        };
        write_labels(&path, &[one, one]).unwrap();
        write_labels(&path, &[one]).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "1 0.500000 0.500000 0.100000 0.300000\n"
        );
        let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["f1.txt"]);
    }
}
