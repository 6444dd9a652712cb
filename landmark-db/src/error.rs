use crate::csv_io::RowProblem;
use crate::validate::ValidationError;

#[derive(Debug, thiserror::Error)]
pub enum DbError {
    #[error("landmark database {path}: {source}")]
    Sqlite {
        path: String,
        #[source]
        source: rusqlite::Error,
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
