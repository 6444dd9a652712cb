//! Labelled image folders as people keep them: an Ultralytics dataset
//! (`data.yaml` naming its splits and classes), or `images/` beside
//! `labels/` (or `labels_yolo/`) with one YOLO text file per image and the
//! class names in `classes.txt`. An image without a label file, or with an
//! empty one, shows no tower. Parsing is pure; [`ImageFolder::open`] reads
//! the files.

use std::path::{Path, PathBuf};

use yaml_rust2::{Yaml, YamlLoader};

/// One label line: class and box, normalized to the image (centre, size).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YoloLabel {
    pub class: usize,
    pub cx: f64,
    pub cy: f64,
    pub w: f64,
    pub h: f64,
}

impl YoloLabel {
    /// The box in pixels of a `width` x `height` image.
    pub fn pixels(&self, width: f64, height: f64) -> towernav_geometry::PixelBox {
        towernav_geometry::PixelBox {
            left: (self.cx - self.w / 2.0) * width,
            top: (self.cy - self.h / 2.0) * height,
            right: (self.cx + self.w / 2.0) * width,
            bottom: (self.cy + self.h / 2.0) * height,
        }
    }

    /// The label of pixel box `b` in a `width` x `height` image.
    pub fn from_pixels(
        class: usize,
        b: &towernav_geometry::PixelBox,
        width: f64,
        height: f64,
    ) -> Self {
        Self {
            class,
            cx: b.center_x() / width,
            cy: b.center_y() / height,
            w: b.width() / width,
            h: b.height() / height,
        }
    }
}

/// One line of a label file, without its newline; six decimals, as
/// Ultralytics writes them (a tenth of a pixel at 4K).
impl std::fmt::Display for YoloLabel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {:.6} {:.6} {:.6} {:.6}",
            self.class, self.cx, self.cy, self.w, self.h
        )
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct LabelledImage {
    pub image: PathBuf,
    /// Where its labels are (or would be: an image with no tower may have no file).
    pub label_path: PathBuf,
    pub labels: Vec<YoloLabel>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ImageFolder {
    /// Where the images were found.
    pub images_dir: PathBuf,
    pub names: Vec<String>,
    pub images: Vec<LabelledImage>,
}

#[derive(Debug, thiserror::Error)]
pub enum FolderError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: not a readable data.yaml: {message}")]
    DataYaml { path: PathBuf, message: String },
    #[error("{path}, line {line}: {message}")]
    Label {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error(
        "{path}: no data.yaml and no images/ folder (expected an Ultralytics dataset, or images/ with labels/ or labels_yolo/ beside it)"
    )]
    NotAFolder { path: PathBuf },
    #[error("{path}: no .jpg, .jpeg or .png images")]
    NoImages { path: PathBuf },
}

/// What `data.yaml` says: its root, its splits' image folders, its class names.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DataYaml {
    pub path: Option<String>,
    pub train: Option<String>,
    pub val: Option<String>,
    pub test: Option<String>,
    pub names: Vec<String>,
}

/// Parse `data.yaml`; `names` may be a list or a map from index to name.
pub fn parse_data_yaml(text: &str, path: &Path) -> Result<DataYaml, FolderError> {
    let fail = |message: String| FolderError::DataYaml {
        path: path.to_path_buf(),
        message,
    };
    let docs = YamlLoader::load_from_str(text).map_err(|e| fail(e.to_string()))?;
    let doc = docs.first().ok_or_else(|| fail("empty".into()))?;
    let text_of = |key: &str| match &doc[key] {
        Yaml::String(s) => Some(s.clone()),
        _ => None,
    };
    let names = match &doc["names"] {
        Yaml::Array(items) => items
            .iter()
            .map(|n| scalar(n).ok_or_else(|| fail(format!("names holds {n:?}, not a name"))))
            .collect::<Result<Vec<_>, _>>()?,
        Yaml::Hash(map) => {
            let mut pairs = map
                .iter()
                .map(|(k, v)| match (k, scalar(v)) {
                    (Yaml::Integer(i), Some(name)) if *i >= 0 => Ok((*i as usize, name)),
                    _ => Err(fail(format!("names maps {k:?} to {v:?}"))),
                })
                .collect::<Result<Vec<_>, _>>()?;
            pairs.sort();
            if pairs.iter().enumerate().any(|(i, (k, _))| i != *k) {
                return Err(fail("names' indices are not 0, 1, 2, ...".into()));
            }
            pairs.into_iter().map(|(_, n)| n).collect()
        }
        Yaml::BadValue => Vec::new(),
        other => return Err(fail(format!("names is {other:?}"))),
    };
    Ok(DataYaml {
        path: text_of("path"),
        train: text_of("train"),
        val: text_of("val"),
        test: text_of("test"),
        names,
    })
}

