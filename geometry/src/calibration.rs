//! Camera calibration files as the usual tools write them: OpenCV's
//! `FileStorage` (YAML with `!!opencv-matrix`, or JSON), ROS `camera_info`
//! YAML and Kalibr's camchain YAML. Text in, a camera out: reading the file
//! is the caller's.

use serde_yaml_ng::{Mapping, Value};

use crate::camera::Intrinsics;
use crate::distortion::Distortion;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CalibrationError {
    #[error("not YAML or JSON: {0}")]
    Syntax(String),
    #[error("{field}: {reason}")]
    Field { field: String, reason: String },
    #[error(
        "no camera found: expected OpenCV's camera_matrix, ROS camera_info's camera_matrix \
         or a Kalibr cam0 with intrinsics"
    )]
    NotACalibration,
    #[error(
        "the calibration is for {calibrated_width}x{calibrated_height} images but the frames are \
         {width}x{height}; calibrate at the frames' size or set the source's size to the calibrated one"
    )]
    SizeMismatch {
        calibrated_width: u32,
        calibrated_height: u32,
        width: u32,
        height: u32,
    },
}

/// A calibrated camera: intrinsics at the calibrated image size, and its lens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
    /// Which writer's layout it was read as.
    pub format: CalibrationFormat,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationFormat {
    OpenCv,
    RosCameraInfo,
    Kalibr,
}

impl Calibration {
    /// Reads any of the supported layouts, told apart by their keys.
    pub fn parse(text: &str) -> Result<Self, CalibrationError> {
        let root = parse_document(text)?;
        let Some(map) = root.as_mapping() else {
            return Err(CalibrationError::NotACalibration);
        };
        if let Some(cam) = map.get("cam0").and_then(Value::as_mapping) {
            return kalibr(cam);
        }
        if map.contains_key("camera_matrix") {
            return camera_matrix_layout(map);
        }
        Err(CalibrationError::NotACalibration)
    }

    /// Refuses frames of another size than the calibrated one, naming both.
    pub fn check_size(&self, width: u32, height: u32) -> Result<(), CalibrationError> {
        let k = &self.intrinsics;
        if (k.width, k.height) == (width, height) {
            return Ok(());
        }
        Err(CalibrationError::SizeMismatch {
            calibrated_width: k.width,
            calibrated_height: k.height,
            width,
            height,
        })
    }
}

/// YAML 1.2 parsers refuse OpenCV's `%YAML:1.0` directive and know nothing of
/// its `!!opencv-matrix` tag; both carry no data, so they go before parsing.
/// JSON is YAML, so OpenCV's JSON files take the same road.
fn parse_document(text: &str) -> Result<Value, CalibrationError> {
    let cleaned: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("%YAML"))
        .map(|l| l.replace("!!opencv-matrix", ""))
        .collect::<Vec<_>>()
        .join("\n");
    serde_yaml_ng::from_str(&cleaned).map_err(|e| CalibrationError::Syntax(e.to_string()))
}

fn field(name: &str, reason: impl Into<String>) -> CalibrationError {
    CalibrationError::Field {
        field: name.to_string(),
        reason: reason.into(),
    }
}

fn number(v: &Value, name: &str) -> Result<f64, CalibrationError> {
    v.as_f64()
        .filter(|x| x.is_finite())
        .ok_or_else(|| field(name, format!("{v:?} is not a finite number")))
}

fn numbers(v: &Value, name: &str) -> Result<Vec<f64>, CalibrationError> {
    v.as_sequence()
        .ok_or_else(|| field(name, "is not a list of numbers"))?
        .iter()
        .map(|x| number(x, name))
        .collect()
}

/// A matrix as OpenCV (`rows`, `cols`, `data`) or ROS (`rows`, `cols`,
/// `data`) write it, or a bare list.
fn matrix(v: &Value, name: &str) -> Result<Vec<f64>, CalibrationError> {
    let data = match v {
        Value::Mapping(m) => {
            let data = numbers(
                m.get("data")
                    .ok_or_else(|| field(name, "has no data list"))?,
                &format!("{name}.data"),
            )?;
            let dim = |key: &str| m.get(key).and_then(Value::as_u64);
            if let (Some(rows), Some(cols)) = (dim("rows"), dim("cols"))
                && rows * cols != data.len() as u64
            {
                return Err(field(
                    name,
                    format!("{rows}x{cols} but data has {} values", data.len()),
                ));
            }
            data
        }
        other => numbers(other, name)?,
    };
    Ok(data)
}

fn size(map: &Mapping, width_key: &str, height_key: &str) -> Result<(u32, u32), CalibrationError> {
    let side = |key: &str| -> Result<u32, CalibrationError> {
        let v = map
            .get(key)
            .ok_or_else(|| field(key, "is missing: the calibrated image size is needed"))?;
        v.as_u64()
            .and_then(|x| u32::try_from(x).ok())
            .filter(|x| *x > 0)
            .ok_or_else(|| field(key, format!("{v:?} is not an image size")))
    };
    Ok((side(width_key)?, side(height_key)?))
}

