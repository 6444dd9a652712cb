use std::fmt;

use crate::validate::ValidationError;

/// One rejected row: where it is, which record, which field, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct RowProblem {
    /// Where in the file: "line 4" (CSV, header is line 1), "feature 3" (GeoJSON), "node 123" (OSM).
    pub at: String,
    pub id: String,
    pub field: String,
    pub reason: String,
}

impl fmt::Display for RowProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} (id {:?}): {}: {}",
            self.at, self.id, self.field, self.reason
        )
    }
}

#[derive(Debug, thiserror::Error)]
pub enum DbError {
    #[error("landmark database {path}: {source}")]
    Sqlite {
        path: String,
        #[source]
        source: rusqlite::Error,
    },
    /// Another connection held the write lock past the busy timeout.
    #[error(
        "landmark database {path} is locked by another writer (the ground station or another \
         towernav-db) and stayed locked past the {}-second wait; nothing was written, try again",
        crate::busy::BUSY_TIMEOUT.as_secs()
    )]
    Busy { path: String },
    /// `add` of an id that is stored already (perhaps by a concurrent writer).
    #[error("landmark database {path}: tower {id:?} exists; use edit")]
    Exists { path: String, id: String },
    /// The tower changed since it was read: the write would undo someone's edit.
    #[error(
        "landmark database {path}: tower {id:?} changed since it was read (revision {expected}, now {}); reload and edit again",
        found.map_or_else(|| "removed".to_string(), |f| f.to_string())
    )]
    Conflict {
        path: String,
        id: String,
        expected: u64,
        found: Option<u64>,
    },
    #[error(transparent)]
    Invalid(#[from] ValidationError),
    #[error("landmark database {path} has schema version {found}; this build knows up to {known}")]
    FutureSchema {
        path: String,
        found: i64,
        known: i64,
    },
    #[error("landmark database {path}: record {id:?} has a bad {field}: {reason}")]
    Corrupt {
        path: String,
        id: String,
        field: &'static str,
        reason: String,
    },
}

impl DbError {
    /// SQLite's error on `path`, a lock held past the busy timeout told apart.
    pub fn from_sqlite(path: &str, source: rusqlite::Error) -> Self {
        match source.sqlite_error_code() {
            Some(rusqlite::ErrorCode::DatabaseBusy | rusqlite::ErrorCode::DatabaseLocked) => {
                Self::Busy { path: path.into() }
            }
            _ => Self::Sqlite {
                path: path.into(),
                source,
            },
        }
    }

    /// The input, not the database, is at fault: a bad record, or an id that
    /// exists or changed.
    pub fn is_refusal(&self) -> bool {
        matches!(
            self,
            Self::Invalid(_) | Self::Exists { .. } | Self::Conflict { .. }
        )
    }
}

/// Why an import was refused; the database is left as it was.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("cannot read {file}: {reason}")]
    Read { file: String, reason: String },
    #[error("{file}: {} row(s) rejected, nothing imported:\n{}", problems.len(), list(problems))]
    Rejected {
        file: String,
        problems: Vec<RowProblem>,
    },
    #[error(transparent)]
    Db(#[from] DbError),
}

fn list(problems: &[RowProblem]) -> String {
    problems
        .iter()
        .map(|p| format!("  {p}"))
        .collect::<Vec<_>>()
        .join("\n")
}
