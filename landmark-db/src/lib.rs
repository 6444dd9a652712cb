//! The surveyed tower database: validation, SQLite storage and CSV exchange.
//!
//! Records are [`towernav_protocol::LandmarkRecord`], the same type that
//! crosses the wire, so a tower means one thing everywhere.

pub mod busy;
pub mod csv_io;
pub mod error;
pub mod fields;
pub mod formats;
pub mod import;
pub mod load;
pub mod parsed;
pub mod store;
pub mod validate;

/// Geodesy has one home, `towernav-geometry`; re-exported for database users.
pub use towernav_geometry::geodesy;

pub use busy::BUSY_TIMEOUT;
pub use csv_io::{export_csv, parse_csv, read_csv};
pub use error::{DbError, ImportError, RowProblem};
pub use formats::{OSM_TYPE_TAG, OsmMapping, export_geojson, export_osm_xml};
pub use import::{
    CheckKind, Format, ImportOptions, ImportReport, Parsed, Warning, checks_by_kind, import_csv,
    import_file, import_parsed, likely_mistakes, parse_file,
};
pub use load::load_towers;
pub use store::{Author, Expect, HistoryEntry, LandmarkDb};
pub use validate::{ValidationError, validate};

#[cfg(test)]
mod concurrency_tests;
#[cfg(test)]
mod fixtures;
#[cfg(test)]
mod round_trip_tests;
