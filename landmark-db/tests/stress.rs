//! Writer processes racing on one database file with a mix of `add`, `edit`,
//! `remove` and `import` for a bounded time: none fails for the lock, and
//! every change one of them reported is in the history at the revision it said.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use towernav_landmark_db::LandmarkDb;
use towernav_protocol::LandmarkChangeOp;

const WRITERS: usize = 4;
const RUN_FOR: Duration = Duration::from_secs(6);

/// What a writer said it did: revision -> (id, removed).
type Reported = Vec<(u64, String, bool)>;

fn writer(db: &Path, csv: &Path, w: usize) -> Reported {
    let mut reported = Vec::new();
    let started = Instant::now();
    let mut k = 0usize;
    while started.elapsed() < RUN_FOR {
        k += 1;
        let id = format!("T{}", (k * 7 + w) % 12);
        let height = format!("{}", 30 + k % 20);
        let args: Vec<String> = match k % 4 {
            0 => [
                "add", &id, "--type", "B", "--lat", "30.5", "--lon", "114.3", "--elev", "20",
                "--height", &height,
            ]
            .map(String::from)
            .to_vec(),
            1 => ["edit", &id, "--notes", &format!("w{w} k{k}")]
                .map(String::from)
                .to_vec(),
            2 => ["remove", &id].map(String::from).to_vec(),
            _ => vec!["import".into(), csv.display().to_string()],
        };
        let out = Command::new(env!("CARGO_BIN_EXE_towernav-db"))
            .arg("--db")
            .arg(db)
            .args(["--by", &format!("writer{w}")])
            .args(&args)
            .output()
            .expect("runs");
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        match out.status.code() {
            Some(0) => {}
            // Refused: the id exists, or is gone; a lost race, not a failure.
            Some(1) => continue,
            code => panic!("writer {w}: {args:?} exited {code:?}: {err}"),
        }
        let revision = |line: &str| -> u64 {
            let tail = line.rsplit("revision ").next().expect("a revision");
            tail.trim_end_matches(|c: char| !c.is_ascii_digit())
                .split(|c: char| !c.is_ascii_digit())
                .next()
                .and_then(|n| n.parse().ok())
                .expect("revision number")
        };
        let line = text.lines().next().expect("a line");
        match args[0].as_str() {
            "add" | "edit" => reported.push((revision(line), id, false)),
            "remove" => reported.push((revision(line), id, true)),
            // An import's last revision is its last row.
            _ => reported.push((revision(line), "T11".into(), false)),
        }
    }
    reported
}

#[test]
fn every_reported_change_of_racing_writers_is_in_the_history() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("shared.sqlite");
    let csv = dir.path().join("line.csv");
    let mut rows = String::from("id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m\n");
    for i in 0..12 {
        rows += &format!("T{i},B,30.5{i:02},114.3,20,38\n");
    }
    std::fs::write(&csv, rows).expect("write");
    let writers: Vec<_> = (0..WRITERS)
        .map(|w| {
            let (db, csv) = (db.clone(), csv.clone());
            std::thread::spawn(move || writer(&db, &csv, w))
        })
        .collect();
    let reported: Vec<_> = writers
        .into_iter()
        .flat_map(|w| w.join().expect("writer"))
        .collect();
    assert!(
        reported.len() > 20,
        "only {} changes in {RUN_FOR:?}",
        reported.len()
    );
    let history: HashMap<u64, (String, bool)> = LandmarkDb::open(&db)
        .expect("open")
        .changes_since(0)
        .expect("history")
        .into_iter()
        .map(|c| match c.change {
            LandmarkChangeOp::Upsert { record } => (c.revision, (record.id, false)),
            LandmarkChangeOp::Remove { id } => (c.revision, (id, true)),
        })
        .collect();
    for (revision, id, removed) in &reported {
        assert_eq!(
            history.get(revision),
            Some(&(id.clone(), *removed)),
            "revision {revision}"
        );
    }
    let mut revisions: Vec<u64> = reported.iter().map(|r| r.0).collect();
    revisions.sort_unstable();
    revisions.dedup();
    assert_eq!(
        revisions.len(),
        reported.len(),
        "no revision reported twice"
    );
}