fn intrinsics(
    (width, height): (u32, u32),
    [fx, fy, cx, cy]: [f64; 4],
    name: &str,
) -> Result<Intrinsics, CalibrationError> {
    if !(fx > 0.0 && fy > 0.0) {
        return Err(field(
            name,
            format!("focal lengths {fx}, {fy} must be positive"),
        ));
    }
    Ok(Intrinsics {
        width,
        height,
        fx,
        fy,
        cx,
        cy,
    })
}

/// OpenCV's calibration sample and ROS `camera_info`: `camera_matrix` 3x3,
/// `distortion_coefficients`, and the model by name (ROS `distortion_model`)
/// or OpenCV's `fisheye_model` flag.
fn camera_matrix_layout(map: &Mapping) -> Result<Calibration, CalibrationError> {
    let k = matrix(&map["camera_matrix"], "camera_matrix")?;
    if k.len() != 9 {
        return Err(field(
            "camera_matrix",
            format!("has {} values, not 9", k.len()),
        ));
    }
    let format = if map.contains_key("camera_name") || map.contains_key("projection_matrix") {
        CalibrationFormat::RosCameraInfo
    } else {
        CalibrationFormat::OpenCv
    };
    let intrinsics = intrinsics(
        size(map, "image_width", "image_height")?,
        [k[0], k[4], k[2], k[5]],
        "camera_matrix",
    )?;
    let coefficients = match map.get("distortion_coefficients") {
        Some(v) => matrix(v, "distortion_coefficients")?,
        None => Vec::new(),
    };
    let model = match map.get("distortion_model") {
        Some(v) => v
            .as_str()
            .ok_or_else(|| field("distortion_model", "is not text"))?
            .to_string(),
        None if map
            .get("fisheye_model")
            .is_some_and(|v| v.as_u64() == Some(1) || v.as_bool() == Some(true)) =>
        {
            "equidistant".into()
        }
        None => "plumb_bob".into(),
    };
    let distortion = distortion_from(&model, &coefficients, "distortion_coefficients")?;
    Ok(Calibration {
        intrinsics,
        distortion,
        format,
    })
}

/// Kalibr's camchain: `cam0` with `intrinsics: [fu, fv, pu, pv]`,
/// `distortion_model` (`radtan`, `equidistant`), `distortion_coeffs` and
/// `resolution: [width, height]`.
fn kalibr(cam: &Mapping) -> Result<Calibration, CalibrationError> {
    let get = |key: &str| {
        cam.get(key)
            .ok_or_else(|| field(&format!("cam0.{key}"), "is missing"))
    };
    if let Some(model) = cam.get("camera_model").and_then(Value::as_str)
        && model != "pinhole"
    {
        return Err(field(
            "cam0.camera_model",
            format!("{model:?} is not supported; calibrate with the pinhole model"),
        ));
    }
    let k = numbers(get("intrinsics")?, "cam0.intrinsics")?;
    let [fx, fy, cx, cy] = k[..] else {
        return Err(field("cam0.intrinsics", "must be [fu, fv, pu, pv]"));
    };
    let resolution = numbers(get("resolution")?, "cam0.resolution")?;
    let (width, height) = match resolution[..] {
        [w, h] if w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 => {
            (w as u32, h as u32)
        }
        _ => return Err(field("cam0.resolution", "must be [width, height]")),
    };
    let model = get("distortion_model")?
        .as_str()
        .ok_or_else(|| field("cam0.distortion_model", "is not text"))?;
    let coefficients = numbers(get("distortion_coeffs")?, "cam0.distortion_coeffs")?;
    Ok(Calibration {
        intrinsics: intrinsics((width, height), [fx, fy, cx, cy], "cam0.intrinsics")?,
        distortion: distortion_from(model, &coefficients, "cam0.distortion_coeffs")?,
        format: CalibrationFormat::Kalibr,
    })
}

