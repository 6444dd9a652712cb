//! CSV exchange; the columns and units are in the README. Required:
//! `id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m`; optional (empty cell: unknown):
//! `base_width_m,line_name,survey_source,sigma_horizontal_m,sigma_vertical_m,notes`.
//! Export adds `updated_at_unix_s,updated_by,revision`, which import ignores:
//! the database stamps its own.

use std::io::{Read, Write};

use towernav_protocol::LandmarkRecord;

use crate::error::{ImportError, RowProblem};
use crate::fields::{BOOKKEEPING, Collector, OPTIONAL, REQUIRED, build_record};
use crate::parsed::Parsed;

/// Parses and validates every row; records and problems both come back.
/// Fails whole only when the file cannot be read as CSV at all.
pub fn parse_csv(input: impl Read, file: &str) -> Result<Parsed, ImportError> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(input);
    let headers = reader
        .headers()
        .map_err(|e| ImportError::Read {
            file: file.into(),
            reason: e.to_string(),
        })?
        .clone();
    let column = |name: &str| headers.iter().position(|h| h == name);
    if let Some(missing) = REQUIRED.iter().find(|name| column(name).is_none()) {
        return Err(ImportError::Read {
            file: file.into(),
            reason: format!(
                "missing column {missing:?} (header must have {})",
                REQUIRED.join(",")
            ),
        });
    }
    let mut out = Collector::default();
    for row in reader.records() {
        match row {
            Ok(row) => {
                let at = format!("line {}", row.position().map_or(0, |p| p.line()));
                let get = |name: &str| {
                    column(name)
                        .and_then(|i| row.get(i))
                        .filter(|v| !v.is_empty())
                        .map(str::to_owned)
                };
                out.push(&at, build_record(&at, &get));
            }
            Err(e) => out.push(
                "",
                Err(RowProblem {
                    at: format!("line {}", e.position().map_or(0, |p| p.line())),
                    id: String::new(),
                    field: "row".into(),
                    reason: e.to_string(),
                }),
            ),
        }
    }
    Ok(out.finish())
}

/// All rows or an error listing every bad one.
pub fn read_csv(input: impl Read, file: &str) -> Result<Vec<LandmarkRecord>, ImportError> {
    parse_csv(input, file)?.all_or_nothing(file)
}

pub fn export_csv(records: &[LandmarkRecord], output: impl Write) -> Result<(), csv::Error> {
    let mut writer = csv::Writer::from_writer(output);
    writer.write_record(REQUIRED.iter().chain(&OPTIONAL).chain(&BOOKKEEPING))?;
    // Shortest text that reads back as the same number: an export imports back unchanged.
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
    for r in records {
        writer.write_record([
            r.id.clone(),
            r.tower_type.to_string(),
            r.lat_deg.to_string(),
            r.lon_deg.to_string(),
            r.ground_elev_m.to_string(),
            r.height_m.to_string(),
            opt(r.base_width_m),
            r.line_name.clone().unwrap_or_default(),
            r.survey_source.clone().unwrap_or_default(),
            opt(r.sigma_horizontal_m),
            opt(r.sigma_vertical_m),
            r.notes.clone(),
            r.updated_at_unix_s.to_string(),
            r.updated_by.clone(),
            r.revision.to_string(),
        ])?;
    }
    writer.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use towernav_protocol::TowerType;

    const GOOD: &str = "id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m,notes\n\
                        A1,A,30.5,114.3,20,35,north line\n\
                        B1,B,30.501,114.301,20,40,\n";

    #[test]
    fn a_good_file_imports_every_row() {
        let records = read_csv(GOOD.as_bytes(), "good.csv").expect("import");
        assert_eq!(records.len(), 2);
        assert_eq!(records[0].notes, "north line");
        assert_eq!(records[1].tower_type, TowerType::B);
    }

    #[test]
    fn every_bad_row_is_reported_with_line_and_field() {
        let bad = format!(
            "{GOOD}C1,C,30.5,114.3,20,tall,\nD1,Q;R,30.5,114.3,20,40,\nA1,A,30.5,114.3,20,35,\n"
        );
        let Err(ImportError::Rejected { problems, .. }) = read_csv(bad.as_bytes(), "bad.csv")
        else {
            panic!("must be rejected");
        };
        let summary: Vec<_> = problems
            .iter()
            .map(|p| (p.at.as_str(), p.field.as_str()))
            .collect();
        assert_eq!(
            summary,
            [
                ("line 4", "height_m"),
                ("line 5", "tower_type"),
                ("line 6", "id")
            ]
        );
    }

    #[test]
    fn a_missing_column_is_named() {
        let err =
            read_csv("id,tower_type,lat_deg\nA1,A,30\n".as_bytes(), "x.csv").expect_err("refuse");
        assert!(err.to_string().contains("lon_deg"), "{err}");
    }

    proptest! {
        #[test]
        fn export_then_import_loses_nothing(
            rows in proptest::collection::vec((0usize..4, -89.0f64..89.0, -179.0f64..179.0, -100.0f64..3000.0, 1.0f64..150.0, "[a-z ,\"]{0,12}"), 1..20)
        ) {
            let records: Vec<LandmarkRecord> = rows.into_iter().enumerate().map(|(i, (t, lat, lon, elev, h, notes))| LandmarkRecord {
                notes: notes.trim().to_string(),
                base_width_m: (i % 2 == 0).then_some(h / 5.0),
                line_name: (i % 3 == 0).then(|| format!("line, \"{i}\"")),
                sigma_vertical_m: (i % 2 == 1).then_some(0.25),
                ..LandmarkRecord::new(format!("T{i}"), TowerType::ALL[t], lat, lon, elev, h)
            }).collect();
            let mut out = Vec::new();
            export_csv(&records, &mut out).expect("export");
            let back = read_csv(out.as_slice(), "round.csv").expect("import");
            prop_assert_eq!(back.len(), records.len());
            for (a, b) in records.iter().zip(&back) {
                prop_assert_eq!(&a.id, &b.id);
                prop_assert_eq!(a.tower_type, b.tower_type);
                prop_assert_eq!(&a.notes, &b.notes);
                prop_assert_eq!(&a.line_name, &b.line_name);
                prop_assert_eq!(a.sigma_vertical_m, b.sigma_vertical_m);
                prop_assert_eq!(a.base_width_m.is_some(), b.base_width_m.is_some());
                prop_assert!((a.lat_deg - b.lat_deg).abs() < 1e-8 && (a.lon_deg - b.lon_deg).abs() < 1e-8);
                prop_assert!((a.height_m - b.height_m).abs() < 1e-3 && (a.ground_elev_m - b.ground_elev_m).abs() < 1e-3);
            }
        }
    }
}
