//! Towers from a file a user names: a landmark CSV (checked as an import is)
//! or a landmark database. For readers that only need the records: the edge's
//! landmarks and the simulator's world.

use std::path::Path;

use towernav_protocol::LandmarkRecord;

use crate::csv_io::read_csv;
use crate::error::ImportError;
use crate::store::LandmarkDb;

/// `.csv` with the CSV importer's checks; anything else as a SQLite landmark database.
pub fn load_towers(path: &Path) -> Result<Vec<LandmarkRecord>, ImportError> {
    let name = path.display().to_string();
    let unreadable = |reason: String| ImportError::Read {
        file: name.clone(),
        reason,
    };
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
    {
        let file = std::fs::File::open(path).map_err(|e| unreadable(e.to_string()))?;
        read_csv(file, &name)
    } else {
        if !path.exists() {
            return Err(unreadable("it does not exist".into()));
        }
        Ok(LandmarkDb::open(path)?.list()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_or_bad_file_is_named() {
        let dir = tempfile::tempdir().expect("tempdir");
        let missing = dir.path().join("none.sqlite");
        let err = load_towers(&missing).expect_err("missing").to_string();
        assert!(err.contains("none.sqlite"), "{err}");
        let bad = dir.path().join("bad.csv");
        std::fs::write(&bad, "id,tower_type\nB1,Q\n").expect("write");
        let err = load_towers(&bad).expect_err("bad row").to_string();
        assert!(err.contains("bad.csv"), "{err}");
    }
}
