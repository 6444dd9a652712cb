//! Fleet scale: 20 simulated edges through one router-mode Zenoh session to one
//! subscriber, as fast as they can run: not one pose is lost.
//! Secured, the same through mutual TLS and the fleet's access rules.
//! (The timing figures come from `cargo bench -p towernav-tests --bench fleet`.)

use towernav_tests::fleet::{FleetOptions, run_fleet};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_edges_through_one_router_lose_no_pose() -> anyhow::Result<()> {
    let report = run_fleet(&FleetOptions {
        edges: 20,
        frames: 120,
        speed: 0.0,
        preview_hz: 0.0,
        record: None,
        zenohd: None,
        secure: false,
    })
    .await?;
    assert_eq!(report.published.len(), 20);
    let published: u64 = report.published.values().sum();
    assert!(
        published > 20 * 90,
        "the edges localized: {published} poses"
    );
    assert_eq!(report.lost(), vec![], "poses lost on the way");
    assert_eq!(
        report.latency_ms.len() as u64,
        published,
        "every pose carried a timestamp"
    );
    Ok(())
}

/// The access rules let a fleet's own traffic through: every pose of every
/// edge (client of the router, with its certificate) reaches the subscriber.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_secured_fleet_loses_no_pose() -> anyhow::Result<()> {
    let report = run_fleet(&FleetOptions {
        edges: 4,
        frames: 90,
        speed: 0.0,
        preview_hz: 0.0,
        record: None,
        zenohd: None,
        secure: true,
    })
    .await?;
    assert_eq!(report.published.len(), 4);
    let published: u64 = report.published.values().sum();
    assert!(published > 4 * 60, "the edges localized: {published} poses");
    assert_eq!(report.lost(), vec![], "poses lost on the way");
    Ok(())
}
