//! SQLite storage: WAL, synchronous=FULL, one transaction per write, versioned
//! schema, a revision per change and a change log that replicas replay.

use std::path::Path;

use rusqlite::{Connection, OptionalExtension, Transaction, TransactionBehavior, params};
use towernav_protocol::{LandmarkChange, LandmarkChangeOp, LandmarkRecord, TowerType};

use crate::busy::BUSY_TIMEOUT;
use crate::error::DbError;
use crate::validate::validate;

/// Each entry moves the schema from version `i` to `i + 1`; never edit a shipped one.
pub(crate) const MIGRATIONS: &[&str] = &[
    // 0 -> 1: landmarks and the database-wide revision counter.
    "CREATE TABLE landmarks (
        id            TEXT PRIMARY KEY NOT NULL,
        tower_type    TEXT NOT NULL,
        lat_deg       REAL NOT NULL,
        lon_deg       REAL NOT NULL,
        ground_elev_m REAL NOT NULL,
        height_m      REAL NOT NULL,
        notes         TEXT NOT NULL DEFAULT '',
        revision      INTEGER NOT NULL
    );
    CREATE TABLE meta (key TEXT PRIMARY KEY NOT NULL, value INTEGER NOT NULL);
    INSERT INTO meta (key, value) VALUES ('revision', 0);",
    // 1 -> 2: optional survey fields, who and when, and the change log.
    "ALTER TABLE landmarks ADD COLUMN base_width_m REAL;
    ALTER TABLE landmarks ADD COLUMN line_name TEXT;
    ALTER TABLE landmarks ADD COLUMN survey_source TEXT;
    ALTER TABLE landmarks ADD COLUMN sigma_horizontal_m REAL;
    ALTER TABLE landmarks ADD COLUMN sigma_vertical_m REAL;
    ALTER TABLE landmarks ADD COLUMN updated_at_unix_s INTEGER NOT NULL DEFAULT 0;
    ALTER TABLE landmarks ADD COLUMN updated_by TEXT NOT NULL DEFAULT '';
    CREATE TABLE changes (
        revision          INTEGER PRIMARY KEY NOT NULL,
        id                TEXT NOT NULL,
        op                TEXT NOT NULL CHECK (op IN ('upsert', 'remove')),
        record            TEXT,
        updated_at_unix_s INTEGER NOT NULL,
        updated_by        TEXT NOT NULL
    );
    -- v1 rows enter the log as upserts at their own revision, so that
    -- 'changes since 0' rebuilds the current set.
    INSERT INTO changes (revision, id, op, record, updated_at_unix_s, updated_by)
        SELECT revision, id, 'upsert',
               json_object('id', id, 'tower_type', tower_type, 'lat_deg', lat_deg,
                           'lon_deg', lon_deg, 'ground_elev_m', ground_elev_m,
                           'height_m', height_m, 'notes', notes, 'revision', revision),
               0, 'migration v2'
        FROM landmarks;",
];

/// One change of the log and its author.
#[derive(Debug, Clone, PartialEq)]
pub struct HistoryEntry {
    pub change: LandmarkChange,
    pub author: Author,
}

/// Who writes, and when: stamped on every record and change.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Author {
    pub by: String,
    pub at_unix_s: i64,
}

impl Author {
    /// `by` at the current wall-clock time.
    pub fn now(by: impl Into<String>) -> Self {
        let at_unix_s = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        Self {
            by: by.into(),
            at_unix_s,
        }
    }
}

pub struct LandmarkDb {
    conn: Connection,
    path: String,
}

/// What `edit` did: nothing (no such tower), the edit's own refusal, or the
/// tower as stored with its revision.
pub type Edited<E> = Option<Result<(LandmarkRecord, u64), E>>;

/// What a write expects of the stored tower it replaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    /// Whatever is there (imports replace).
    Any,
    /// No tower by this id yet (`add`).
    Absent,
    /// The tower as it was at this revision (an edit made from what was read).
    Revision(u64),
}

const COLUMNS: &str = "id, tower_type, lat_deg, lon_deg, ground_elev_m, height_m, base_width_m, line_name, \
     survey_source, sigma_horizontal_m, sigma_vertical_m, notes, updated_at_unix_s, updated_by, revision";

