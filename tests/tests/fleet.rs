//! Fleet scale: 20 simulated edges through one router-mode Zenoh session to one
//! subscriber, as fast as they can run: not one pose is lost.
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