fn scalar(y: &Yaml) -> Option<String> {
    match y {
        Yaml::String(s) => Some(s.clone()),
        Yaml::Integer(i) => Some(i.to_string()),
        _ => None,
    }
}

/// Parse one YOLO label file: `class cx cy w h` per line, normalized; blank
/// lines and `#` comments are skipped. A class at or past `classes` (when
/// known) or a box outside the image is an error naming the line.
pub fn parse_labels(
    text: &str,
    path: &Path,
    classes: Option<usize>,
) -> Result<Vec<YoloLabel>, FolderError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fail = |message: String| FolderError::Label {
            path: path.to_path_buf(),
            line: i + 1,
            message,
        };
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 5 {
            return Err(fail(format!(
                "{} fields, expected 5 (class cx cy w h); segments are not boxes",
                fields.len()
            )));
        }
        let class: usize = fields[0]
            .parse()
            .map_err(|_| fail(format!("class {:?} is not a whole number", fields[0])))?;
        if let Some(n) = classes
            && class >= n
        {
            return Err(fail(format!("class {class}, but only {n} names are given")));
        }
        let mut v = [0.0f64; 4];
        for (slot, field) in v.iter_mut().zip(&fields[1..]) {
            *slot = field
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| fail(format!("{field:?} is not a number")))?;
        }
        let [cx, cy, w, h] = v;
        let inside = |c: f64, s: f64| s > 0.0 && c - s / 2.0 >= -0.01 && c + s / 2.0 <= 1.01;
        if !inside(cx, w) || !inside(cy, h) {
            return Err(fail(format!(
                "box {cx} {cy} {w} {h} is not inside the image (normalized 0..1)"
            )));
        }
        out.push(YoloLabel {
            class,
            cx,
            cy,
            w,
            h,
        });
    }
    Ok(out)
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> FolderError + '_ {
    move |source| FolderError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Image files under `dir`, one folder level deep, in name order.
pub fn images_under(dir: &Path) -> Result<Vec<PathBuf>, FolderError> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io(dir))? {
        let path = entry.map_err(io(dir))?.path();
        if path.is_dir() {
            for inner in std::fs::read_dir(&path).map_err(io(&path))? {
                let p = inner.map_err(io(&path))?.path();
                if is_image(&p) {
                    out.push(p);
                }
            }
        } else if is_image(&path) {
            out.push(path);
        }
    }
    out.sort();
    if out.is_empty() {
        return Err(FolderError::NoImages {
            path: dir.to_path_buf(),
        });
    }
    Ok(out)
}

fn is_image(p: &Path) -> bool {
    p.is_file()
        && p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "jpg" | "jpeg" | "png"))
}