impl LandmarkDb {
    pub fn open(path: &Path) -> Result<Self, DbError> {
        let name = path.display().to_string();
        let conn = Connection::open(path).map_err(|source| DbError::Sqlite {
            path: name.clone(),
            source,
        })?;
        Self::init(conn, name)
    }

    pub fn open_in_memory() -> Result<Self, DbError> {
        let conn = Connection::open_in_memory().map_err(|source| DbError::Sqlite {
            path: ":memory:".into(),
            source,
        })?;
        Self::init(conn, ":memory:".into())
    }

    fn init(mut conn: Connection, path: String) -> Result<Self, DbError> {
        let sql = |source| DbError::from_sqlite(&path, source);
        // A second writer (the CLI beside the ground station) waits rather
        // than fails; set first, so that switching a new file to WAL waits too.
        conn.busy_timeout(BUSY_TIMEOUT).map_err(sql)?;
        // Switching a new file to WAL can be refused at once while another
        // connection is creating it (SQLite calls no busy handler there).
        retry_busy(|| conn.pragma_update(None, "journal_mode", "WAL")).map_err(sql)?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(sql)?;
        // Migrations run under the write lock and read the version inside it:
        // writers starting together on a new file migrate it once, in turn.
        retry_busy(|| conn.execute_batch("BEGIN IMMEDIATE; COMMIT")).map_err(sql)?;
        let tx = conn
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(sql)?;
        let version: i64 = tx
            .pragma_query_value(None, "user_version", |row| row.get(0))
            .map_err(sql)?;
        let known = MIGRATIONS.len() as i64;
        if version > known {
            return Err(DbError::FutureSchema {
                path,
                found: version,
                known,
            });
        }
        for (i, migration) in MIGRATIONS.iter().enumerate().skip(version as usize) {
            tx.execute_batch(migration).map_err(sql)?;
            tx.pragma_update(None, "user_version", (i + 1) as i64)
                .map_err(sql)?;
        }
        tx.commit().map_err(sql)?;
        Ok(Self { conn, path })
    }

