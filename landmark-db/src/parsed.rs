//! What a parser of any format hands on: the good records and each bad row.
//! Its own home, below both the parsers and the import that picks one.

use towernav_protocol::LandmarkRecord;

use crate::error::{ImportError, RowProblem};

/// Records that parsed and validated, and every row that did not.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Parsed {
    pub records: Vec<LandmarkRecord>,
    pub problems: Vec<RowProblem>,
}

impl Parsed {
    pub fn all_or_nothing(self, file: &str) -> Result<Vec<LandmarkRecord>, ImportError> {
        if self.problems.is_empty() {
            Ok(self.records)
        } else {
            Err(ImportError::Rejected {
                file: file.into(),
                problems: self.problems,
            })
        }
    }
}
