//! `towernav-db`: survey data entry for the landmark database.
//!
//! Exit codes: 0 done; 1 refused (bad record, refused import, unknown or duplicate id);
//! 2 usage error (a bad flag, NaN or infinity included); 3 the database could not be
//! opened, read or written (another writer's lock held past the wait included).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand, ValueEnum};
use comfy_table::{Table, presets::UTF8_BORDERS_ONLY};
use towernav_landmark_db::{
    Author, DbError, Expect, Format, ImportError, ImportOptions, LandmarkDb, OsmMapping,
    export_csv, export_geojson, export_osm_xml, import_file, likely_mistakes, validate,
};
use towernav_protocol::{LandmarkChangeOp, LandmarkRecord, TowerType};

#[derive(Parser)]
#[command(about = "towernav landmark database: survey data entry", version)]
struct Cli {
    /// The database file.
    #[arg(
        long,
        env = "TOWERNAV_DB",
        default_value = "towers.sqlite",
        global = true
    )]
    db: PathBuf,
    /// Name stamped on every change.
    #[arg(long, env = "USER", default_value = "towernav-db", global = true)]
    by: String,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Create the database (or migrate an older one) and say where it is.
    Init,
    /// Import towers from a file, all or nothing unless --skip-invalid.
    Import {
        file: PathBuf,
        #[arg(long, value_enum, default_value_t = FileFormat::Csv)]
        format: FileFormat,
        /// Import the good records and list the bad ones instead of refusing the file.
        #[arg(long)]
        skip_invalid: bool,
        /// Flag towers closer than this to another, metres.
        #[arg(long, default_value_t = 30.0, value_parser = finite_non_negative)]
        min_spacing_m: f64,
        /// OSM: a tag that chooses the tower type, as key=value=TYPE (repeatable), e.g. design=donau=A.
        #[arg(long = "osm-map", value_parser = OsmMapping::parse_rule)]
        osm_map: Vec<(String, String, TowerType)>,
        /// OSM: the type of towers no --osm-map rule matches.
        #[arg(long)]
        osm_default_type: Option<TowerType>,
        /// OSM: ground elevation (WGS84 ellipsoid, m) of towers without an `ele` tag.
        #[arg(long, value_parser = finite)]
        osm_ground_elev_m: Option<f64>,
    },
    /// Export every tower; `-` writes to standard output.
    Export {
        file: PathBuf,
        #[arg(long, value_enum, default_value_t = FileFormat::Csv)]
        format: FileFormat,
    },
    /// All towers as a table.
    List,
    /// Every field of one tower.
    Show { id: String },
    /// Add a new tower (refused if the id exists).
    Add(RecordArgs),
    /// Change fields of an existing tower.
    Edit(EditArgs),
    /// Remove a tower.
    Remove { id: String },
    /// The change log, oldest first.
    History {
        /// Only changes after this revision.
        #[arg(long, default_value_t = 0)]
        since: u64,
    },
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum FileFormat {
    Csv,
    Geojson,
    /// OpenStreetMap XML (`power=tower` nodes; exports carry `towernav:type`).
    Osm,
    /// Overpass API JSON (import only).
    Overpass,
}

#[derive(Args)]
struct RecordArgs {
    id: String,
    #[arg(long = "type")]
    tower_type: TowerType,
    #[arg(long, value_parser = finite)]
    lat: f64,
    #[arg(long, value_parser = finite)]
    lon: f64,
    /// Foot elevation above the WGS84 ellipsoid, metres.
    #[arg(long, value_parser = finite)]
    elev: f64,
    /// Foot to top, metres.
    #[arg(long, value_parser = finite_non_negative)]
    height: f64,
    #[command(flatten)]
    optional: OptionalArgs,
}

#[derive(Args)]
struct EditArgs {
    id: String,
    #[arg(long = "type")]
    tower_type: Option<TowerType>,
    #[arg(long, value_parser = finite)]
    lat: Option<f64>,
    #[arg(long, value_parser = finite)]
    lon: Option<f64>,
    #[arg(long, value_parser = finite)]
    elev: Option<f64>,
    #[arg(long, value_parser = finite_non_negative)]
    height: Option<f64>,
    #[command(flatten)]
    optional: OptionalArgs,
}

#[derive(Args)]
struct OptionalArgs {
    #[arg(long, value_parser = finite_non_negative)]
    base_width: Option<f64>,
    #[arg(long)]
    line: Option<String>,
    #[arg(long)]
    source: Option<String>,
    /// One-sigma horizontal survey accuracy, metres.
    #[arg(long, value_parser = finite_non_negative)]
    sigma_h: Option<f64>,
    /// One-sigma vertical survey accuracy, metres.
    #[arg(long, value_parser = finite_non_negative)]
    sigma_v: Option<f64>,
    #[arg(long)]
    notes: Option<String>,
}

