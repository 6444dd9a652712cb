//! The ground station as owner of the landmark database: it answers the landmark
//! queryable and publishes every change. It tails the database's change log, so
//! edits made by `towernav-db` beside it go out too.

use std::path::PathBuf;
use std::time::Duration;

use towernav_landmark_db::LandmarkDb;
use towernav_protocol::{Keys, LandmarkSyncReply, LandmarkSyncRequest, NodeId, decode, encode};
use zenoh::Session;

/// How often the change log is tailed.
const TAIL_PERIOD: Duration = Duration::from_millis(200);

pub async fn serve(session: Session, fleet: NodeId, db_path: PathBuf) -> Result<(), String> {
    let db = LandmarkDb::open(&db_path).map_err(|e| e.to_string())?;
    let keys = Keys::new(fleet);
    let query_key = keys.landmark_query();
    let queryable = session
        .declare_queryable(query_key.clone())
        .await
        .map_err(|e| format!("declaring {query_key}: {e}"))?;
    let changes_key = keys.landmark_changes();
    let publisher = session
        .declare_publisher(changes_key.clone())
        .await
        .map_err(|e| format!("declaring {changes_key}: {e}"))?;
    let mut published = db.revision().map_err(|e| e.to_string())?;
    let mut tail = tokio::time::interval(TAIL_PERIOD);
    tracing::info!(%query_key, revision = published, db = %db_path.display(), "serving landmarks");
    loop {
        tokio::select! {
            query = queryable.recv_async() => {
                let Ok(query) = query else { return Ok(()) };
                let request = query
                    .payload()
                    .map(|p| decode::<LandmarkSyncRequest>(&p.to_bytes()))
                    .unwrap_or(Ok(LandmarkSyncRequest { since: None }));
                let reply = match request {
                    Ok(request) => answer(&db, &request).map_err(|e| e.to_string()),
                    Err(e) => Err(format!("bad landmark sync request: {e}")),
                };
                let sent = match reply.and_then(|r| encode(&r).map_err(|e| e.to_string())) {
                    Ok(bytes) => query.reply(query_key.clone(), bytes).await,
                    Err(e) => {
                        tracing::warn!(error = %e, "landmark query refused");
                        query.reply_err(e.into_bytes()).await
                    }
                };
                if let Err(e) = sent {
                    tracing::warn!(error = %e, "cannot answer a landmark query");
                }
            }
            _ = tail.tick() => {
                let changes = db.changes_since(published).map_err(|e| e.to_string())?;
                for change in changes {
                    let bytes = encode(&change).map_err(|e| e.to_string())?;
                    publisher.put(bytes).await.map_err(|e| format!("publishing on {changes_key}: {e}"))?;
                    published = change.revision;
                }
            }
        }
    }
}

/// Changes since the replica's revision, or the full set when it asks for it or is ahead of us.
pub fn answer(
    db: &LandmarkDb,
    request: &LandmarkSyncRequest,
) -> Result<LandmarkSyncReply, towernav_landmark_db::DbError> {
    let revision = db.revision()?;
    Ok(match request.since {
        Some(since) if since <= revision => LandmarkSyncReply {
            revision,
            full: None,
            changes: db.changes_since(since)?,
        },
        _ => LandmarkSyncReply {
            revision,
            full: Some(db.list()?),
            changes: Vec::new(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_landmark_db::Author;
    use towernav_protocol::{LandmarkRecord, TowerType};

    #[test]
    fn answers_changes_or_the_full_set() {
        let mut db = LandmarkDb::open_in_memory().expect("open");
        let by = Author {
            by: "t".into(),
            at_unix_s: 0,
        };
        db.upsert(
            &LandmarkRecord::new("A1", TowerType::A, 30.5, 114.3, 20.0, 30.0),
            &by,
        )
        .expect("upsert");
        db.upsert(
            &LandmarkRecord::new("A2", TowerType::A, 30.6, 114.3, 20.0, 30.0),
            &by,
        )
        .expect("upsert");
        let tail = answer(&db, &LandmarkSyncRequest { since: Some(1) }).expect("answer");
        assert_eq!(
            (tail.revision, tail.full.is_none(), tail.changes.len()),
            (2, true, 1)
        );
        let full = answer(&db, &LandmarkSyncRequest { since: None }).expect("answer");
        assert_eq!(full.full.map(|f| f.len()), Some(2));
        let ahead = answer(&db, &LandmarkSyncRequest { since: Some(9) }).expect("answer");
        assert!(ahead.full.is_some(), "a replica ahead of us is reset");
    }
}
