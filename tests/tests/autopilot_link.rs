//! MAVLink on loopback UDP: the daemon's GPS_INPUT reaches an autopilot-side
//! listener with the estimate's position and a 3-D fix, and ATTITUDE sent by an
//! autopilot is read back in the ENU convention.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{ATTITUDE_DATA, GpsFixType, MavMessage};
use mavlink::{MavConnection, MavHeader};
use towernav_edge::daemon::attitude::MavlinkAttitude;
use towernav_edge::daemon::config::{DetectorKind, EdgeConfig};
use towernav_edge::edge_cmd::run_edge;

fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("a free loopback port")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gps_input_reaches_the_autopilot_with_a_fix() -> anyhow::Result<()> {
    let port = free_udp_port();
    let autopilot = mavlink::connect::<MavMessage>(&format!("udpin:127.0.0.1:{port}"))?;
    let received = std::thread::spawn(move || {
        let mut got = Vec::new();
        let start = Instant::now();
        while got.len() < 5 && start.elapsed() < Duration::from_secs(20) {
            if let Ok((header, MavMessage::GPS_INPUT(g))) = autopilot.recv() {
                got.push((header, g));
            }
        }
        got
    });
    let mut config = EdgeConfig {
        fleet: "mav".into(),
        ..EdgeConfig::default()
    };
    config.zenoh.listen = vec![towernav_tests::loopback_endpoint()];
    config.detector.kind = DetectorKind::Oracle;
    config.source.max_frames = Some(300);
    config.source.speed = Some(2.0);
    config.mavlink.enabled = true;
    config.mavlink.address = format!("udpout:127.0.0.1:{port}");
    config.mavlink.rate_hz = 10.0;
    let summary = run_edge(&config, None, Arc::new(AtomicBool::new(false))).await?;
    assert!(summary.mavlink_sent >= 5, "{} sent", summary.mavlink_sent);
    let got = received
        .join()
        .map_err(|_| anyhow::anyhow!("listener panicked"))?;
    assert!(got.len() >= 5, "only {} GPS_INPUT arrived", got.len());
    let (header, last) = got.last().ok_or_else(|| anyhow::anyhow!("none"))?;
    assert_eq!((header.system_id, header.component_id), (1, 191));
    assert_eq!(last.fix_type, GpsFixType::GPS_FIX_TYPE_3D_FIX);
    // The paper's field lies near 30.52 N, 114.36 E.
    assert!(
        (f64::from(last.lat) / 1e7 - 30.52).abs() < 0.05,
        "{}",
        last.lat
    );
    assert!(
        (f64::from(last.lon) / 1e7 - 114.36).abs() < 0.05,
        "{}",
        last.lon
    );
    assert!(last.horiz_accuracy > 0.0 && last.horiz_accuracy < 10.0);
    Ok(())
}

#[test]
fn attitude_from_the_autopilot_is_read_in_enu() -> anyhow::Result<()> {
    let port = free_udp_port();
    let input = MavlinkAttitude::listen(&format!("udpin:127.0.0.1:{port}"))?;
    let autopilot = mavlink::connect::<MavMessage>(&format!("udpout:127.0.0.1:{port}"))?;
    let attitude = MavMessage::ATTITUDE(ATTITUDE_DATA {
        roll: 0.1,
        pitch: -0.05,
        yaw: std::f32::consts::FRAC_PI_2, // heading east
        ..ATTITUDE_DATA::DEFAULT
    });
    let start = Instant::now();
    // An autopilot streams ATTITUDE (here at 20 Hz) whether or not anyone
    // listens; this one streams until the edge has read one.
    loop {
        autopilot.send(&MavHeader::default(), &attitude)?;
        if let Some(a) = input.latest(Duration::from_secs(1)) {
            assert!((a.roll - 0.1).abs() < 1e-6 && (a.pitch + 0.05).abs() < 1e-6);
            assert!(a.yaw.abs() < 1e-6, "heading east is ENU yaw 0: {}", a.yaw);
            return Ok(());
        }
        anyhow::ensure!(start.elapsed() < Duration::from_secs(5), "no ATTITUDE read");
        std::thread::sleep(Duration::from_millis(50));
    }
}
