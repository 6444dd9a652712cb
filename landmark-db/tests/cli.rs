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

/// A database in `dir` holding `SURVEY`.
fn import_survey(dir: &Path) {
    std::fs::write(dir.join("s.csv"), SURVEY).expect("write");
    let out = db(dir, &["import", dir.join("s.csv").to_str().expect("utf8")]);
    assert!(out.status.success(), "{}", text(&out));
}

/// `out` exited with `code` and says `needle`.
fn refused(out: &Output, code: i32, needle: &str) {
    assert_eq!(out.status.code(), Some(code), "{}", text(out));
    assert!(text(out).contains(needle), "{}", text(out));
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
    refused(&out, 1, "line 4");
    refused(&out, 1, "height_m");
    refused(&out, 1, "nothing was imported");

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
    refused(&out, 1, "exists");

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

    refused(&db(d, &["edit", "A2", "--height", "900"]), 1, "height_m");
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
}

/// GeoJSON out of one database and into another loses nothing.
#[test]
fn geojson_out_of_one_database_and_into_another_loses_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    import_survey(d);
    assert!(db(d, &["edit", "A1", "--sigma-h", "0.05"]).status.success());
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
    assert_eq!(a.len(), 3, "header and two towers: {a:?}");
    assert_eq!(a, b);
}

#[test]
fn numeric_flags_refuse_nan_infinity_and_negatives_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("s.csv"), SURVEY).expect("write");
    let file = d.join("s.csv");
    let file = file.to_str().expect("utf8");
    for (args, flag) in [
        (
            vec!["import", "--min-spacing-m", "NaN", file],
            "--min-spacing-m",
        ),
        (
            vec!["import", "--min-spacing-m=-5", file],
            "--min-spacing-m",
        ),
        (
            vec!["import", "--min-spacing-m", "inf", file],
            "--min-spacing-m",
        ),
        (
            vec![
                "add", "Z1", "--type", "A", "--lat", "NaN", "--lon", "114", "--elev", "20",
                "--height", "30",
            ],
            "--lat",
        ),
        (vec!["edit", "A1", "--height", "inf"], "--height"),
        (vec!["edit", "A1", "--base-width=-1"], "--base-width"),
    ] {
        let out = db(d, &args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", text(&out));
        assert!(text(&out).contains(flag), "{args:?}: {}", text(&out));
    }
}

#[test]
fn towers_at_one_spot_are_summarized_not_listed_pair_by_pair() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let mut csv = String::from("id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m\n");
    for i in 0..1500 {
        csv += &format!("T{i},B,30.5,114.3,20,38\n");
    }
    std::fs::write(d.join("heap.csv"), csv).expect("write");
    let out = db(d, &["import", d.join("heap.csv").to_str().expect("utf8")]);
    assert!(out.status.success(), "{}", text(&out));
    let lines = text(&out).lines().count();
    assert!(lines < 20, "{lines} lines:\n{}", text(&out));
    assert!(
        text(&out).contains("1495 more") && text(&out).contains("imported 1500 towers"),
        "{}",
        text(&out)
    );
}

#[test]
fn a_writer_locked_out_past_the_wait_exits_3_from_every_command() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    import_survey(d);
    let holder = rusqlite::Connection::open(d.join("towers.sqlite")).expect("raw connection");
    holder.execute_batch("BEGIN IMMEDIATE").expect("lock");
    let csv = d.join("s.csv");
    for args in [
        vec![
            "add", "Z1", "--type", "A", "--lat", "30.6", "--lon", "114.3", "--elev", "20",
            "--height", "30",
        ],
        vec!["edit", "A1", "--notes", "x"],
        vec!["remove", "B1"],
        vec!["import", csv.to_str().expect("utf8")],
    ] {
        let out = db(d, &args);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {}", text(&out));
        assert!(
            text(&out).contains("locked by another writer"),
            "{args:?}: {}",
            text(&out)
        );
    }
    holder.execute_batch("ROLLBACK").expect("unlock");
}

#[test]
fn every_export_imports_back_into_a_new_database() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let csv = "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m,base_width_m,notes\n\
               A1,A,30.5,114.3,20,0.0004,0.0002,\"two\nlines\"\n";
    std::fs::write(d.join("tiny.csv"), csv).expect("write");
    assert!(
        db(d, &["import", d.join("tiny.csv").to_str().expect("utf8")])
            .status
            .success()
    );
    for (format, name) in [("csv", "e.csv"), ("geojson", "e.geojson"), ("osm", "e.osm")] {
        let path = d.join(name);
        let path = path.to_str().expect("utf8");
        let out = db(d, &["export", "--format", format, path]);
        assert!(out.status.success(), "{}", text(&out));
        let fresh = d.join(format!("fresh-{format}"));
        std::fs::create_dir_all(&fresh).expect("mkdir");
        let out = db(&fresh, &["import", "--format", format, path]);
        assert!(out.status.success(), "{format}: {}", text(&out));
        let show = text(&db(&fresh, &["show", "A1"]));
        assert!(show.contains("0.0004"), "{format}: {show}");
        if format != "osm" {
            assert!(show.contains("two\\nlines"), "{format}: {show}");
        }
    }
}