    fn sql(&self) -> impl Fn(rusqlite::Error) -> DbError + '_ {
        |source| DbError::from_sqlite(&self.path, source)
    }

    /// A write transaction that holds the write lock from its first statement
    /// (`BEGIN IMMEDIATE`): what it reads cannot change before it writes, and
    /// a second writer waits for the lock up to the busy timeout instead of
    /// failing when a read would have to become a write.
    fn write(&mut self) -> Result<Transaction<'_>, DbError> {
        let path = self.path.clone();
        self.conn
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(|source| DbError::from_sqlite(&path, source))
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    pub fn schema_version(&self) -> Result<i64, DbError> {
        self.conn
            .pragma_query_value(None, "user_version", |row| row.get(0))
            .map_err(self.sql())
    }

    /// SQLite's own consistency check; `Err` names what it found.
    pub fn check_integrity(&self) -> Result<(), DbError> {
        let verdict: String = self
            .conn
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .map_err(self.sql())?;
        if verdict == "ok" {
            Ok(())
        } else {
            Err(DbError::Corrupt {
                path: self.path.clone(),
                id: String::new(),
                field: "integrity_check",
                reason: verdict,
            })
        }
    }

    /// The revision of the last change; 0 for an empty, untouched database.
    pub fn revision(&self) -> Result<u64, DbError> {
        let rev: i64 = self
            .conn
            .query_row("SELECT value FROM meta WHERE key = 'revision'", [], |r| {
                r.get(0)
            })
            .map_err(self.sql())?;
        Ok(rev as u64)
    }

    /// Validates and writes every record in one transaction: all of them or none.
    /// Each record gets its own revision and change-log entry. Returns the last revision.
    pub fn upsert_all(
        &mut self,
        records: &[LandmarkRecord],
        author: &Author,
    ) -> Result<u64, DbError> {
        self.write_records(records, Expect::Any, author)
    }

    /// Writes `record` if the stored tower is as `expect` says, in one
    /// transaction that holds the write lock from the check to the write:
    /// a concurrent `add` of the same id or an edit from a stale read is
    /// refused (`Exists`, `Conflict`), never silently replaced.
    pub fn upsert_expecting(
        &mut self,
        record: &LandmarkRecord,
        expect: Expect,
        author: &Author,
    ) -> Result<u64, DbError> {
        self.write_records(std::slice::from_ref(record), expect, author)
    }

    /// Reads tower `id`, changes it with `edit` and writes it back, all under
    /// the write lock: two concurrent edits of one tower both land.
    /// `Ok(None)` if there is no such tower.
    pub fn edit<E>(
        &mut self,
        id: &str,
        author: &Author,
        edit: impl FnOnce(&mut LandmarkRecord) -> Result<(), E>,
    ) -> Result<Edited<E>, DbError> {
        let path = self.path.clone();
        let tx = self.write()?;
        let Some(mut record) = get_in(&tx, &path, id)? else {
            return Ok(None);
        };
        if let Err(e) = edit(&mut record) {
            return Ok(Some(Err(e)));
        }
        validate(&record)?;
        let revision = write_in(
            &tx,
            &path,
            std::slice::from_ref(&record),
            Expect::Any,
            author,
        )?;
        tx.commit().map_err(|s| DbError::from_sqlite(&path, s))?;
        Ok(Some(Ok((record, revision))))
    }

    fn write_records(
        &mut self,
        records: &[LandmarkRecord],
        expect: Expect,
        author: &Author,
    ) -> Result<u64, DbError> {
        for r in records {
            validate(r)?;
        }
        let path = self.path.clone();
        let tx = self.write()?;
        let revision = write_in(&tx, &path, records, expect, author)?;
        tx.commit().map_err(|s| DbError::from_sqlite(&path, s))?;
        Ok(revision)
    }

    pub fn upsert(&mut self, record: &LandmarkRecord, author: &Author) -> Result<u64, DbError> {
        self.upsert_all(std::slice::from_ref(record), author)
    }

    /// Removes a tower; `Ok(None)` if there was none by that id.
    pub fn remove(&mut self, id: &str, author: &Author) -> Result<Option<u64>, DbError> {
        let path = self.path.clone();
        let tx = self.write()?;
        let revision = remove_in(&tx, &path, id, author)?;
        if revision.is_some() {
            tx.commit().map_err(|s| DbError::from_sqlite(&path, s))?;
        }
        Ok(revision)
    }

    /// Puts the towers of `before` back as they were, in one transaction: a
    /// record is written again, `None` removes the tower (it did not exist).
    /// What undoes an import as a whole. Returns the last revision.
    pub fn revert(
        &mut self,
        before: &[(String, Option<LandmarkRecord>)],
        author: &Author,
    ) -> Result<u64, DbError> {
        for record in before.iter().filter_map(|(_, r)| r.as_ref()) {
            validate(record)?;
        }
        let path = self.path.clone();
        let tx = self.write()?;
        for (id, record) in before {
            match record {
                Some(record) => {
                    write_in(
                        &tx,
                        &path,
                        std::slice::from_ref(record),
                        Expect::Any,
                        author,
                    )?;
                }
                None => {
                    remove_in(&tx, &path, id, author)?;
                }
            }
        }
        let revision = current_revision(&tx).map_err(|s| DbError::from_sqlite(&path, s))?;
        tx.commit().map_err(|s| DbError::from_sqlite(&path, s))?;
        Ok(revision)
    }

    pub fn get(&self, id: &str) -> Result<Option<LandmarkRecord>, DbError> {
        let row = self
            .conn
            .query_row(
                &format!("SELECT {COLUMNS} FROM landmarks WHERE id = ?1"),
                [id],
                raw_row,
            )
            .optional()
            .map_err(self.sql())?;
        row.map(|raw| self.decode(raw)).transpose()
    }

    /// Every tower, ordered by id.
    pub fn list(&self) -> Result<Vec<LandmarkRecord>, DbError> {
        let mut stmt = self
            .conn
            .prepare(&format!("SELECT {COLUMNS} FROM landmarks ORDER BY id"))
            .map_err(self.sql())?;
        let raws = stmt
            .query_map([], raw_row)
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        raws.into_iter().map(|raw| self.decode(raw)).collect()
    }

    /// Every change after `revision`, in revision order: what a replica at `revision` needs.
    pub fn changes_since(&self, revision: u64) -> Result<Vec<LandmarkChange>, DbError> {
        Ok(self
            .history_since(revision)?
            .into_iter()
            .map(|entry| entry.change)
            .collect())
    }

    /// Every change after `revision` with who made it and when: the history an
    /// operator reads, removals included.
    pub fn history_since(&self, revision: u64) -> Result<Vec<HistoryEntry>, DbError> {
        let mut stmt = self
            .conn
            .prepare("SELECT revision, id, op, record, updated_by, updated_at_unix_s FROM changes WHERE revision > ?1 ORDER BY revision")
            .map_err(self.sql())?;
        let rows = stmt
            .query_map([revision as i64], |r| {
                Ok((
                    r.get::<_, i64>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, String>(2)?,
                    r.get::<_, Option<String>>(3)?,
                    r.get::<_, String>(4)?,
                    r.get::<_, i64>(5)?,
                ))
            })
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        rows.into_iter()
            .map(|(rev, id, op, record, by, at_unix_s)| {
                let corrupt = |reason: String| DbError::Corrupt {
                    path: self.path.clone(),
                    id: id.clone(),
                    field: "change",
                    reason,
                };
                let change = match (op.as_str(), record) {
                    ("remove", _) => LandmarkChangeOp::Remove { id: id.clone() },
                    ("upsert", Some(json)) => LandmarkChangeOp::Upsert {
                        record: serde_json::from_str(&json)
                            .map_err(|e| corrupt(format!("revision {rev}: {e}")))?,
                    },
                    (op, _) => {
                        return Err(corrupt(format!(
                            "revision {rev}: op {op:?} without a record"
                        )));
                    }
                };
                Ok(HistoryEntry {
                    change: LandmarkChange {
                        revision: rev as u64,
                        change,
                    },
                    author: Author { by, at_unix_s },
                })
            })
            .collect()
    }

    fn decode(&self, raw: RawRow) -> Result<LandmarkRecord, DbError> {
        decode(&self.path, raw)
    }
}

