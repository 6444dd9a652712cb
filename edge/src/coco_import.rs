//! Reviewed labels back from COCO JSON (as CVAT and Label Studio export it)
//! into YOLO label files: one `labels/<image stem>.txt` per image, classes
//! in the order of the categories' ids, boxes normalised by each image's
//! size. Text in, files' text out; the command writes them.

use std::collections::HashMap;

use serde::Deserialize;
use towernav_dataset::YoloLabel;

#[derive(Debug, thiserror::Error)]
pub enum CocoError {
    #[error("{what}: not COCO JSON: {reason}")]
    Json { what: String, reason: String },
    #[error("{what}: annotation {annotation} names {field} {id}, which the file does not list")]
    Unknown {
        what: String,
        annotation: u64,
        field: &'static str,
        id: u64,
    },
    #[error("{what}: image {id} ({file}) has a size of {width}x{height}")]
    BadSize {
        what: String,
        id: u64,
        file: String,
        width: f64,
        height: f64,
    },
}

#[derive(Deserialize)]
struct Coco {
    images: Vec<CocoImage>,
    annotations: Vec<CocoAnnotation>,
    categories: Vec<CocoCategory>,
}

#[derive(Deserialize)]
struct CocoImage {
    id: u64,
    file_name: String,
    width: f64,
    height: f64,
}

#[derive(Deserialize)]
struct CocoAnnotation {
    #[serde(default)]
    id: u64,
    image_id: u64,
    category_id: u64,
    bbox: [f64; 4],
}

#[derive(Deserialize)]
struct CocoCategory {
    id: u64,
    name: String,
}

/// A YOLO label set: class names in id order, and each image's label file
/// (its stem, its text).
#[derive(Debug, Clone, PartialEq)]
pub struct YoloLabels {
    pub names: Vec<String>,
    pub files: Vec<(String, String)>,
}

/// Converts COCO JSON `text` (`what` names it in errors).
pub fn yolo_from_coco(text: &str, what: &str) -> Result<YoloLabels, CocoError> {
    let coco: Coco = serde_json::from_str(text).map_err(|e| CocoError::Json {
        what: what.into(),
        reason: e.to_string(),
    })?;
    let mut categories: Vec<&CocoCategory> = coco.categories.iter().collect();
    categories.sort_by_key(|c| c.id);
    let class_of: HashMap<u64, usize> = categories
        .iter()
        .enumerate()
        .map(|(i, c)| (c.id, i))
        .collect();
    let mut lines: HashMap<u64, String> = HashMap::new();
    let images: HashMap<u64, &CocoImage> = coco.images.iter().map(|i| (i.id, i)).collect();
    for image in &coco.images {
        if !(image.width > 0.0 && image.height > 0.0) {
            return Err(CocoError::BadSize {
                what: what.into(),
                id: image.id,
                file: image.file_name.clone(),
                width: image.width,
                height: image.height,
            });
        }
    }
    for a in &coco.annotations {
        let unknown = |field, id| CocoError::Unknown {
            what: what.into(),
            annotation: a.id,
            field,
            id,
        };
        let image = images
            .get(&a.image_id)
            .ok_or_else(|| unknown("image", a.image_id))?;
        let class = class_of
            .get(&a.category_id)
            .ok_or_else(|| unknown("category", a.category_id))?;
        let [x, y, w, h] = a.bbox;
        let line = lines.entry(a.image_id).or_default();
        let label = YoloLabel {
            class: *class,
            cx: (x + w / 2.0) / image.width,
            cy: (y + h / 2.0) / image.height,
            w: w / image.width,
            h: h / image.height,
        };
        line.push_str(&format!("{label}\n"));
    }
    let files = coco
        .images
        .iter()
        .map(|i| {
            let stem = std::path::Path::new(&i.file_name)
                .file_stem()
                .map_or_else(|| i.file_name.clone(), |s| s.to_string_lossy().into_owned());
            (stem, lines.remove(&i.id).unwrap_or_default())
        })
        .collect();
    Ok(YoloLabels {
        names: categories.iter().map(|c| c.name.clone()).collect(),
        files,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXPORT: &str = r#"{
        "images": [
            {"id": 1, "file_name": "frame_000000.jpg", "width": 1000, "height": 500},
            {"id": 2, "file_name": "frames/frame_000010.jpg", "width": 1000, "height": 500}
        ],
        "annotations": [
            {"id": 7, "image_id": 1, "category_id": 3, "bbox": [100, 50, 20, 100], "area": 2000, "iscrowd": 0}
        ],
        "categories": [{"id": 3, "name": "B"}, {"id": 1, "name": "A"}]
    }"#;

    #[test]
    fn coco_boxes_become_normalised_yolo_lines_by_category_order() {
        let y = yolo_from_coco(EXPORT, "review.json").expect("converts");
        assert_eq!(y.names, vec!["A", "B"]);
        assert_eq!(y.files[0].0, "frame_000000");
        assert_eq!(y.files[0].1, "1 0.110000 0.200000 0.020000 0.200000\n");
        assert_eq!(
            y.files[1],
            ("frame_000010".into(), String::new()),
            "no box: an empty file"
        );
    }

    #[test]
    fn an_annotation_of_an_unknown_image_or_category_is_refused_naming_it() {
        let bad = EXPORT.replace("\"category_id\": 3", "\"category_id\": 9");
        let err = yolo_from_coco(&bad, "review.json").expect_err("unknown category");
        assert!(
            err.to_string().contains("review.json") && err.to_string().contains("category 9"),
            "{err}"
        );
        let err = yolo_from_coco("[]", "x.json").expect_err("not COCO");
        assert!(err.to_string().contains("x.json"), "{err}");
    }
}
