//! SQLite storage: WAL, synchronous=FULL, one transaction per write, versioned schema.

use std::path::Path;

use rusqlite::{Connection, OptionalExtension, Transaction, params};
use towernav_protocol::{LandmarkRecord, TowerType};

use crate::error::DbError;
use crate::validate::validate;

/// Each entry moves the schema from version `i` to `i + 1`; never edit a shipped one.
const MIGRATIONS: &[&str] = &[
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
];

pub struct LandmarkDb {
    conn: Connection,
    path: String,
}

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
        let sql = |source| DbError::Sqlite {
            path: path.clone(),
            source,
        };
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(sql)?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(sql)?;
        let version: i64 = conn
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
            let tx = conn.transaction().map_err(sql)?;
            tx.execute_batch(migration).map_err(sql)?;
            tx.pragma_update(None, "user_version", (i + 1) as i64)
                .map_err(sql)?;
            tx.commit().map_err(sql)?;
        }
        Ok(Self { conn, path })
    }

    fn sql(&self) -> impl Fn(rusqlite::Error) -> DbError + '_ {
        |source| DbError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    pub fn schema_version(&self) -> Result<i64, DbError> {
        self.conn
            .pragma_query_value(None, "user_version", |row| row.get(0))
            .map_err(self.sql())
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
    /// Each record gets its own revision. Returns the last revision.
    pub fn upsert_all(&mut self, records: &[LandmarkRecord]) -> Result<u64, DbError> {
        for r in records {
            validate(r)?;
        }
        let path = self.path.clone();
        let sql = |source| DbError::Sqlite {
            path: path.clone(),
            source,
        };
        let tx = self.conn.transaction().map_err(sql)?;
        let mut revision = current_revision(&tx).map_err(sql)?;
        for r in records {
            revision += 1;
            tx.execute(
                "INSERT INTO landmarks (id, tower_type, lat_deg, lon_deg, ground_elev_m, height_m, notes, revision)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)
                 ON CONFLICT(id) DO UPDATE SET tower_type = ?2, lat_deg = ?3, lon_deg = ?4,
                     ground_elev_m = ?5, height_m = ?6, notes = ?7, revision = ?8",
                params![r.id, r.tower_type.as_str(), r.lat_deg, r.lon_deg, r.ground_elev_m, r.height_m, r.notes, revision as i64],
            )
            .map_err(sql)?;
        }
        tx.execute(
            "UPDATE meta SET value = ?1 WHERE key = 'revision'",
            [revision as i64],
        )
        .map_err(sql)?;
        tx.commit().map_err(sql)?;
        Ok(revision)
    }

    pub fn upsert(&mut self, record: &LandmarkRecord) -> Result<u64, DbError> {
        self.upsert_all(std::slice::from_ref(record))
    }

    /// Removes a tower; `Ok(None)` if there was none by that id.
    pub fn remove(&mut self, id: &str) -> Result<Option<u64>, DbError> {
        let path = self.path.clone();
        let sql = |source| DbError::Sqlite {
            path: path.clone(),
            source,
        };
        let tx = self.conn.transaction().map_err(sql)?;
        if tx
            .execute("DELETE FROM landmarks WHERE id = ?1", [id])
            .map_err(sql)?
            == 0
        {
            return Ok(None);
        }
        let revision = current_revision(&tx).map_err(sql)? + 1;
        tx.execute(
            "UPDATE meta SET value = ?1 WHERE key = 'revision'",
            [revision as i64],
        )
        .map_err(sql)?;
        tx.commit().map_err(sql)?;
        Ok(Some(revision))
    }

    pub fn get(&self, id: &str) -> Result<Option<LandmarkRecord>, DbError> {
        let row = self
            .conn
            .query_row(&format!("{SELECT} WHERE id = ?1"), [id], raw_row)
            .optional()
            .map_err(self.sql())?;
        row.map(|raw| self.decode(raw)).transpose()
    }

    /// Every tower, ordered by id.
    pub fn list(&self) -> Result<Vec<LandmarkRecord>, DbError> {
        let mut stmt = self
            .conn
            .prepare(&format!("{SELECT} ORDER BY id"))
            .map_err(self.sql())?;
        let raws = stmt
            .query_map([], raw_row)
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        raws.into_iter().map(|raw| self.decode(raw)).collect()
    }

    fn decode(&self, raw: RawRow) -> Result<LandmarkRecord, DbError> {
        let tower_type: TowerType = raw.tower_type.parse().map_err(|reason| DbError::Corrupt {
            path: self.path.clone(),
            id: raw.record.id.clone(),
            field: "tower_type",
            reason,
        })?;
        Ok(LandmarkRecord {
            tower_type,
            ..raw.record
        })
    }
}