fn decode(path: &str, raw: RawRow) -> Result<LandmarkRecord, DbError> {
    let tower_type: TowerType =
        raw.tower_type
            .parse()
            .map_err(|e: towernav_protocol::TowerTypeError| DbError::Corrupt {
                path: path.into(),
                id: raw.record.id.clone(),
                field: "tower_type",
                reason: e.to_string(),
            })?;
    Ok(LandmarkRecord {
        tower_type,
        ..raw.record
    })
}

/// A row before its tower type is checked (SQLite cannot hold our enum).
struct RawRow {
    record: LandmarkRecord,
    tower_type: String,
}

fn raw_row(row: &rusqlite::Row<'_>) -> rusqlite::Result<RawRow> {
    Ok(RawRow {
        tower_type: row.get(1)?,
        record: LandmarkRecord {
            base_width_m: row.get(6)?,
            line_name: row.get(7)?,
            survey_source: row.get(8)?,
            sigma_horizontal_m: row.get(9)?,
            sigma_vertical_m: row.get(10)?,
            notes: row.get(11)?,
            updated_at_unix_s: row.get(12)?,
            updated_by: row.get(13)?,
            revision: row.get::<_, i64>(14)? as u64,
            ..LandmarkRecord::new(
                row.get::<_, String>(0)?,
                TowerType::A,
                row.get(2)?,
                row.get(3)?,
                row.get(4)?,
                row.get(5)?,
            )
        },
    })
}