/// The model's coefficients in OpenCV's order. Longer OpenCV vectors (the
/// rational and thin-prism terms) are taken only when those extra terms are zero.
fn distortion_from(model: &str, c: &[f64], name: &str) -> Result<Distortion, CalibrationError> {
    let extra_zero = |from: usize| c.iter().skip(from).all(|x| *x == 0.0);
    match model {
        "plumb_bob" | "radtan" | "radial-tangential" | "rational_polynomial" => match c.len() {
            0 => Ok(Distortion::None),
            4 | 5 => Ok(Distortion::RadialTangential {
                k1: c[0],
                k2: c[1],
                p1: c[2],
                p2: c[3],
                k3: c.get(4).copied().unwrap_or(0.0),
            }),
            8 | 12 | 14 if extra_zero(5) => distortion_from("plumb_bob", &c[..5], name),
            n => Err(field(
                name,
                format!(
                    "{n} coefficients: the radial-tangential model takes 4 or 5 \
                     (k1, k2, p1, p2[, k3]); rational and thin-prism terms are not supported"
                ),
            )),
        },
        "equidistant" | "fisheye" => match c {
            [k1, k2, k3, k4] => Ok(Distortion::Fisheye {
                k1: *k1,
                k2: *k2,
                k3: *k3,
                k4: *k4,
            }),
            _ => Err(field(
                name,
                format!(
                    "{} coefficients: the fisheye model takes 4 (k1..k4)",
                    c.len()
                ),
            )),
        },
        other => Err(field(
            "distortion_model",
            format!("{other:?} is not one of plumb_bob, rational_polynomial, radtan, equidistant"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layout of OpenCV's `samples/cpp/calibration.cpp` output.
    const OPENCV_YAML: &str = "%YAML:1.0
---
calibration_time: \"Tue 01 Dec 2026\"
image_width: 1280
image_height: 720
flags: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 912.5, 0., 641.2, 0., 910.8, 359.6, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.28, 0.09, 0.0012, -0.0007, -0.012 ]
avg_reprojection_error: 0.21
";

    const OPENCV_JSON: &str = r#"{
    "image_width": 1920,
    "image_height": 1080,
    "fisheye_model": 1,
    "camera_matrix": { "type_id": "opencv-matrix", "rows": 3, "cols": 3, "dt": "d",
        "data": [ 700.0, 0.0, 960.0, 0.0, 701.0, 540.0, 0.0, 0.0, 1.0 ] },
    "distortion_coefficients": { "type_id": "opencv-matrix", "rows": 4, "cols": 1, "dt": "d",
        "data": [ 0.05, -0.01, 0.002, -0.0004 ] }
}"#;

    /// `camera_calibration`'s `ost.yaml` layout.
    const ROS: &str = "image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [430.2, 0, 319.1, 0, 431.0, 241.7, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.33, 0.11, 0.0005, 0.0002, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [400, 0, 320, 0, 0, 400, 240, 0, 0, 0, 1, 0]
";

    const KALIBR: &str = "cam0:
  camera_model: pinhole
  intrinsics: [461.6, 460.3, 366.2, 249.1]
  distortion_model: radtan
  distortion_coeffs: [-0.27, 0.06, 0.0002, 0.00002]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
";

    #[test]
    fn opencv_yaml_reads_with_its_directive_and_tags() {
        let c = Calibration::parse(OPENCV_YAML).expect("reads");
        assert_eq!(c.format, CalibrationFormat::OpenCv);
        assert_eq!((c.intrinsics.width, c.intrinsics.height), (1280, 720));
        assert_eq!(
            (
                c.intrinsics.fx,
                c.intrinsics.fy,
                c.intrinsics.cx,
                c.intrinsics.cy
            ),
            (912.5, 910.8, 641.2, 359.6)
        );
        assert_eq!(
            c.distortion,
            Distortion::RadialTangential {
                k1: -0.28,
                k2: 0.09,
                p1: 0.0012,
                p2: -0.0007,
                k3: -0.012
            }
        );
    }

    #[test]
    fn opencv_json_with_the_fisheye_flag_is_a_fisheye() {
        let c = Calibration::parse(OPENCV_JSON).expect("reads");
        assert_eq!(c.intrinsics.width, 1920);
        assert_eq!(
            c.distortion,
            Distortion::Fisheye {
                k1: 0.05,
                k2: -0.01,
                k3: 0.002,
                k4: -0.0004
            }
        );
    }

    #[test]
    fn ros_camera_info_and_kalibr_read() {
        let ros = Calibration::parse(ROS).expect("ros");
        assert_eq!(ros.format, CalibrationFormat::RosCameraInfo);
        assert_eq!(ros.intrinsics.cy, 241.7);
        let kalibr = Calibration::parse(KALIBR).expect("kalibr");
        assert_eq!(kalibr.format, CalibrationFormat::Kalibr);
        assert_eq!(
            (kalibr.intrinsics.width, kalibr.intrinsics.height),
            (752, 480)
        );
        assert!(matches!(
            kalibr.distortion,
            Distortion::RadialTangential { k3, .. } if k3 == 0.0
        ));
    }

    #[test]
    fn the_frames_must_have_the_calibrated_size() {
        let c = Calibration::parse(OPENCV_YAML).expect("reads");
        assert!(c.check_size(1280, 720).is_ok());
        let message = c
            .check_size(1920, 1080)
            .expect_err("other size")
            .to_string();
        assert!(
            message.contains("1280x720") && message.contains("1920x1080"),
            "{message}"
        );
    }

    #[test]
    fn bad_files_name_what_is_wrong() {
        let cases = [
            ("[1, 2", "not YAML"),
            ("name: x\n", "no camera found"),
            (
                &OPENCV_YAML.replace("image_width: 1280\n", ""),
                "image_width: is missing",
            ),
            (
                &OPENCV_YAML.replace("cols: 5", "cols: 6"),
                "1x6 but data has 5 values",
            ),
            (
                &ROS.replace("plumb_bob", "kannala"),
                "\"kannala\" is not one of",
            ),
            (&OPENCV_YAML.replace("912.5", "-912.5"), "must be positive"),
            (
                &KALIBR.replace("[752, 480]", "[752]"),
                "cam0.resolution: must be [width, height]",
            ),
        ];
        for (text, expected) in cases {
            let message = Calibration::parse(text).expect_err(expected).to_string();
            assert!(
                message.contains(expected),
                "{expected:?} not in {message:?}"
            );
        }
    }
}
