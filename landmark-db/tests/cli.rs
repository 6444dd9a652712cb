//! `towernav-db` as a surveyor uses it: messages and exit codes.

use std::path::Path;
use std::process::{Command, Output};

fn db(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_towernav-db"))
        .arg("--db")
        .arg(dir.join("towers.sqlite"))
        .args(["--by", "crew-3"])
        .args(args)
        .output()
        .expect("runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

const SURVEY: &str = "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m,line_name\n\
                      A1,A,30.5000,114.3000,20,32,North\n\
                      B1,B,30.5010,114.3000,20,38,North\n";

#[test]
fn a_surveyor_session() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    assert!(db(d, &["init"]).status.success());

    std::fs::write(
        d.join("bad.csv"),
        format!("{SURVEY}C1,C,30.502,114.3,20,-45,\n"),
    )
    .expect("write");
    let out = db(d, &["import", d.join("bad.csv").to_str().expect("utf8")]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(
        text(&out).contains("line 4") && text(&out).contains("height_m"),
        "{}",
        text(&out)
    );
    assert!(text(&out).contains("nothing was imported"));

    let out = db(
        d,
        &[
            "import",
            "--skip-invalid",
            d.join("bad.csv").to_str().expect("utf8"),
        ],
    );
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("imported 2 towers") && text(&out).contains("1 skipped"),
        "{}",
        text(&out)
    );

    let out = db(
        d,
        &[
            "add", "A1", "--type", "A", "--lat", "30.5", "--lon", "114.3", "--elev", "20",
            "--height", "32",
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out).contains("exists"), "{}", text(&out));

    // 0.0001 deg north of A1 is about 11 m: added, but flagged.
    let out = db(
        d,
        &[
            "add", "A2", "--type", "A", "--lat", "30.5001", "--lon", "114.3", "--elev", "20",
            "--height", "32",
        ],
    );
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("check A2: stands"), "{}", text(&out));

    let out = db(d, &["edit", "A2", "--height", "900"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out).contains("height_m"), "{}", text(&out));
    assert!(
        db(d, &["edit", "A2", "--lat", "30.51", "--sigma-h", "0.05"])
            .status
            .success()
    );

    let out = db(d, &["remove", "ZZ"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(db(d, &["remove", "B1"]).status.success());

    let out = db(d, &["history"]);
    let history = text(&out);
    assert_eq!(history.lines().count(), 5, "{history}");
    assert!(
        history.contains("remove B1") && history.contains("by crew-3"),
        "{history}"
    );

    let out = db(d, &["list"]);
    assert!(
        text(&out).contains("North") && !text(&out).contains("B1"),
        "{}",
        text(&out)
    );

    let out = db(d, &["show", "A2"]);
    assert!(
        text(&out).contains("\"sigma_horizontal_m\": 0.05"),
        "{}",
        text(&out)
    );

    assert_eq!(
        db(d, &["add", "Q1", "--type", "Q"]).status.code(),
        Some(2),
        "usage errors exit 2"
    );

    // GeoJSON out of one database and into another loses nothing.
    let geojson = d.join("towers.geojson");
    let out = db(
        d,
        &[
            "export",
            "--format",
            "geojson",
            geojson.to_str().expect("utf8"),
        ],
    );
    assert!(out.status.success(), "{}", text(&out));
    let other = tempfile::tempdir().expect("tempdir");
    let out = db(
        other.path(),
        &[
            "import",
            "--format",
            "geojson",
            geojson.to_str().expect("utf8"),
        ],
    );
    assert!(out.status.success(), "{}", text(&out));
    let survey = |dir: &Path| {
        let out = db(dir, &["export", "-"]);
        // Drop the bookkeeping columns, which each database stamps itself.
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(|l| l.rsplitn(4, ',').last().unwrap_or_default().to_owned())
            .collect::<Vec<_>>()
    };
    let (a, b) = (survey(d), survey(other.path()));
    assert_eq!(a.len(), 3, "{a:?}");
    assert_eq!(a, b);
}