impl OptionalArgs {
    fn apply(self, r: &mut LandmarkRecord) {
        r.base_width_m = self.base_width.or(r.base_width_m);
        r.line_name = self.line.or(r.line_name.take());
        r.survey_source = self.source.or(r.survey_source.take());
        r.sigma_horizontal_m = self.sigma_h.or(r.sigma_horizontal_m);
        r.sigma_vertical_m = self.sigma_v.or(r.sigma_vertical_m);
        if let Some(n) = self.notes {
            r.notes = n;
        }
    }
}

/// An error and the exit code it maps to.
struct Failure(u8, anyhow::Error);

impl<E: Into<anyhow::Error>> From<E> for Failure {
    fn from(e: E) -> Self {
        let e = e.into();
        // The database's own failures (locked, unreadable) are 3 whichever
        // command met them; a bad record or id is a refusal.
        let db = e
            .downcast_ref::<DbError>()
            .or_else(|| match e.downcast_ref::<ImportError>() {
                Some(ImportError::Db(d)) => Some(d),
                _ => None,
            });
        let code = match db {
            Some(d) if !d.is_refusal() => 3,
            _ => 1,
        };
        Failure(code, e)
    }
}

/// A finite number, for every numeric flag: NaN or infinity is refused with its flag's name.
fn finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(format!("{v} is not a finite number")),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number of zero or more.
fn finite_non_negative(text: &str) -> Result<f64, String> {
    match finite(text)? {
        v if v >= 0.0 => Ok(v),
        v => Err(format!("{v} is negative")),
    }
}

fn refused(message: String) -> Failure {
    Failure(1, anyhow::anyhow!(message))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure(code, e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(code)
        }
    }
}

fn run(cli: Cli) -> Result<(), Failure> {
    let mut db = LandmarkDb::open(&cli.db).map_err(|e| Failure(3, e.into()))?;
    let author = Author::now(&cli.by);
    match cli.command {
        Command::Init => {
            println!(
                "{}: schema v{}, revision {}, {} towers",
                cli.db.display(),
                db.schema_version()?,
                db.revision()?,
                db.list()?.len()
            );
        }
        Command::Import {
            file,
            format,
            skip_invalid,
            min_spacing_m,
            osm_map,
            osm_default_type,
            osm_ground_elev_m,
        } => {
            // The operator's rules first, then towernav's own type tag (its OSM exports).
            let osm = OsmMapping {
                rules: osm_map
                    .into_iter()
                    .chain(OsmMapping::towernav().rules)
                    .collect(),
                default: osm_default_type,
                default_ground_elev_m: osm_ground_elev_m,
            };
            let options = ImportOptions {
                osm,
                skip_invalid,
                min_spacing_m,
                ..ImportOptions::default()
            };
            import(&mut db, &file, format, &options, &author)?;
        }
        Command::Export { file, format } => export(&db, &file, format)?,
        Command::List => list(&db)?,
        Command::Show { id } => {
            let r = db
                .get(&id)?
                .ok_or_else(|| refused(format!("no tower {id:?} in {}", cli.db.display())))?;
            println!("{}", serde_json_pretty(&r));
        }
        Command::Add(args) => add(&mut db, args, &author)?,
        Command::Edit(args) => edit(&mut db, args, &author)?,
        Command::Remove { id } => match db.remove(&id, &author)? {
            Some(rev) => println!("removed {id} at revision {rev}"),
            None => return Err(refused(format!("no tower {id:?} to remove"))),
        },
        Command::History { since } => history(&db, since)?,
    }
    Ok(())
}

fn add(db: &mut LandmarkDb, args: RecordArgs, author: &Author) -> Result<(), Failure> {
    let mut r = LandmarkRecord::new(
        args.id,
        args.tower_type,
        args.lat,
        args.lon,
        args.elev,
        args.height,
    );
    args.optional.apply(&mut r);
    validate(&r)?;
    // Refused inside the write if the id exists, also when a
    // concurrent writer added it a moment ago.
    let revision = db.upsert_expecting(&r, Expect::Absent, author)?;
    println!("added {} at revision {revision}", r.id);
    warn_likely_mistakes(db, &r)?;
    Ok(())
}

fn edit(db: &mut LandmarkDb, args: EditArgs, author: &Author) -> Result<(), Failure> {
    let id = args.id.clone();
    // Read, change and write under one write lock: a concurrent edit
    // of another field is kept, not overwritten.
    let edited = db.edit(&id, author, |r| {
        r.tower_type = args.tower_type.unwrap_or(r.tower_type);
        r.lat_deg = args.lat.unwrap_or(r.lat_deg);
        r.lon_deg = args.lon.unwrap_or(r.lon_deg);
        r.ground_elev_m = args.elev.unwrap_or(r.ground_elev_m);
        r.height_m = args.height.unwrap_or(r.height_m);
        args.optional.apply(r);
        Ok::<(), std::convert::Infallible>(())
    })?;
    let Some(Ok((r, revision))) = edited else {
        return Err(refused(format!("no tower {id:?}; use `add`")));
    };
    println!("edited {} at revision {revision}", r.id);
    warn_likely_mistakes(db, &r)?;
    Ok(())
}

