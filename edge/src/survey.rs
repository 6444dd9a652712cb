//! `towernav-edge label`: a survey flight (video or images, a log with GNSS
//! and attitude, the calibration, the landmarks) turned into a YOLO dataset.
//! Each frame's pose is the log's GNSS and attitude at its time; every tower
//! is projected into it (`towernav_core::survey_labels`), kept when in view,
//! unhidden and tall enough, and snapped to the detector's box where they
//! agree. Writes `images/`, `labels/`, `data.yaml`, `report.csv` (every
//! tower in every labelled frame: projected box, written box, IoU, or why it
//! was dropped), `annotations.coco.json` (the same labels as COCO, which CVAT
//! and Label Studio import for review) and `contact_sheet.png` (frames
//! across the flight with their labels drawn: green snapped to the
//! detector, amber projected).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use towernav_core::survey_labels::{
    Dropped, FrameLabels, LabelCamera, LabelParams, SurveyTower, TowerLabel, WIDTH_PER_HEIGHT,
    borrow_widths, project_labels, snap,
};
use towernav_dataset::YoloLabel;
use towernav_flightlog::{FlightLog, GnssSample};
use towernav_geometry::{Datum, Geodetic, PixelBox, Pose};
use towernav_protocol::LandmarkRecord;

use crate::daemon::config::EdgeConfig;
use crate::edge_cmd::load_detector;
use crate::replay::Recording;

/// What the labeller did.
#[derive(Debug, Clone, Default)]
pub struct LabelRun {
    pub frames: u64,
    pub labelled_frames: u64,
    pub labels: usize,
    pub snapped: usize,
    pub dropped: usize,
    /// Frames with no GNSS fix around them (no pose, no labels).
    pub without_pose: u64,
}

/// Options beyond the config's source, log, camera, landmarks and detector.
#[derive(Debug, Clone)]
pub struct LabelOptions {
    pub params: LabelParams,
    /// Label every n-th frame.
    pub every: u64,
    /// Snap to the detector's boxes (off: projections only).
    pub snap: bool,
    /// One class, `tower`, instead of the database's types.
    pub one_class: bool,
    pub out: PathBuf,
}

pub(crate) fn survey_towers(
    records: &[LandmarkRecord],
    datum: &Datum,
) -> anyhow::Result<Vec<SurveyTower>> {
    records
        .iter()
        .map(|r| {
            let foot = Geodetic::new(r.lat_deg, r.lon_deg, r.ground_elev_m)
                .with_context(|| format!("tower {}", r.id))?;
            Ok(SurveyTower {
                id: r.id.clone(),
                tower_type: r.tower_type,
                foot_in_world: datum.to_enu(&foot),
                height_m: r.height_m,
                width_m: r
                    .base_width_m
                    .unwrap_or(0.0)
                    .max(WIDTH_PER_HEIGHT * r.height_m),
            })
        })
        .collect()
}

/// A survey flight's world frame: its log's first GNSS fix.
pub(crate) fn survey_datum(log: &FlightLog) -> anyhow::Result<Datum> {
    log.gnss
        .first()
        .and_then(GnssSample::geodetic)
        .map(Datum::new)
        .context("the flight log has no GNSS: a survey flight needs it for the poses")
}

/// The pose a survey flight's log gives at `log_time_s`: its GNSS and
/// attitude; `None` where the log has neither around that time.
pub(crate) fn survey_pose(log: &FlightLog, datum: &Datum, log_time_s: f64) -> Option<Pose> {
    Some(Pose {
        position_in_world: datum.to_enu(&log.gnss_at(log_time_s)?.geodetic()?),
        attitude: log.attitude_at(log_time_s)?,
    })
}

