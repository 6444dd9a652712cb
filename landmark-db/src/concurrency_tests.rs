//! Two writers on one file, as the ground station and `towernav-db` are:
//! threads with their own connections, racing on purpose.

use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};

use crate::fixtures::tower;
use crate::store::{Author, Expect, LandmarkDb};

fn author(by: &str) -> Author {
    Author {
        by: by.into(),
        at_unix_s: 1,
    }
}

#[test]
fn concurrent_edits_of_one_tower_both_land() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t.sqlite");
    let mut db = LandmarkDb::open(&path).expect("open");
    db.upsert(&tower("B1"), &author("setup")).expect("add");
    let start = Arc::new(Barrier::new(2));
    let writers: Vec<_> = (0..2)
        .map(|w| {
            let (path, start) = (path.clone(), start.clone());
            std::thread::spawn(move || {
                let mut db = LandmarkDb::open(&path).expect("open");
                start.wait();
                for k in 1..=20 {
                    db.edit("B1", &author("w"), |r| {
                        if w == 0 {
                            r.height_m = 30.0 + f64::from(k);
                        } else {
                            r.notes = format!("note {k}");
                        }
                        Ok::<(), ()>(())
                    })
                    .expect("no database error")
                    .expect("the tower exists")
                    .expect("the edit applies");
                }
            })
        })
        .collect();
    for w in writers {
        w.join().expect("writer");
    }
    let r = db.get("B1").expect("read").expect("stored");
    assert_eq!(r.height_m, 50.0, "the height writer's last edit");
    assert_eq!(r.notes, "note 20", "the notes writer's last edit");
    assert_eq!(db.revision().expect("revision"), 41);
}

#[test]
fn of_concurrent_adds_of_one_id_exactly_one_succeeds() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t.sqlite");
    LandmarkDb::open(&path).expect("create");
    let start = Arc::new(Barrier::new(4));
    let adders: Vec<_> = (0..4)
        .map(|w| {
            let (path, start) = (path.clone(), start.clone());
            std::thread::spawn(move || {
                let mut db = LandmarkDb::open(&path).expect("open");
                let mut r = tower("B7");
                r.notes = format!("writer {w}");
                start.wait();
                db.upsert_expecting(&r, Expect::Absent, &author("w"))
            })
        })
        .collect();
    let results: Vec<_> = adders
        .into_iter()
        .map(|a| a.join().expect("adder"))
        .collect();
    let won: Vec<_> = results.iter().filter(|r| r.is_ok()).collect();
    assert_eq!(won.len(), 1, "{results:?}");
    for r in results.iter().filter_map(|r| r.as_ref().err()) {
        assert!(
            matches!(r, crate::DbError::Exists { id, .. } if id == "B7"),
            "{r}"
        );
    }
    let db = LandmarkDb::open(&path).expect("open");
    assert_eq!(
        db.changes_since(0).expect("log").len(),
        1,
        "one add, no replacement"
    );
}

#[test]
fn a_stale_edit_is_refused_not_applied() {
    let mut db = LandmarkDb::open_in_memory().expect("open");
    let rev = db.upsert(&tower("B1"), &author("a")).expect("add");
    let mut mine = db.get("B1").expect("read").expect("stored");
    db.edit("B1", &author("b"), |r| {
        r.notes = "theirs".into();
        Ok::<(), ()>(())
    })
    .expect("edit");
    mine.height_m = 40.0;
    let err = db
        .upsert_expecting(&mine, Expect::Revision(rev), &author("a"))
        .expect_err("stale");
    assert!(
        err.to_string().contains("changed since it was read"),
        "{err}"
    );
    assert_eq!(db.get("B1").expect("read").expect("stored").notes, "theirs");
}

#[test]
fn a_writer_waits_for_anothers_lock_instead_of_failing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t.sqlite");
    LandmarkDb::open(&path).expect("create");
    let holder = rusqlite::Connection::open(&path).expect("raw connection");
    holder.execute_batch("BEGIN IMMEDIATE").expect("lock");
    let release = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(1500));
        holder.execute_batch("COMMIT").expect("unlock");
    });
    let started = Instant::now();
    let mut db = LandmarkDb::open(&path).expect("open while locked");
    db.upsert_expecting(&tower("B2"), Expect::Absent, &author("cli"))
        .expect("waits, then writes");
    db.edit("B2", &author("cli"), |r| {
        r.notes = "x".into();
        Ok::<(), ()>(())
    })
    .expect("edit");
    let waited = started.elapsed();
    release.join().expect("holder");
    assert!(
        waited >= Duration::from_millis(1000),
        "waited only {waited:?}"
    );
}

#[test]
fn a_lock_held_past_the_wait_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("t.sqlite");
    let mut db = LandmarkDb::open(&path).expect("create");
    let holder = rusqlite::Connection::open(&path).expect("raw connection");
    holder.execute_batch("BEGIN IMMEDIATE").expect("lock");
    let err = db.upsert(&tower("B3"), &author("cli")).expect_err("locked");
    assert!(matches!(err, crate::DbError::Busy { .. }), "{err}");
    assert!(
        err.to_string().contains("locked by another writer"),
        "{err}"
    );
    holder.execute_batch("ROLLBACK").expect("unlock");
}

#[test]
fn writers_starting_together_on_a_new_file_all_open_it() {
    for round in 0..5 {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join(format!("new-{round}.sqlite"));
        let start = Arc::new(Barrier::new(4));
        let openers: Vec<_> = (0..4)
            .map(|w| {
                let (path, start) = (path.clone(), start.clone());
                std::thread::spawn(move || {
                    start.wait();
                    let mut db = LandmarkDb::open(&path)?;
                    db.upsert(&tower(&format!("B{w}")), &author("w"))
                })
            })
            .collect();
        for o in openers {
            o.join()
                .expect("opener")
                .expect("opens, migrates and writes");
        }
        let db = LandmarkDb::open(&path).expect("open");
        assert_eq!(
            db.schema_version().expect("version"),
            crate::store::MIGRATIONS.len() as i64
        );
        assert_eq!(db.list().expect("list").len(), 4);
    }
}