const SELECT: &str = "SELECT id, tower_type, lat_deg, lon_deg, ground_elev_m, height_m, notes, revision FROM landmarks";

/// A row before its tower type is checked (SQLite cannot hold our enum).
struct RawRow {
    record: LandmarkRecord,
    tower_type: String,
}

fn raw_row(row: &rusqlite::Row<'_>) -> rusqlite::Result<RawRow> {
    Ok(RawRow {
        tower_type: row.get(1)?,
        record: LandmarkRecord {
            id: row.get(0)?,
            tower_type: TowerType::A,
            lat_deg: row.get(2)?,
            lon_deg: row.get(3)?,
            ground_elev_m: row.get(4)?,
            height_m: row.get(5)?,
            notes: row.get(6)?,
            revision: row.get::<_, i64>(7)? as u64,
        },
    })
}

fn current_revision(tx: &Transaction<'_>) -> rusqlite::Result<u64> {
    tx.query_row("SELECT value FROM meta WHERE key = 'revision'", [], |r| {
        r.get::<_, i64>(0)
    })
    .map(|v| v as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn tower(id: &str, height_m: f64) -> LandmarkRecord {
        LandmarkRecord {
            id: id.into(),
            tower_type: TowerType::B,
            lat_deg: 30.5,
            lon_deg: 114.3,
            ground_elev_m: 20.0,
            height_m,
            notes: "survey 2026".into(),
            revision: 0,
        }
    }

    #[test]
    fn upsert_get_list_remove_bump_revisions() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        assert_eq!(db.revision().expect("rev"), 0);
        assert_eq!(db.upsert(&tower("B1", 35.0)).expect("upsert"), 1);
        assert_eq!(db.upsert(&tower("B1", 36.0)).expect("upsert"), 2);
        let got = db.get("B1").expect("get").expect("present");
        assert_eq!(got.height_m, 36.0);
        assert_eq!(got.revision, 2);
        assert_eq!(
            db.upsert_all(&[tower("B2", 30.0), tower("A0", 31.0)])
                .expect("batch"),
            4
        );
        let ids: Vec<_> = db.list().expect("list").into_iter().map(|r| r.id).collect();
        assert_eq!(ids, ["A0", "B1", "B2"]);
        assert_eq!(db.remove("B2").expect("remove"), Some(5));
        assert_eq!(db.remove("B2").expect("remove"), None);
        assert_eq!(db.revision().expect("rev"), 5);
    }

    #[test]
    fn an_invalid_record_in_a_batch_writes_nothing() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        let err = db
            .upsert_all(&[tower("B1", 35.0), tower("B2", -1.0)])
            .expect_err("must refuse");
        assert!(
            err.to_string().contains("B2") && err.to_string().contains("height_m"),
            "{err}"
        );
        assert!(db.list().expect("list").is_empty());
        assert_eq!(db.revision().expect("rev"), 0);
    }

    #[test]
    fn a_file_database_persists_and_uses_wal() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("towers.sqlite");
        {
            let mut db = LandmarkDb::open(&path).expect("open");
            db.upsert(&tower("B1", 35.0)).expect("upsert");
            let mode: String = db
                .conn
                .pragma_query_value(None, "journal_mode", |r| r.get(0))
                .expect("pragma");
            assert_eq!(mode, "wal");
        }
        let db = LandmarkDb::open(&path).expect("reopen");
        assert_eq!(db.schema_version().expect("version"), 1);
        assert_eq!(db.list().expect("list").len(), 1);
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