/// The records written inside `tx`, each with its revision and change-log
/// entry, after `expect` was checked against what is stored. Returns the last revision.
fn write_in(
    tx: &Transaction<'_>,
    path: &str,
    records: &[LandmarkRecord],
    expect: Expect,
    author: &Author,
) -> Result<u64, DbError> {
    let sql = |source| DbError::from_sqlite(path, source);
    // Imports replace whatever is stored: no look-up per row for them.
    for r in records.iter().filter(|_| expect != Expect::Any) {
        let stored: Option<i64> = tx
            .query_row(
                "SELECT revision FROM landmarks WHERE id = ?1",
                [&r.id],
                |row| row.get(0),
            )
            .optional()
            .map_err(sql)?;
        match (expect, stored) {
            (Expect::Absent, Some(_)) => {
                return Err(DbError::Exists {
                    path: path.into(),
                    id: r.id.clone(),
                });
            }
            (Expect::Revision(want), found) if found != Some(want as i64) => {
                return Err(DbError::Conflict {
                    path: path.into(),
                    id: r.id.clone(),
                    expected: want,
                    found: found.map(|f| f as u64),
                });
            }
            _ => {}
        }
    }
    let mut revision = current_revision(tx).map_err(sql)?;
    {
        let mut upsert = tx
                .prepare_cached(&format!(
                    "INSERT OR REPLACE INTO landmarks ({COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15)"
                ))
                .map_err(sql)?;
        let mut log = tx
                .prepare_cached(
                    "INSERT INTO changes (revision, id, op, record, updated_at_unix_s, updated_by) VALUES (?1, ?2, 'upsert', ?3, ?4, ?5)",
                )
                .map_err(sql)?;
        for r in records {
            revision += 1;
            let stored = LandmarkRecord {
                updated_at_unix_s: author.at_unix_s,
                updated_by: author.by.clone(),
                revision,
                ..r.clone()
            };
            upsert
                .execute(params![
                    stored.id,
                    stored.tower_type.as_str(),
                    stored.lat_deg,
                    stored.lon_deg,
                    stored.ground_elev_m,
                    stored.height_m,
                    stored.base_width_m,
                    stored.line_name,
                    stored.survey_source,
                    stored.sigma_horizontal_m,
                    stored.sigma_vertical_m,
                    stored.notes,
                    stored.updated_at_unix_s,
                    stored.updated_by,
                    revision as i64
                ])
                .map_err(sql)?;
            let json = serde_json::to_string(&stored).map_err(|e| DbError::Corrupt {
                path: path.into(),
                id: stored.id.clone(),
                field: "record",
                reason: e.to_string(),
            })?;
            log.execute(params![
                revision as i64,
                stored.id,
                json,
                author.at_unix_s,
                author.by
            ])
            .map_err(sql)?;
        }
    }
    set_revision(tx, revision).map_err(sql)?;
    Ok(revision)
}