fn history(db: &LandmarkDb, since: u64) -> Result<(), Failure> {
    for c in db.changes_since(since)? {
        match c.change {
            LandmarkChangeOp::Upsert { record } => println!(
                "r{:<6} {}  upsert {:<10} by {}",
                c.revision,
                utc(record.updated_at_unix_s),
                record.id,
                record.updated_by
            ),
            LandmarkChangeOp::Remove { id } => {
                println!("r{:<6} {:20}  remove {id}", c.revision, "")
            }
        }
    }
    Ok(())
}

impl From<FileFormat> for Format {
    fn from(f: FileFormat) -> Self {
        match f {
            FileFormat::Csv => Format::Csv,
            FileFormat::Geojson => Format::GeoJson,
            FileFormat::Osm => Format::OsmXml,
            FileFormat::Overpass => Format::OverpassJson,
        }
    }
}

/// Replacement of another id, spacing and type-height checks for one record (the import's rules).
fn warn_likely_mistakes(db: &LandmarkDb, r: &LandmarkRecord) -> Result<(), Failure> {
    let existing: Vec<LandmarkRecord> = db.list()?.into_iter().filter(|e| e.id != r.id).collect();
    for w in likely_mistakes(
        std::slice::from_ref(r),
        &existing,
        &ImportOptions::default(),
    ) {
        eprintln!("check {w}");
    }
    Ok(())
}

/// Examples of each kind of check printed in full; the rest counted.
const CHECK_EXAMPLES: usize = 5;

/// Checks summarized: a count per kind and its first few examples, so a
/// file of towers at one spot does not print a line per pair.
fn print_checks(warnings: &[towernav_landmark_db::Warning]) {
    for (kind, of_kind) in towernav_landmark_db::import::checks_by_kind(warnings) {
        for w in of_kind.iter().take(CHECK_EXAMPLES) {
            eprintln!("check {w}");
        }
        if of_kind.len() > CHECK_EXAMPLES {
            eprintln!(
                "check ... and {} more: {kind} ({} in all)",
                of_kind.len() - CHECK_EXAMPLES,
                of_kind.len()
            );
        }
    }
}

fn utc(unix_s: i64) -> String {
    let t = std::time::UNIX_EPOCH + std::time::Duration::from_secs(unix_s.max(0) as u64);
    humantime::format_rfc3339_seconds(t).to_string()
}

fn serde_json_pretty(r: &LandmarkRecord) -> String {
    serde_json::to_string_pretty(r).unwrap_or_else(|e| format!("{r:?} ({e})"))
}

/// `import`: one transaction, then the skipped rows and the checks.
fn import(
    db: &mut LandmarkDb,
    file: &std::path::Path,
    format: FileFormat,
    options: &ImportOptions,
    author: &Author,
) -> Result<(), Failure> {
    let report = match import_file(db, file, format.into(), options, author) {
        Ok(report) => report,
        Err(e @ ImportError::Rejected { .. }) => {
            return Err(refused(format!(
                "{e}\n(nothing was imported; fix the rows or use --skip-invalid)"
            )));
        }
        Err(e) => return Err(e.into()),
    };
    for p in &report.skipped {
        eprintln!("skipped {p}");
    }
    print_checks(&report.warnings);
    println!(
        "imported {} towers from {} (revision {}); {} skipped, {} to check",
        report.imported,
        file.display(),
        report.revision,
        report.skipped.len(),
        report.warnings.len()
    );
    Ok(())
}

/// `export`: the whole set, to a file or standard output.
fn export(db: &LandmarkDb, file: &std::path::Path, format: FileFormat) -> Result<(), Failure> {
    let records = db.list()?;
    let text = match format {
        FileFormat::Csv => {
            let mut out = Vec::new();
            export_csv(&records, &mut out)?;
            out
        }
        FileFormat::Geojson => export_geojson(&records)?.into_bytes(),
        FileFormat::Osm => export_osm_xml(&records).into_bytes(),
        FileFormat::Overpass => {
            return Err(refused(
                "Overpass JSON is import only; export to csv, geojson or osm".into(),
            ));
        }
    };
    if file.as_os_str() == "-" {
        use std::io::Write;
        std::io::stdout().lock().write_all(&text)?;
    } else {
        std::fs::write(file, text).with_context(|| format!("writing {}", file.display()))?;
        eprintln!("exported {} towers to {}", records.len(), file.display());
    }
    Ok(())
}

/// `list`: one row per tower.
fn list(db: &LandmarkDb) -> Result<(), Failure> {
    let mut table = Table::new();
    table.load_style(UTF8_BORDERS_ONLY).set_header([
        "id", "type", "lat", "lon", "elev m", "height m", "line", "rev",
    ]);
    for r in db.list()? {
        table.add_row([
            r.id,
            r.tower_type.to_string(),
            format!("{:.6}", r.lat_deg),
            format!("{:.6}", r.lon_deg),
            format!("{:.1}", r.ground_elev_m),
            format!("{:.1}", r.height_m),
            r.line_name.unwrap_or_default(),
            r.revision.to_string(),
        ]);
    }
    println!("{table}");
    Ok(())
}
