//! Ground station to edge landmark sync over Zenoh on loopback: the edge gets the
//! full set, follows live edits, catches up after missing changes while down,
//! re-asks on a gap, and starts from its saved replica when nobody answers.

use std::time::Duration;

use towernav_edge::landmark_sync::{LandmarkSync, Source};
use towernav_edge::node::open_session;
use towernav_ground_station::landmark_service::serve;
use towernav_landmark_db::{Author, LandmarkDb};
use towernav_protocol::session::Endpoints;
use towernav_protocol::{
    Keys, LandmarkChange, LandmarkChangeOp, LandmarkRecord, NodeId, TowerType, encode,
};
use towernav_sim::World;

/// Applies changes as they arrive until the replica equals the database, or
/// fails after a few seconds without.
async fn converge(sync: &mut LandmarkSync, db: &LandmarkDb) -> anyhow::Result<()> {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    sync.poll().await?;
    while sync.replica().records() != db.list()? || sync.replica().revision != db.revision()? {
        let change = tokio::time::timeout_at(deadline, sync.next_change()).await;
        let Ok(Some(change)) = change else {
            anyhow::bail!(
                "replica at r{} never matched the database at r{}",
                sync.replica().revision,
                db.revision()?
            );
        };
        sync.apply(Some(change)).await?;
    }
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_edge_replica_follows_the_ground_station() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let db_path = dir.path().join("gs.sqlite");
    let replica_path = dir.path().join("replica.json");
    let crew = Author {
        by: "crew".into(),
        at_unix_s: 0,
    };
    let mut db = LandmarkDb::open(&db_path)?;
    db.upsert_all(&World::paper_field().landmarks(), &crew)?;

    let fleet = NodeId::new("synctest")?;
    let endpoint = towernav_tests::loopback_endpoint();
    let gs = open_session(&Endpoints {
        listen: vec![endpoint.clone()],
        connect: vec![],
        ..Default::default()
    })
    .await?;
    let service = tokio::spawn(serve(gs.clone(), fleet.clone(), db_path.clone()));
    let edge = open_session(&Endpoints {
        listen: vec![],
        connect: vec![endpoint],
        ..Default::default()
    })
    .await?;
    towernav_edge::node::wait_for_peer(&edge, Duration::from_secs(10)).await?;

    // Full set at start.
    let timeout = Duration::from_secs(2);
    let (mut sync, source) =
        LandmarkSync::start(&edge, fleet.clone(), replica_path.clone(), timeout).await?;
    assert_eq!(source, Source::GroundStation);
    assert_eq!(sync.replica().len(), 18);

    // Live edits, including a removal, arrive in order.
    db.upsert(
        &LandmarkRecord::new("Z1", TowerType::D, 30.53, 114.37, 25.0, 50.0),
        &crew,
    )?;
    db.remove("A1", &crew)?;
    converge(&mut sync, &db).await?;

    // The edge is down while the crew edits; on restart it asks for what it missed.
    drop(sync);
    db.upsert(
        &LandmarkRecord::new("Z2", TowerType::C, 30.53, 114.38, 25.0, 45.0),
        &crew,
    )?;
    db.remove("B2", &crew)?;
    let (mut sync, source) =
        LandmarkSync::start(&edge, fleet.clone(), replica_path.clone(), timeout).await?;
    assert_eq!(source, Source::GroundStation);
    converge(&mut sync, &db).await?;

    // A change that skips revisions is a gap: the edge re-asks and converges to the truth.
    let bogus = LandmarkChange {
        revision: db.revision()? + 5,
        change: LandmarkChangeOp::Remove { id: "C1".into() },
    };
    edge.put(Keys::new(fleet.clone()).landmark_changes(), encode(&bogus)?)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // The bogus change arrives, is seen as a gap, and the answer to the re-ask wins.
    let bogus_arrived = tokio::time::timeout(Duration::from_secs(5), sync.next_change()).await?;
    sync.apply(bogus_arrived).await?;
    converge(&mut sync, &db).await?;
    assert!(
        sync.replica().records().iter().any(|r| r.id == "C1"),
        "the gap's change was not applied blindly"
    );
    let expected = db.list()?;
    drop(sync);

    // The ground station goes away: the edge starts from its saved replica and says so.
    service.abort();
    gs.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    let (sync, source) =
        LandmarkSync::start(&edge, fleet, replica_path, Duration::from_millis(500)).await?;
    assert_eq!(source, Source::SavedReplica);
    assert_eq!(sync.replica().records(), expected);
    Ok(())
}