/// Labels the survey flight `config` names into `options.out`.
pub fn label_flight(
    config: &EdgeConfig,
    options: &LabelOptions,
    mut progress: impl FnMut(u64, Option<u64>),
) -> anyhow::Result<LabelRun> {
    let Recording {
        config,
        source,
        log,
        offset_s,
    } = Recording::open(config)?;
    let (width, height) = (config.source.width, config.source.height);
    let datum = survey_datum(&log)?;
    let camera = config.camera.camera(width, height)?;
    let labeller = LabelCamera::new(camera);
    let records = towernav_landmark_db::load_towers(
        config
            .landmarks
            .file
            .as_deref()
            .context("labels need the landmarks (--landmarks)")?,
    )?;
    let towers = survey_towers(&records, &datum)?;
    let mut detector = match options.snap {
        true => load_detector(&config.detector)?.0,
        false => None,
    };
    let classes = class_names(&towers, options.one_class);
    let mut writer = DatasetWriter::create(&options.out, &classes, (width, height))?;

    let mut run = LabelRun::default();
    let mut report = String::from(
        "frame,tower_id,status,projected_left,projected_top,projected_right,projected_bottom,\
         label_left,label_top,label_right,label_bottom,iou_with_projection,distance_m\n",
    );
    let mut source = source;
    let total = source.frame_count();
    let every = options.every.max(1);
    let mut names = Vec::new();
    let mut flight: Vec<FrameLabels> = Vec::new();
    while let Some(frame) = source.next_frame() {
        let frame = frame?;
        run.frames += 1;
        progress(frame.seq, total);
        if frame.seq % every != 0 {
            continue;
        }
        let (Some(pose), Some(image)) = (
            survey_pose(&log, &datum, frame.time_s + offset_s),
            frame.image.as_ref(),
        ) else {
            run.without_pose += 1;
            continue;
        };
        let mut labels = project_labels(&labeller, &pose, &towers, &options.params);
        if let Some(detector) = &mut detector {
            let boxes: Vec<PixelBox> = detector
                .detect(image, frame.seq)
                .with_context(|| format!("the detector on frame {}", frame.seq))?
                .into_iter()
                .map(|d| d.bbox)
                .collect();
            snap(
                &mut labels,
                &boxes,
                &options.params,
                (f64::from(width), f64::from(height)),
            );
        }
        let name = format!("frame_{:06}", frame.seq);
        writer.save_image(&name, image)?;
        names.push(name);
        flight.push((frame.time_s, labels));
    }
    // Widths come from the whole flight: a tower is often far, unsnapped,
    // before the frames where the detector boxes it.
    borrow_widths(&mut flight, &options.params);
    for (index, (name, (_, labels))) in names.iter().zip(&flight).enumerate() {
        run.labelled_frames += 1;
        run.labels += writer.write_labels(index, name, labels, &towers, &classes)?;
        for l in labels {
            run.snapped += usize::from(l.dropped.is_none() && l.snapped.is_some());
            run.dropped += usize::from(l.dropped.is_some());
            report_row(&mut report, name, l, &towers);
        }
    }
    writer.finish(&classes)?;
    let report_path = options.out.join("report.csv");
    std::fs::write(&report_path, report)
        .with_context(|| format!("writing {}", report_path.display()))?;
    Ok(run)
}

fn class_names(towers: &[SurveyTower], one_class: bool) -> Vec<String> {
    if one_class {
        return vec!["tower".into()];
    }
    let mut names: Vec<String> = towers.iter().map(|t| t.tower_type.to_string()).collect();
    names.sort();
    names.dedup();
    names
}