impl ImageFolder {
    /// Open `dir`: with a `data.yaml`, its `split` (default: test, else
    /// val); else `images/` with `labels/` or `labels_yolo/`. `names`
    /// overrides the folder's class names.
    pub fn open(
        dir: &Path,
        split: Option<&str>,
        names: Option<&[String]>,
    ) -> Result<Self, FolderError> {
        let yaml_path = dir.join("data.yaml");
        let (images_dir, labels_dir, found_names) = if yaml_path.is_file() {
            let text = std::fs::read_to_string(&yaml_path).map_err(io(&yaml_path))?;
            let data = parse_data_yaml(&text, &yaml_path)?;
            let root = data
                .path
                .as_deref()
                .map_or(dir.to_path_buf(), |p| dir.join(p));
            let chosen = match split {
                Some("train") => data.train.clone(),
                Some("val") => data.val.clone(),
                Some("test") => data.test.clone(),
                Some(other) => {
                    return Err(FolderError::DataYaml {
                        path: yaml_path,
                        message: format!("no split {other:?} (train, val or test)"),
                    });
                }
                None => data.test.clone().or(data.val.clone()),
            }
            .ok_or_else(|| FolderError::DataYaml {
                path: yaml_path.clone(),
                message: format!("has no {} split", split.unwrap_or("test or val")),
            })?;
            let images = root.join(&chosen);
            let labels = labels_for(&images);
            (images, labels, data.names)
        } else if dir.join("images").is_dir() {
            let labels = ["labels", "labels_yolo"]
                .iter()
                .map(|l| dir.join(l))
                .find(|p| p.is_dir())
                .unwrap_or_else(|| dir.join("labels"));
            let classes = dir.join("classes.txt");
            let names = if classes.is_file() {
                std::fs::read_to_string(&classes)
                    .map_err(io(&classes))?
                    .lines()
                    .map(str::trim)
                    .filter(|l| !l.is_empty())
                    .map(String::from)
                    .collect()
            } else {
                Vec::new()
            };
            (dir.join("images"), labels, names)
        } else {
            return Err(FolderError::NotAFolder {
                path: dir.to_path_buf(),
            });
        };
        let names: Vec<String> = names.map_or(found_names, <[String]>::to_vec);
        let known = (!names.is_empty()).then_some(names.len());
        let mut images = Vec::new();
        for image in images_under(&images_dir)? {
            let rel = image.strip_prefix(&images_dir).unwrap_or(&image);
            let label = labels_dir.join(rel).with_extension("txt");
            let labels = match std::fs::read_to_string(&label) {
                Ok(text) => parse_labels(&text, &label, known)?,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
                Err(e) => return Err(io(&label)(e)),
            };
            images.push(LabelledImage {
                image,
                label_path: label,
                labels,
            });
        }
        let classes = images
            .iter()
            .flat_map(|i| &i.labels)
            .map(|l| l.class + 1)
            .max()
            .unwrap_or(0);
        let names = if names.is_empty() {
            (0..classes).map(|c| format!("class{c}")).collect()
        } else {
            names
        };
        Ok(Self {
            images_dir,
            names,
            images,
        })
    }
}

/// Ultralytics' rule: the labels of `.../images/<x>` are in `.../labels/<x>`.
pub fn labels_for(images: &Path) -> PathBuf {
    let parts: Vec<_> = images.components().collect();
    match parts.iter().rposition(|c| c.as_os_str() == "images") {
        Some(i) => {
            let mut p: PathBuf = parts[..i].iter().collect();
            p.push("labels");
            p.extend(&parts[i + 1..]);
            p
        }
        None => images.with_file_name("labels"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_come_as_a_list_or_a_map() {
        let p = Path::new("data.yaml");
        let list =
            parse_data_yaml("path: /d\nval: images/val\nnames: [lattice, tubular]\n", p).unwrap();
        assert_eq!(list.names, ["lattice", "tubular"]);
        assert_eq!(list.val.as_deref(), Some("images/val"));
        let map = parse_data_yaml("test: images/test\nnames:\n  1: B\n  0: A\n", p).unwrap();
        assert_eq!(map.names, ["A", "B"]);
        assert!(parse_data_yaml("names:\n  0: A\n  2: C\n", p).is_err());
        assert!(parse_data_yaml("names: [a\n", p).is_err());
    }

    #[test]
    fn bad_label_lines_are_named() {
        let p = Path::new("x.txt");
        let ok = parse_labels(
            "# note\n0 0.5 0.5 0.2 0.4\n\n1 0.1 0.2 0.1 0.1\n",
            p,
            Some(2),
        )
        .unwrap();
        assert_eq!(ok.len(), 2);
        assert_eq!(ok[1].class, 1);
        for (text, needle) in [
            ("0 0.5 0.5 0.2\n", "4 fields"),
            ("3 0.5 0.5 0.2 0.2\n", "only 2 names"),
            ("0 0.5 nan 0.2 0.2\n", "not a number"),
            ("0 0.95 0.5 0.2 0.2\n", "not inside"),
            ("x 0.5 0.5 0.2 0.2\n", "whole number"),
        ] {
            let err = parse_labels(text, p, Some(2)).unwrap_err().to_string();
            assert!(err.contains("line 1") && err.contains(needle), "{err}");
        }
    }

    #[test]
    fn labels_sit_where_ultralytics_looks() {
        assert_eq!(
            labels_for(Path::new("/d/images/val")),
            PathBuf::from("/d/labels/val")
        );
    }
}
