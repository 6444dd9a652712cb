//! Import from any supported format: parse to records and problems, flag likely
//! mistakes, then write all or nothing (or, if asked, only the good records).

use std::path::Path;

use towernav_geometry::Geodetic;
use towernav_protocol::LandmarkRecord;

use crate::csv_io::parse_csv;
use crate::error::{ImportError, RowProblem};
use crate::formats::{OsmMapping, parse_geojson, parse_osm_xml, parse_overpass_json};
pub use crate::parsed::Parsed;
use crate::store::{Author, LandmarkDb};
use towernav_geometry::GeoIndex;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Csv,
    GeoJson,
    /// OpenStreetMap XML (`power=tower` nodes).
    OsmXml,
    /// Overpass API JSON (`power=tower` nodes).
    OverpassJson,
}

/// How to treat likely mistakes and bad records.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions {
    /// Import the good records and report the bad ones, instead of refusing the file.
    pub skip_invalid: bool,
    /// Towers closer than this to another are flagged.
    pub min_spacing_m: f64,
    /// Towers farther than this from every other are flagged: a line's
    /// towers stand 0.2-0.5 km apart, and a dropped digit puts one hundreds
    /// of kilometres off.
    pub max_isolation_m: f64,
    /// Plausible tower height range, metres.
    pub height_range_m: (f64, f64),
    /// How OSM tags become tower types and ground elevations.
    pub osm: OsmMapping,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            skip_invalid: false,
            min_spacing_m: 30.0,
            max_isolation_m: 20_000.0,
            height_range_m: (15.0, 80.0),
            osm: OsmMapping::default(),
        }
    }
}

/// A record that imported but looks wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    pub id: String,
    pub kind: CheckKind,
    pub message: String,
}

/// What a check is about, for summaries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CheckKind {
    Replaces,
    Height,
    Spacing,
    Far,
}

impl std::fmt::Display for CheckKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Replaces => "towers replacing one stored under their id",
            Self::Height => "heights outside their type's range",
            Self::Spacing => "towers closer than the minimum spacing to another",
            Self::Far => "towers far from every other (is the position right?)",
        })
    }
}

/// `warnings` grouped by kind, in a fixed order, each group in input order.
pub fn checks_by_kind(warnings: &[Warning]) -> Vec<(CheckKind, Vec<&Warning>)> {
    let mut groups: std::collections::BTreeMap<CheckKind, Vec<&Warning>> = Default::default();
    for w in warnings {
        groups.entry(w.kind).or_default().push(w);
    }
    groups.into_iter().collect()
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.id, self.message)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct ImportReport {
    pub imported: usize,
    /// Bad records left out (only with `skip_invalid`).
    pub skipped: Vec<RowProblem>,
    pub warnings: Vec<Warning>,
    /// Database revision after the import.
    pub revision: u64,
}

pub fn parse_file(path: &Path, format: Format, osm: &OsmMapping) -> Result<Parsed, ImportError> {
    let file = path.display().to_string();
    let read_err = |e: std::io::Error| ImportError::Read {
        file: file.clone(),
        reason: e.to_string(),
    };
    if format == Format::Csv {
        return parse_csv(std::fs::File::open(path).map_err(read_err)?, &file);
    }
    let text = std::fs::read_to_string(path).map_err(read_err)?;
    match format {
        Format::Csv | Format::GeoJson => parse_geojson(&text, &file),
        Format::OsmXml => parse_osm_xml(&text, &file, osm),
        Format::OverpassJson => parse_overpass_json(&text, &file, osm),
    }
}

pub fn import_file(
    db: &mut LandmarkDb,
    path: &Path,
    format: Format,
    options: &ImportOptions,
    author: &Author,
) -> Result<ImportReport, ImportError> {
    let file = path.display().to_string();
    let parsed = parse_file(path, format, &options.osm)?;
    import_parsed(db, parsed, &file, options, author)
}

/// Imports a CSV file all-or-nothing: one bad row refuses the whole file and leaves the database as it was.
pub fn import_csv(db: &mut LandmarkDb, path: &Path, author: &Author) -> Result<usize, ImportError> {
    let report = import_file(db, path, Format::Csv, &ImportOptions::default(), author)?;
    Ok(report.imported)
}

pub fn import_parsed(
    db: &mut LandmarkDb,
    parsed: Parsed,
    file: &str,
    options: &ImportOptions,
    author: &Author,
) -> Result<ImportReport, ImportError> {
    let (records, skipped) = if options.skip_invalid {
        (parsed.records, parsed.problems)
    } else {
        (parsed.all_or_nothing(file)?, Vec::new())
    };
    let existing = db.list()?;
    let warnings = likely_mistakes(&records, &existing, options);
    let revision = if records.is_empty() {
        db.revision()?
    } else {
        db.upsert_all(&records, author)?
    };
    Ok(ImportReport {
        imported: records.len(),
        skipped,
        warnings,
        revision,
    })
}

