//! A writer killed with SIGKILL in the middle of a stream of edits loses no
//! committed edit and leaves a readable database.
//!
//! The test re-runs its own binary as the writer (selected by an environment
//! variable), which prints each revision only after its transaction committed.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use towernav_landmark_db::{Author, LandmarkDb};
use towernav_protocol::{LandmarkRecord, TowerType};

const WRITER_ENV: &str = "TOWERNAV_CRASH_WRITER_DB";

/// The writer: edits forever, one transaction each, printing the committed revision.
fn writer(path: &Path) -> ! {
    let mut db = LandmarkDb::open(path).expect("open");
    let author = Author {
        by: "writer".into(),
        at_unix_s: 0,
    };
    for i in 0u64.. {
        let record = LandmarkRecord::new(
            format!("T{}", i % 500),
            TowerType::ALL[(i % 4) as usize],
            30.5,
            114.3,
            20.0,
            20.0 + (i % 100) as f64,
        );
        let revision = db.upsert(&record, &author).expect("upsert");
        println!("{revision} {} {}", record.id, record.height_m);
    }
    unreachable!()
}

#[test]
fn sigkill_mid_stream_loses_no_committed_edit() {
    if let Some(path) = std::env::var_os(WRITER_ENV) {
        writer(Path::new(&path));
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("towers.sqlite");
    LandmarkDb::open(&path).expect("create");

    let mut child = Command::new(std::env::current_exe().expect("test binary"))
        .args([
            "--exact",
            "crash::sigkill_mid_stream_loses_no_committed_edit",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(WRITER_ENV, &path)
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn writer");
    let stdout = child.stdout.take().expect("piped");
    let mut committed = Vec::new();
    for line in BufReader::new(stdout).lines() {
        let line = line.expect("line");
        let mut parts = line.split_whitespace();
        let (Some(rev), Some(id), Some(height)) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        let (Ok(rev), Ok(height)) = (rev.parse::<u64>(), height.parse::<f64>()) else {
            continue;
        };
        committed.push((rev, id.to_string(), height));
        if committed.len() == 300 {
            // SIGKILL: no destructor, no flush, no chance to finish the transaction in flight.
            child.kill().expect("kill");
            break;
        }
    }
    child.wait().expect("reaped");
    assert_eq!(
        committed.len(),
        300,
        "the writer must have committed 300 edits before the kill"
    );

    let db = LandmarkDb::open(&path).expect("the database opens after the crash");
    db.check_integrity()
        .expect("SQLite finds the file consistent");
    let last = committed.last().expect("some").0;
    assert!(
        db.revision().expect("revision") >= last,
        "revision went back"
    );
    let log = db.changes_since(0).expect("the change log reads");
    for (rev, id, height) in &committed {
        let change = log
            .iter()
            .find(|c| c.revision == *rev)
            .unwrap_or_else(|| panic!("revision {rev} lost"));
        match &change.change {
            towernav_protocol::LandmarkChangeOp::Upsert { record } => {
                assert_eq!((&record.id, record.height_m), (id, *height));
            }
            other => panic!("revision {rev} is {other:?}"),
        }
    }
    assert!(!db.list().expect("the towers read").is_empty());
}