fn report_row(out: &mut String, frame: &str, l: &TowerLabel, towers: &[SurveyTower]) {
    let p = &l.projected;
    let status = match l.dropped {
        None if l.snapped.is_some() => "snapped".to_string(),
        None => match (l.shifted, l.width_from_s) {
            (Some(_), Some(t)) => {
                format!("shifted by the frame's offset; width from the snapped box at {t:.1} s")
            }
            (Some(_), None) => "shifted by the frame's offset".to_string(),
            (None, _) => "projected".to_string(),
        },
        Some(Dropped::OutOfView) => "dropped: out of view".to_string(),
        Some(Dropped::CutByFrame { in_frame }) => {
            format!("dropped: {:.0} % in frame", 100.0 * in_frame)
        }
        Some(Dropped::TooSmall { height_px }) => format!("dropped: {height_px:.0} px tall"),
        Some(Dropped::Hidden { covered }) => {
            format!("dropped: {:.0} % behind nearer towers", 100.0 * covered)
        }
        Some(Dropped::Unconfirmed) => {
            "dropped: at the frame's edge and no detector box agrees".into()
        }
    };
    let (s, iou) = match l.snapped.or(l.shifted.map(|b| (b, l.projected.iou(&b)))) {
        Some((b, iou)) => (
            format!("{:.1},{:.1},{:.1},{:.1}", b.left, b.top, b.right, b.bottom),
            format!("{iou:.3}"),
        ),
        None => (",,,".into(), String::new()),
    };
    let _ = writeln!(
        out,
        "{frame},{},{status},{:.1},{:.1},{:.1},{:.1},{s},{iou},{:.1}",
        towers[l.tower].id, p.left, p.top, p.right, p.bottom, l.distance_m
    );
}

/// A YOLO dataset on disk: `images/`, `labels/`, `data.yaml`; the COCO
/// file and the contact sheet at the end.
struct DatasetWriter {
    out: PathBuf,
    images: PathBuf,
    labels: PathBuf,
    coco_images: Vec<serde_json::Value>,
    coco_annotations: Vec<serde_json::Value>,
    tiles: Vec<image::RgbImage>,
    /// The camera's frame, pixels.
    width: f64,
    height: f64,
}

/// Contact-sheet tiles: this wide, at most this many, this many a row.
const TILE_WIDTH: u32 = 320;
const SHEET_TILES: usize = 24;
const SHEET_COLUMNS: usize = 4;

/// A frame shrunk to a contact-sheet tile.
fn tile(image: &image::RgbImage) -> image::RgbImage {
    let scale = f64::from(TILE_WIDTH) / f64::from(image.width().max(1));
    let th = (f64::from(image.height()) * scale).round().max(1.0) as u32;
    image::imageops::resize(image, TILE_WIDTH, th, image::imageops::FilterType::Triangle)
}

/// A frame's labels drawn on its tile: green snapped to the detector, amber
/// projected.
fn draw_labels(tile: &mut image::RgbImage, labels: &[TowerLabel], w: f64, h: f64) {
    let scale = f64::from(tile.width()) / w;
    for l in labels {
        let Some(b) = l.label() else { continue };
        let b = b.clipped(w, h);
        let small = PixelBox::new(
            b.left * scale,
            b.top * scale,
            b.right * scale,
            b.bottom * scale,
        );
        let colour = if l.snapped.is_some() {
            [40, 220, 80]
        } else {
            [255, 180, 0]
        };
        draw_box(tile, &small, colour, 1);
    }
}

/// A box's outline, `thickness` pixels, clipped to the image.
fn draw_box(image: &mut image::RgbImage, b: &PixelBox, colour: [u8; 3], thickness: i64) {
    let (w, h) = (i64::from(image.width()), i64::from(image.height()));
    let (x0, y0, x1, y1) = (b.left as i64, b.top as i64, b.right as i64, b.bottom as i64);
    for y in y0.max(0)..=y1.min(h - 1) {
        for x in x0.max(0)..=x1.min(w - 1) {
            let edge = x - x0 < thickness
                || x1 - x < thickness
                || y - y0 < thickness
                || y1 - y < thickness;
            if edge {
                image.put_pixel(x as u32, y as u32, image::Rgb(colour));
            }
        }
    }
}