/// `op` again while SQLite answers busy without waiting, up to the busy timeout.
fn retry_busy<T>(mut op: impl FnMut() -> rusqlite::Result<T>) -> rusqlite::Result<T> {
    let started = std::time::Instant::now();
    loop {
        match op() {
            Err(e)
                if e.sqlite_error_code() == Some(rusqlite::ErrorCode::DatabaseBusy)
                    && started.elapsed() < BUSY_TIMEOUT =>
            {
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            other => return other,
        }
    }
}

/// One tower read inside a transaction.
fn get_in(tx: &Transaction<'_>, path: &str, id: &str) -> Result<Option<LandmarkRecord>, DbError> {
    let raw = tx
        .query_row(
            &format!("SELECT {COLUMNS} FROM landmarks WHERE id = ?1"),
            [id],
            raw_row,
        )
        .optional()
        .map_err(|s| DbError::from_sqlite(path, s))?;
    raw.map(|raw| decode(path, raw)).transpose()
}

/// Removes `id` inside `tx` with its change-log entry; `None` if absent.
fn remove_in(
    tx: &Transaction<'_>,
    path: &str,
    id: &str,
    author: &Author,
) -> Result<Option<u64>, DbError> {
    let sql = |source| DbError::from_sqlite(path, source);
    if tx
        .execute("DELETE FROM landmarks WHERE id = ?1", [id])
        .map_err(sql)?
        == 0
    {
        return Ok(None);
    }
    let revision = current_revision(tx).map_err(sql)? + 1;
    tx.execute(
        "INSERT INTO changes (revision, id, op, record, updated_at_unix_s, updated_by) VALUES (?1, ?2, 'remove', NULL, ?3, ?4)",
        params![revision as i64, id, author.at_unix_s, author.by],
    )
    .map_err(sql)?;
    set_revision(tx, revision).map_err(sql)?;
    Ok(Some(revision))
}

fn current_revision(tx: &Transaction<'_>) -> rusqlite::Result<u64> {
    tx.query_row("SELECT value FROM meta WHERE key = 'revision'", [], |r| {
        r.get::<_, i64>(0)
    })
    .map(|v| v as u64)
}

fn set_revision(tx: &Transaction<'_>, revision: u64) -> rusqlite::Result<()> {
    tx.execute(
        "UPDATE meta SET value = ?1 WHERE key = 'revision'",
        [revision as i64],
    )
    .map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::surveyed as tower;

    #[test]
    fn revert_puts_towers_back_and_removes_new_ones_in_one_go() {
        let mut db = LandmarkDb::open_in_memory().expect("db");
        let author = Author::now("op");
        let a = tower("A1", 30.0);
        db.upsert(&a, &author).expect("a");
        let before = vec![
            ("A1".to_owned(), db.get("A1").expect("get")),
            ("N1".to_owned(), None),
        ];
        let mut moved = a.clone();
        moved.lat_deg += 0.01;
        db.upsert_all(&[moved, tower("N1", 32.0)], &author)
            .expect("import");
        db.revert(&before, &author).expect("revert");
        let back = db.get("A1").expect("get").expect("A1 is there");
        assert_eq!(back.lat_deg, a.lat_deg);
        assert!(db.get("N1").expect("get").is_none());
        // The edges hear the undo as changes, after the import's.
        let ops: Vec<_> = db.changes_since(3).expect("changes");
        assert_eq!(ops.len(), 2, "{ops:?}");
    }

    fn surveyor() -> Author {
        Author {
            by: "crew-7".into(),
            at_unix_s: 1_790_000_000,
        }
    }

    #[test]
    fn upsert_get_list_remove_bump_revisions() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        let me = surveyor();
        assert_eq!(db.revision().expect("rev"), 0);
        assert_eq!(db.upsert(&tower("B1", 35.0), &me).expect("upsert"), 1);
        assert_eq!(db.upsert(&tower("B1", 36.0), &me).expect("upsert"), 2);
        let got = db.get("B1").expect("get").expect("present");
        assert_eq!(got.height_m, 36.0);
        assert_eq!(got.revision, 2);
        assert_eq!(got.updated_by, "crew-7");
        assert_eq!(got.sigma_horizontal_m, Some(0.05));
        assert_eq!(
            db.upsert_all(&[tower("B2", 30.0), tower("A0", 31.0)], &me)
                .expect("batch"),
            4
        );
        let ids: Vec<_> = db.list().expect("list").into_iter().map(|r| r.id).collect();
        assert_eq!(ids, ["A0", "B1", "B2"]);
        assert_eq!(db.remove("B2", &me).expect("remove"), Some(5));
        assert_eq!(db.remove("B2", &me).expect("remove"), None);
        assert_eq!(db.revision().expect("rev"), 5);
    }

    #[test]
    fn the_change_log_replays_to_the_current_set() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        let me = surveyor();
        db.upsert_all(&[tower("B1", 35.0), tower("B2", 30.0)], &me)
            .expect("batch");
        db.upsert(&tower("B1", 37.0), &me).expect("edit");
        db.remove("B2", &me).expect("remove");
        let changes = db.changes_since(0).expect("log");
        assert_eq!(
            changes.iter().map(|c| c.revision).collect::<Vec<_>>(),
            [1, 2, 3, 4]
        );
        assert!(matches!(&changes[3].change, LandmarkChangeOp::Remove { id } if id == "B2"));
        let mut replica = std::collections::BTreeMap::new();
        for c in changes {
            match c.change {
                LandmarkChangeOp::Upsert { record } => replica.insert(record.id.clone(), *record),
                LandmarkChangeOp::Remove { id } => replica.remove(&id),
            };
        }
        assert_eq!(
            replica.into_values().collect::<Vec<_>>(),
            db.list().expect("list")
        );
        assert_eq!(db.changes_since(3).expect("tail").len(), 1);
    }

    #[test]
    fn the_history_names_who_removed_a_tower_and_when() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        db.upsert(&tower("B1", 35.0), &surveyor()).expect("add");
        let operator = Author {
            by: "operator-2".into(),
            at_unix_s: 1_790_000_500,
        };
        db.remove("B1", &operator).expect("remove");
        let history = db.history_since(0).expect("history");
        assert_eq!(history.len(), 2);
        assert_eq!(history[0].author, surveyor());
        assert!(matches!(&history[1].change.change, LandmarkChangeOp::Remove { id } if id == "B1"));
        assert_eq!(history[1].author, operator);
    }

    #[test]
    fn an_invalid_record_in_a_batch_writes_nothing() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        let err = db
            .upsert_all(&[tower("B1", 35.0), tower("B2", -1.0)], &surveyor())
            .expect_err("must refuse");
        assert!(
            err.to_string().contains("B2") && err.to_string().contains("height_m"),
            "{err}"
        );
        assert!(db.list().expect("list").is_empty());
        assert!(db.changes_since(0).expect("log").is_empty());
        assert_eq!(db.revision().expect("rev"), 0);
    }

    #[test]
    fn a_file_database_persists_and_uses_wal() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("towers.sqlite");
        {
            let mut db = LandmarkDb::open(&path).expect("open");
            db.upsert(&tower("B1", 35.0), &surveyor()).expect("upsert");
            let mode: String = db
                .conn
                .pragma_query_value(None, "journal_mode", |r| r.get(0))
                .expect("pragma");
            assert_eq!(mode, "wal");
        }
        let db = LandmarkDb::open(&path).expect("reopen");
        assert_eq!(
            db.schema_version().expect("version"),
            MIGRATIONS.len() as i64
        );
        assert_eq!(db.list().expect("list").len(), 1);
    }

    /// Builds a database as each earlier schema version left it, then opens it with this build.
    #[test]
    fn migrates_from_every_earlier_schema_version() {
        for from in 0..MIGRATIONS.len() {
            let dir = tempfile::tempdir().expect("tempdir");
            let path = dir.path().join(format!("v{from}.sqlite"));
            {
                let conn = Connection::open(&path).expect("open");
                for m in &MIGRATIONS[..from] {
                    conn.execute_batch(m).expect("old migration");
                }
                conn.pragma_update(None, "user_version", from as i64)
                    .expect("version");
                if from == 1 {
                    conn.execute_batch(
                        "INSERT INTO landmarks (id, tower_type, lat_deg, lon_deg, ground_elev_m, height_m, notes, revision)
                         VALUES ('A1', 'A', 30.5, 114.3, 20.0, 32.0, 'from v1', 1);
                         UPDATE meta SET value = 1 WHERE key = 'revision';",
                    )
                    .expect("v1 row");
                }
            }
            let db = LandmarkDb::open(&path).expect("migrate");
            assert_eq!(
                db.schema_version().expect("version"),
                MIGRATIONS.len() as i64,
                "from v{from}"
            );
            if from == 1 {
                let a1 = db.get("A1").expect("get").expect("kept");
                assert_eq!(
                    (a1.notes.as_str(), a1.height_m, a1.revision, a1.base_width_m),
                    ("from v1", 32.0, 1, None)
                );
                let log = db.changes_since(0).expect("backfilled log");
                assert!(
                    matches!(&log[..], [LandmarkChange { revision: 1, change: LandmarkChangeOp::Upsert { record } }] if **record == a1)
                );
            }
        }
    }

    #[test]
    fn a_database_from_a_newer_build_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("future.sqlite");
        let conn = Connection::open(&path).expect("open");
        conn.pragma_update(None, "user_version", 99)
            .expect("pragma");
        drop(conn);
        assert!(matches!(
            LandmarkDb::open(&path),
            Err(DbError::FutureSchema { found: 99, .. })
        ));
    }
}
