//! A landmark CSV with one bad row is refused whole: the row and field are named and
//! the database is left exactly as it was.

use towernav_landmark_db::{Author, ImportError, LandmarkDb, export_csv, import_csv};
use towernav_sim::World;

#[test]
fn one_bad_row_refuses_the_file_and_changes_nothing() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let db_path = dir.path().join("towers.sqlite");
    let mut db = LandmarkDb::open(&db_path)?;
    let world = World::paper_field();
    let crew = Author {
        by: "survey crew".into(),
        at_unix_s: 1_790_000_000,
    };
    db.upsert(&world.landmarks()[0], &crew)?;
    let before = (db.list()?, db.revision()?);

    let mut csv = Vec::new();
    export_csv(&world.landmarks(), &mut csv)?;
    let mut text = String::from_utf8(csv)?;
    // Spoil the height of the seventh tower (line 8 counting the header).
    let lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let mut cells: Vec<String> = lines[7].split(',').map(str::to_owned).collect();
    cells[5] = "-12".into();
    let spoiled_id = cells[0].clone();
    let mut spoiled = lines.clone();
    spoiled[7] = cells.join(",");
    text = spoiled.join("\n");
    let file = dir.path().join("survey.csv");
    std::fs::write(&file, text)?;

    let err = import_csv(&mut db, &file, &crew).expect_err("a bad row must refuse the import");
    let ImportError::Rejected { problems, .. } = &err else {
        panic!("unexpected error {err}")
    };
    assert_eq!(problems.len(), 1);
    assert_eq!(problems[0].at, "line 8");
    assert_eq!(problems[0].field, "height_m");
    assert_eq!(problems[0].id, spoiled_id);
    assert!(
        err.to_string().contains("line 8") && err.to_string().contains("height_m"),
        "{err}"
    );

    drop(db);
    let db = LandmarkDb::open(&db_path)?;
    assert_eq!((db.list()?, db.revision()?), before);
    assert_eq!(
        db.changes_since(0)?.len(),
        1,
        "the refused import left no change"
    );
    Ok(())
}
