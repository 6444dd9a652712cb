//! `towernav-edge map-towers` on a rendered survey corner: a tower the
//! landmark file has moved is confirmed with its offset, a tower it lacks is
//! proposed as new, and what it writes is what the database imports.

use std::path::Path;
use std::process::Command;

use towernav_tests::programs::{run_ok, sibling_binary};

/// A small lens with barrel distortion: renders and detects quickly.
const CAMERA_YAML: &str = "%YAML:1.0
---
image_width: 640
image_height: 360
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 457.0, 0., 320.0, 0., 457.0, 180.0, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.28, 0.08, 0.001, -0.002, -0.01 ]
";

/// Metres east and north between two records.
fn offset(
    a: &towernav_protocol::LandmarkRecord,
    b: &towernav_protocol::LandmarkRecord,
) -> (f64, f64) {
    let north = (a.lat_deg - b.lat_deg).to_radians() * 6_378_137.0;
    let east = (a.lon_deg - b.lon_deg).to_radians() * 6_378_137.0 * b.lat_deg.to_radians().cos();
    (east, north)
}

fn workspace() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

#[test]
fn a_survey_corner_confirms_a_moved_tower_and_proposes_a_missing_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let camera = dir.path().join("camera.yaml");
    std::fs::write(&camera, CAMERA_YAML).expect("write");
    let flight = dir.path().join("flight");
    run_ok(
        Command::new(sibling_binary("towernav-sim"))
            .arg("flight")
            .arg("--plan")
            .arg(workspace().join("tests/fixtures/map-pass.toml"))
            .arg("--calibration")
            .arg(&camera)
            .args(["--video", "--gnss-sigma-m", "0.5", "--seed", "5", "--out"])
            .arg(&flight),
    );
    let truth = towernav_landmark_db::load_towers(&flight.join("towers.csv")).expect("towers");
    let a1 = truth.iter().find(|t| t.id == "A1").expect("A1");
    // The landmark file: A1 moved 7 m east, C1 left out.
    let mut file: Vec<_> = truth.iter().filter(|t| t.id != "C1").cloned().collect();
    for t in &mut file {
        if t.id == "A1" {
            t.lon_deg += (7.0 / (6_378_137.0 * t.lat_deg.to_radians().cos())).to_degrees();
        }
    }
    let landmarks = dir.path().join("landmarks.csv");
    towernav_landmark_db::export_csv(&file, std::fs::File::create(&landmarks).expect("create"))
        .expect("write");

    let out = dir.path().join("out");
    let printed = run_ok(
        Command::new(sibling_binary("towernav-edge"))
            .current_dir(workspace())
            .arg("map-towers")
            .arg("--video")
            .arg(flight.join("flight.mp4"))
            .arg("--log")
            .arg(flight.join("flight.tlog"))
            .args(["--time-offset", "12.5", "--gnss-sigma-m", "0.5", "--camera"])
            .arg(flight.join("camera.yaml"))
            .arg("--landmarks")
            .arg(&landmarks)
            .arg("--out")
            .arg(&out),
    );

    // What it writes, the database reads back.
    let csv = std::fs::File::open(out.join("towers-mapped.csv")).expect("csv");
    let proposals = towernav_landmark_db::read_csv(csv, "towers-mapped.csv").expect("importable");
    let geojson: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("towers-mapped.geojson")).expect("geojson"),
    )
    .expect("json");
    let features = geojson["features"].as_array().expect("features");
    let status = |id: &str| {
        features.iter().find(|f| f["id"] == id).map(|f| {
            f["properties"]["status"]
                .as_str()
                .unwrap_or_default()
                .to_owned()
        })
    };

    // A1 is confirmed where it stands, not where the file has it.
    assert_eq!(status("A1").as_deref(), Some("confirmed"), "{printed}");
    let measured = proposals
        .iter()
        .find(|p| p.id == "A1")
        .expect("A1 proposed");
    let (east, north) = offset(measured, a1);
    assert!(
        east.hypot(north) < 2.5,
        "A1 {east:.1} m east, {north:.1} m north of the truth"
    );
    assert!(
        (measured.height_m - a1.height_m).abs() < 2.0,
        "{measured:?}"
    );
    // C1, missing from the file, comes back as a new tower where it stands.
    let c1 = truth.iter().find(|t| t.id == "C1").expect("C1");
    let new_at_c1 = proposals
        .iter()
        .filter(|p| p.id.starts_with("NEW-"))
        .any(|p| {
            let (e, n) = offset(p, c1);
            e.hypot(n) < 2.5
        });
    assert!(new_at_c1, "C1 proposed as new: {proposals:#?}");
    // Each proposal says how sure it is: the truth lies inside three sigmas.
    for p in &proposals {
        let nearest = truth
            .iter()
            .map(|t| {
                let (e, n) = offset(p, t);
                e.hypot(n)
            })
            .fold(f64::INFINITY, f64::min);
        let sigma = p.sigma_horizontal_m.expect("a sigma");
        assert!(
            nearest <= 3.0 * sigma.max(1.0),
            "{} is {nearest:.1} m from the nearest tower with a sigma of {sigma:.1} m",
            p.id
        );
    }
    // Every feature has a status and a place.
    for f in features {
        let s = f["properties"]["status"].as_str().expect("status");
        assert!(
            ["confirmed", "new", "missed", "uncertain"].contains(&s),
            "{s}"
        );
        assert_eq!(
            f["geometry"]["coordinates"].as_array().map(Vec::len),
            Some(3)
        );
    }
}
