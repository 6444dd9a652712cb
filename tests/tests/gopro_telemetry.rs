//! Our GPMF reader against GoPro's own parser (its C library through the
//! `py-gpmf-parser` binding), on GoPro's sample videos: every sample of every
//! stream the chain uses, the same values in the same order.

use std::path::PathBuf;
use std::process::Command;

use towernav_flightlog::gpmf::Telemetry;

/// For each stream key: GoPro's parser's rows and sample times.
const DUMP: &str = r#"
import json, sys
import py_gpmf_parser as p
x = p.GoProTelemetryExtractor(sys.argv[1]); x.open_source()
out = {}
for key in sys.argv[2:]:
    data, times = x.extract_data(key)
    out[key] = {"rows": [list(map(float, r)) for r in data], "times": list(map(float, times))}
x.close()
print(json.dumps(out))
"#;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/gopro")
        .join(name)
}

/// The workspace root, where the daemon finds its models.
fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn cross_check(name: &str, keys: &[&str]) {
    let Some(pythonpath) = towernav_tests::python_module("py_gpmf_parser") else {
        eprintln!("skipped: py-gpmf-parser is not installed (cargo xtask test installs it)");
        return;
    };
    let path = fixture(name);
    let out = Command::new("python3")
        .args(["-c", DUMP])
        .arg(&path)
        .args(keys)
        .env("PYTHONPATH", pythonpath)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let theirs: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let file = std::fs::File::open(&path).expect("fixture");
    let ours = Telemetry::read(&mut std::io::BufReader::new(file))
        .expect("reads")
        .expect("has GPMF");
    for key in keys {
        let stream = ours
            .stream(key)
            .unwrap_or_else(|| panic!("{name}: no {key}"));
        let rows = theirs[key]["rows"].as_array().expect("rows");
        let times = theirs[key]["times"].as_array().expect("times");
        assert!(!rows.is_empty(), "{name}: GoPro's parser finds no {key}");
        assert_eq!(
            stream.samples.len(),
            rows.len(),
            "{name} {key}: sample count"
        );
        for (i, (ours, theirs)) in stream.samples.iter().zip(rows).enumerate() {
            let theirs: Vec<f64> = theirs
                .as_array()
                .expect("row")
                .iter()
                .map(|v| v.as_f64().expect("number"))
                .collect();
            assert_eq!(ours.values.len(), theirs.len(), "{name} {key}[{i}]: fields");
            for (a, b) in ours.values.iter().zip(&theirs) {
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                    "{name} {key}[{i}]: ours {:?}, GoPro's {theirs:?}",
                    ours.values
                );
            }
            // GoPro's extractor shifts each stream by its own start offset,
            // fitted from the sample counts; ours shares each payload's span.
            let t = times[i].as_f64().expect("time");
            assert!(
                (ours.time_s - t).abs() < 0.2,
                "{name} {key}[{i}]: at {:.3} s, GoPro's at {t:.3} s",
                ours.time_s
            );
        }
    }
}

#[test]
fn karma_streams_agree_with_gopro_s_parser() {
    cross_check("karma.mp4", &["ACCL", "GYRO", "ATTD", "GLPI", "GPRI"]);
}

#[test]
fn max_streams_agree_with_gopro_s_parser() {
    cross_check(
        "max-heromode.mp4",
        &["GPS5", "GPSF", "GPSP", "GRAV", "CORI", "ACCL", "GYRO"],
    );
}

/// A 256x144 pinhole: the fixtures' re-encoded frames.
const CAMERA_YAML: &str = "%YAML:1.0
---
image_width: 256
image_height: 144
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 180., 0., 128., 0., 180., 72., 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
";

/// One tower a few hundred metres from where the MAX was carried.
const TOWERS_CSV: &str = "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m,base_width_m,line_name,survey_source,sigma_horizontal_m,sigma_vertical_m,notes,updated_at_unix_s,updated_by,revision
T1,A,33.1290,-117.3273,10,30,6,line 1,test,0,0,,0,,0
";

#[test]
fn a_gopro_video_alone_replays_on_its_own_telemetry() {
    let dir = tempfile::tempdir().expect("tempdir");
    let camera = dir.path().join("camera.yaml");
    let towers = dir.path().join("towers.csv");
    std::fs::write(&camera, CAMERA_YAML).expect("write");
    std::fs::write(&towers, TOWERS_CSV).expect("write");
    let out = dir.path().join("out");
    let stdout = towernav_tests::programs::run_ok(
        Command::new(towernav_tests::programs::sibling_binary("towernav-edge"))
            .current_dir(workspace())
            .arg("replay")
            .arg("--video")
            .arg(fixture("max-heromode.mp4"))
            .arg("--camera")
            .arg(&camera)
            .arg("--landmarks")
            .arg(&towers)
            .arg("--out")
            .arg(&out),
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("replay.json")).expect("replay.json"),
    )
    .expect("json");
    assert_eq!(summary["frames"], 315, "{stdout}");
    // The start is the GPS fix at the first frame: the video's own telemetry.
    let start = summary["start"].as_str().expect("start");
    assert!(start.contains("log's GNSS"), "{start}");

    // A video without telemetry and no --log is told what to give.
    let plain = dir.path().join("plain.mp4");
    let status = Command::new("ffmpeg")
        .args(["-loglevel", "error", "-y", "-i"])
        .arg(fixture("max-heromode.mp4"))
        .args(["-map", "0:v", "-c", "copy"])
        .arg(&plain)
        .status()
        .expect("ffmpeg");
    assert!(status.success());
    let (ok, text) = towernav_tests::programs::output(
        Command::new(towernav_tests::programs::sibling_binary("towernav-edge"))
            .current_dir(workspace())
            .arg("replay")
            .arg("--video")
            .arg(&plain)
            .arg("--camera")
            .arg(&camera)
            .arg("--landmarks")
            .arg(&towers)
            .arg("--out")
            .arg(dir.path().join("plain-out")),
    );
    assert!(!ok, "{text}");
    assert!(text.contains("--log"), "says what is missing: {text}");
}