/// Replacements of existing towers, towers closer than the set spacing, heights out of range for the type.
pub fn likely_mistakes(
    incoming: &[LandmarkRecord],
    existing: &[LandmarkRecord],
    options: &ImportOptions,
) -> Vec<Warning> {
    let mut warnings = Vec::new();
    let warn = |id: &str, kind: CheckKind, message: String| Warning {
        id: id.into(),
        kind,
        message,
    };
    let existing_ids: std::collections::HashSet<&str> =
        existing.iter().map(|r| r.id.as_str()).collect();
    // The set after import: incoming records win over existing ones of the same id.
    let incoming_ids: std::collections::HashSet<&str> =
        incoming.iter().map(|r| r.id.as_str()).collect();
    let after: Vec<LandmarkRecord> = existing
        .iter()
        .filter(|r| !incoming_ids.contains(r.id.as_str()))
        .chain(incoming)
        .cloned()
        .collect();
    let feet: Vec<_> = after.iter().map(LandmarkRecord::foot).collect();
    let index = GeoIndex::from_points(&feet);
    for r in incoming {
        if existing_ids.contains(r.id.as_str()) {
            warnings.push(warn(
                &r.id,
                CheckKind::Replaces,
                "replaces the tower already stored under this id".into(),
            ));
        }
        let (lo, hi) = options.height_range_m;
        if !(lo..=hi).contains(&r.height_m) {
            warnings.push(warn(
                &r.id,
                CheckKind::Height,
                format!(
                    "height {} m is not between {lo} and {hi} m (type {})",
                    r.height_m, r.tower_type
                ),
            ));
        }
        let foot = Geodetic {
            lat_deg: r.lat_deg,
            lon_deg: r.lon_deg,
            height_m: r.ground_elev_m,
        };
        // The nearest other tower only: one line per tower, and a logarithmic
        // search even when a file puts every tower at one spot.
        let nearest = index.nearest(&foot).find(|(i, _)| after[*i].id != r.id);
        if let Some((i, d)) = nearest {
            if d < options.min_spacing_m {
                warnings.push(warn(
                    &r.id,
                    CheckKind::Spacing,
                    format!(
                        "stands {d:.1} m from {} (closer than {} m)",
                        after[i].id, options.min_spacing_m
                    ),
                ));
            } else if d > options.max_isolation_m {
                warnings.push(warn(
                    &r.id,
                    CheckKind::Far,
                    format!(
                        "stands {:.0} km from the nearest tower ({}); is the position right?",
                        d / 1000.0,
                        after[i].id
                    ),
                ));
            }
        }
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::tower_at as tower;

    #[test]
    fn flags_a_tower_far_from_every_other() {
        let existing = [tower("B1", 30.5, 35.0), tower("B2", 30.503, 35.0)];
        // A latitude with a wrong digit: 26 degrees north, about 2900 km (as the chord).
        let incoming = [tower("B3", 30.506, 35.0), tower("B4", 56.509, 35.0)];
        let w = likely_mistakes(&incoming, &existing, &ImportOptions::default());
        assert_eq!(w.len(), 1, "{w:?}");
        assert_eq!((w[0].id.as_str(), w[0].kind), ("B4", CheckKind::Far));
        assert!(
            w[0].message.contains("2864 km") && w[0].message.contains("B3"),
            "{}",
            w[0].message
        );
    }

    #[test]
    fn flags_near_twins_replacements_and_odd_heights() {
        let existing = [tower("B1", 30.5, 35.0)];
        // 0.0001 deg of latitude is about 11 m.
        let incoming = [
            tower("B2", 30.5001, 35.0),
            tower("B1", 30.49, 35.0),
            tower("B9", 30.6, 120.0),
        ];
        let w = likely_mistakes(&incoming, &existing, &ImportOptions::default());
        let text: Vec<String> = w.iter().map(ToString::to_string).collect();
        assert!(
            text.iter().any(|t| t.starts_with("B1: replaces")),
            "{text:?}"
        );
        assert!(
            text.iter().any(|t| t.starts_with("B9: height 120")),
            "{text:?}"
        );
        // B2 is 11 m from the *old* B1 position, but B1 moves away in this import.
        assert!(
            !text.iter().any(|t| t.starts_with("B2: stands")),
            "{text:?}"
        );
        let twins = [tower("B2", 30.5001, 35.0), tower("B3", 30.5002, 35.0)];
        let w = likely_mistakes(&twins, &[], &ImportOptions::default());
        assert_eq!(w.len(), 2, "{w:?}");
    }

    #[test]
    fn skip_invalid_imports_the_good_rows_and_reports_the_bad() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        let parsed = Parsed {
            records: vec![tower("B1", 30.5, 35.0)],
            problems: vec![RowProblem {
                at: "line 3".into(),
                id: "B2".into(),
                field: "height_m".into(),
                reason: "-1".into(),
            }],
        };
        let author = Author {
            by: "t".into(),
            at_unix_s: 0,
        };
        let refused = import_parsed(
            &mut db,
            parsed.clone(),
            "f.csv",
            &ImportOptions::default(),
            &author,
        );
        assert!(matches!(refused, Err(ImportError::Rejected { .. })));
        assert!(db.list().expect("list").is_empty());
        let options = ImportOptions {
            skip_invalid: true,
            ..ImportOptions::default()
        };
        let report = import_parsed(&mut db, parsed, "f.csv", &options, &author).expect("import");
        assert_eq!(
            (report.imported, report.skipped.len(), report.revision),
            (1, 1, 1)
        );
    }
}