impl DatasetWriter {
    fn create(out: &Path, classes: &[String], (width, height): (u32, u32)) -> anyhow::Result<Self> {
        let images = out.join("images");
        let labels = out.join("labels");
        for dir in [&images, &labels] {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        let mut yaml = format!(
            "# Labels projected from a survey flight (towernav-edge label).\npath: {}\ntrain: images\nval: images\nnames:\n",
            std::path::absolute(out)
                .unwrap_or_else(|_| out.to_path_buf())
                .display()
        );
        for (i, c) in classes.iter().enumerate() {
            let _ = writeln!(yaml, "  {i}: {c:?}");
        }
        let path = out.join("data.yaml");
        std::fs::write(&path, yaml).with_context(|| format!("writing {}", path.display()))?;
        Ok(Self {
            out: out.to_path_buf(),
            images,
            labels,
            coco_images: Vec::new(),
            coco_annotations: Vec::new(),
            tiles: Vec::new(),
            width: f64::from(width),
            height: f64::from(height),
        })
    }

    /// `annotations.coco.json` and `contact_sheet.png`.
    fn finish(&self, classes: &[String]) -> anyhow::Result<()> {
        let categories: Vec<serde_json::Value> = classes
            .iter()
            .enumerate()
            .map(|(i, c)| serde_json::json!({ "id": i + 1, "name": c, "supercategory": "tower" }))
            .collect();
        let coco = serde_json::json!({
            "info": { "description": "Labels projected from a survey flight (towernav-edge label)" },
            "images": self.coco_images,
            "annotations": self.coco_annotations,
            "categories": categories,
        });
        let path = self.out.join("annotations.coco.json");
        std::fs::write(&path, serde_json::to_string_pretty(&coco)?)
            .with_context(|| format!("writing {}", path.display()))?;
        if self.tiles.is_empty() {
            return Ok(());
        }
        let step = self.tiles.len().div_ceil(SHEET_TILES);
        let chosen: Vec<&image::RgbImage> = self.tiles.iter().step_by(step).collect();
        let (tw, th) = chosen[0].dimensions();
        let rows = chosen.len().div_ceil(SHEET_COLUMNS) as u32;
        let cols = chosen.len().min(SHEET_COLUMNS) as u32;
        let mut sheet = image::RgbImage::new(cols * tw, rows * th);
        for (i, tile) in chosen.iter().enumerate() {
            let (c, r) = ((i % SHEET_COLUMNS) as i64, (i / SHEET_COLUMNS) as i64);
            image::imageops::replace(&mut sheet, *tile, c * i64::from(tw), r * i64::from(th));
        }
        let path = self.out.join("contact_sheet.png");
        sheet
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))
    }

    /// One frame's image, with its tile kept for the contact sheet.
    fn save_image(&mut self, name: &str, image: &image::RgbImage) -> anyhow::Result<()> {
        self.coco_images.push(serde_json::json!({
            "id": self.coco_images.len() + 1, "file_name": format!("{name}.jpg"),
            "width": image.width(), "height": image.height(),
        }));
        self.tiles.push(tile(image));
        let image_path = self.images.join(format!("{name}.jpg"));
        image
            .save(&image_path)
            .with_context(|| format!("writing {}", image_path.display()))
    }

    /// The label file of the `index`-th saved image; the number of labels written.
    fn write_labels(
        &mut self,
        index: usize,
        name: &str,
        labels: &[TowerLabel],
        towers: &[SurveyTower],
        classes: &[String],
    ) -> anyhow::Result<usize> {
        let (w, h) = (self.width, self.height);
        let mut text = String::new();
        let mut n = 0;
        for l in labels {
            let Some(b) = l.label() else { continue };
            let b = b.clipped(w, h);
            let class = match classes.len() {
                1 => 0,
                _ => classes
                    .iter()
                    .position(|c| *c == towers[l.tower].tower_type.to_string())
                    .unwrap_or(0),
            };
            let _ = writeln!(text, "{}", YoloLabel::from_pixels(class, &b, w, h));
            self.coco_annotations.push(serde_json::json!({
                "id": self.coco_annotations.len() + 1,
                "image_id": index + 1,
                "category_id": class + 1,
                "bbox": [b.left, b.top, b.width(), b.height()],
                "area": b.area(),
                "iscrowd": 0,
            }));
            n += 1;
        }
        if let Some(tile) = self.tiles.get_mut(index) {
            draw_labels(tile, labels, w, h);
        }
        let label_path = self.labels.join(format!("{name}.txt"));
        std::fs::write(&label_path, text)
            .with_context(|| format!("writing {}", label_path.display()))?;
        Ok(n)
    }
}
