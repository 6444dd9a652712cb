//! One record builder for every import format: named text fields in, a validated
//! record or a problem naming the field out.

use std::collections::HashMap;

use towernav_protocol::LandmarkRecord;

use crate::error::RowProblem;
use crate::parsed::Parsed;
use crate::validate::validate;

/// The record's columns, as every format names them: required, optional,
/// and stamped by the database (ignored on import).
pub const REQUIRED: [&str; 6] = [
    "id",
    "tower_type",
    "lat_deg",
    "lon_deg",
    "ground_elev_m",
    "height_m",
];
pub const OPTIONAL: [&str; 6] = [
    "base_width_m",
    "line_name",
    "survey_source",
    "sigma_horizontal_m",
    "sigma_vertical_m",
    "notes",
];
pub const BOOKKEEPING: [&str; 3] = ["updated_at_unix_s", "updated_by", "revision"];

/// Builds a record from `get(field name)`, which answers trimmed, non-empty text or `None`.
pub(crate) fn build_record(
    at: &str,
    get: &dyn Fn(&str) -> Option<String>,
) -> Result<LandmarkRecord, RowProblem> {
    let id = get(REQUIRED[0]).unwrap_or_default();
    let problem = |field: &str, reason: String| RowProblem {
        at: at.into(),
        id: id.clone(),
        field: field.into(),
        reason,
    };
    let maybe_number = |field: &str| -> Result<Option<f64>, RowProblem> {
        get(field)
            .map(|v| {
                v.parse::<f64>()
                    .map_err(|_| problem(field, format!("{v:?} is not a number")))
            })
            .transpose()
    };
    let number =
        |field: &str| maybe_number(field)?.ok_or_else(|| problem(field, "is missing".into()));
    let tower_type = get(REQUIRED[1])
        .ok_or_else(|| problem("tower_type", "is missing".into()))?
        .parse()
        .map_err(|e: towernav_protocol::TowerTypeError| problem("tower_type", e.to_string()))?;
    let record = LandmarkRecord {
        base_width_m: maybe_number(OPTIONAL[0])?,
        line_name: get(OPTIONAL[1]),
        survey_source: get(OPTIONAL[2]),
        sigma_horizontal_m: maybe_number(OPTIONAL[3])?,
        sigma_vertical_m: maybe_number(OPTIONAL[4])?,
        notes: get(OPTIONAL[5]).unwrap_or_default(),
        ..LandmarkRecord::new(
            id.clone(),
            tower_type,
            number(REQUIRED[2])?,
            number(REQUIRED[3])?,
            number(REQUIRED[4])?,
            number(REQUIRED[5])?,
        )
    };
    validate(&record).map_err(|e| problem(e.field, e.reason))?;
    Ok(record)
}

/// Gathers records and problems, refusing a second record under an id already seen.
#[derive(Default)]
pub(crate) struct Collector {
    parsed: Parsed,
    /// id -> where it was first seen.
    seen: HashMap<String, String>,
}

impl Collector {
    pub(crate) fn push(&mut self, at: &str, result: Result<LandmarkRecord, RowProblem>) {
        match result {
            Ok(r) => match self.seen.get(&r.id) {
                Some(first) => self.parsed.problems.push(RowProblem {
                    at: at.into(),
                    id: r.id.clone(),
                    field: "id".into(),
                    reason: format!("duplicate of {first}"),
                }),
                None => {
                    self.seen.insert(r.id.clone(), at.into());
                    self.parsed.records.push(r);
                }
            },
            Err(p) => self.parsed.problems.push(p),
        }
    }

    pub(crate) fn finish(self) -> Parsed {
        self.parsed
    }
}
