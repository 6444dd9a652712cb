//! Where the edge gets its towers: a landmark CSV or a landmark database file.

use std::path::Path;

use towernav_landmark_db::{LandmarkDb, read_csv};
use towernav_protocol::LandmarkRecord;

use super::ShellError;

/// Loads `.csv` with the CSV importer's checks, anything else as a SQLite landmark database.
pub fn load_landmarks(path: &Path) -> Result<Vec<LandmarkRecord>, ShellError> {
    let name = path.display().to_string();
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
    {
        let file = std::fs::File::open(path)
            .map_err(|e| ShellError::Landmarks(format!("cannot open {name}: {e}")))?;
        read_csv(file, &name).map_err(|e| ShellError::Landmarks(e.to_string()))
    } else {
        if !path.exists() {
            return Err(ShellError::Landmarks(format!("{name} does not exist")));
        }
        let db = LandmarkDb::open(path).map_err(|e| ShellError::Landmarks(e.to_string()))?;
        db.list().map_err(|e| ShellError::Landmarks(e.to_string()))
    }
}
