//! The edge as ROS 2 and PX4 see it over Zenoh, checked by a listener that
//! is not ours (`tests/python/ros2_listen.py`: eclipse-zenoh, rosbags'
//! CDR decoder and type hashes, pycdr2 for PX4's XCDR2) through a router
//! standing in for rmw_zenoh's: keys, liveliness tokens, attachments and
//! every payload's values; and PX4's `vehicle_attitude` read back.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use serde_json::Value;
use towernav_edge::daemon::config::{AttitudeKind, DetectorKind, EdgeConfig};
use towernav_edge::edge_cmd::run_edge;
use towernav_protocol::ros2::msgs;
use towernav_protocol::session::{Endpoints, router_config};

/// PX4's own documentation prints this for `/fmu/out/vehicle_status` (PX4
/// v1.16-v1.17, `ros2 topic info -v`).
const PX4_DOCS_VEHICLE_STATUS_HASH: &str =
    "RIHS01_828bddbb7d4c2aa6ad93757955f6893be1ec5d8f11885ec7715bcdd76b5226c9";
/// Where the listener's fake PX4 clock starts, microseconds since boot.
const PX4_CLOCK_US: u64 = 5_000_000_000;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/px4_msgs")
}

/// The listener's process; killed and reaped if a test ends early.
struct Listener(Option<std::process::Child>);

impl Drop for Listener {
    fn drop(&mut self) {
        if let Some(mut child) = self.0.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// The listener, run for `seconds` against `router`.
fn listener(pythonpath: &std::ffi::OsStr, router: &str, seconds: f64, out: &Path) -> Listener {
    let child = std::process::Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("python/ros2_listen.py"))
        .args(["--connect", router, "--seconds", &seconds.to_string()])
        .arg("--msg-dir")
        .arg(fixtures())
        .args(["--px4-clock-us", &PX4_CLOCK_US.to_string()])
        .arg("--out")
        .arg(out)
        .env("PYTHONPATH", pythonpath)
        .spawn()
        .expect("python3 runs");
    Listener(Some(child))
}

/// Waits for the listener and parses what it heard.
fn finish(mut listener: Listener, out: &Path) -> anyhow::Result<Value> {
    let Some(mut child) = listener.0.take() else {
        anyhow::bail!("the listener was already reaped");
    };
    let status = child.wait()?;
    anyhow::ensure!(status.success(), "the listener failed: {status}");
    Ok(serde_json::from_str(&std::fs::read_to_string(out)?)?)
}

fn python() -> Option<std::ffi::OsString> {
    for module in ["zenoh", "rosbags", "pycdr2"] {
        towernav_tests::python_module(module)?;
    }
    towernav_tests::python_module("zenoh")
}

fn edge_config(onboard: &str, frames: u64) -> EdgeConfig {
    let mut c = EdgeConfig {
        fleet: "ros".into(),
        uav: "uav7".into(),
        ..EdgeConfig::default()
    };
    // Nobody on the fleet's side: this test listens onboard only.
    c.zenoh.listen = vec![towernav_tests::loopback_endpoint()];
    c.zenoh.connect = vec![];
    c.source.seed = 11;
    c.source.max_frames = Some(frames);
    // Real time, so the 10 Hz topics have a flight to report.
    c.source.speed = Some(1.0);
    c.detector.kind = DetectorKind::Oracle;
    c.ros2.enabled = true;
    c.ros2.connect = vec![onboard.into()];
    c.px4.enabled = true;
    c
}

/// A router standing in for rmw_zenoh's, on a loopback endpoint of its own.
async fn onboard_router() -> anyhow::Result<(String, zenoh::Session)> {
    let endpoint = towernav_tests::loopback_endpoint();
    let router = zenoh::open(router_config(&Endpoints {
        listen: vec![endpoint.clone()],
        ..Default::default()
    })?)
    .await
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok((endpoint, router))
}

fn array(v: &Value) -> &[Value] {
    v.as_array().map_or(&[], Vec::as_slice)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ros_2_and_px4_see_the_fix_as_rmw_zenoh_would_deliver_it() -> anyhow::Result<()> {
    let Some(pythonpath) = python() else {
        eprintln!("skipped: no eclipse-zenoh, rosbags or pycdr2 (cargo xtask test installs them)");
        return Ok(());
    };
    let (onboard, _router) = onboard_router().await?;
    let dir = tempfile::tempdir()?;
    let out = dir.path().join("heard.json");
    let child = listener(&pythonpath, &onboard, 14.0, &out);
    // The listener's session and liveliness subscriber come up first.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let summary = run_edge(
        &edge_config(&onboard, 210),
        None,
        Arc::new(AtomicBool::new(false)),
    )
    .await?;
    // A real-time source drops a frame the pipeline is too busy for.
    assert_eq!(summary.record.frames + summary.dropped, 210);
    let heard = tokio::task::spawn_blocking(move || finish(child, &out)).await??;

    // Type hashes: rosbags' equal ours, and rosbags' hash of PX4's
    // VehicleStatus is the one PX4 publishes.
    let hashes = &heard["hashes"];
    for t in [
        &msgs::NAV_SAT_FIX,
        &msgs::POSE_WITH_COVARIANCE_STAMPED,
        &msgs::ODOMETRY,
        &msgs::AUX_GLOBAL_POSITION,
        &msgs::VEHICLE_GLOBAL_POSITION,
        &msgs::VEHICLE_ATTITUDE,
    ] {
        assert_eq!(
            hashes[t.name].as_str(),
            Some(t.type_hash().as_str()),
            "{}",
            t.name
        );
    }
    assert_eq!(
        hashes["px4_msgs/msg/VehicleStatus"].as_str(),
        Some(PX4_DOCS_VEHICLE_STATUS_HASH)
    );

    // Keys, as rmw_zenoh's design document lays them out.
    let topics = &heard["topics"];
    let key_of = |t: &str| topics[t][0]["key"].as_str().unwrap_or_default().to_owned();
    assert_eq!(
        key_of("sensor_msgs/msg/NavSatFix"),
        format!(
            "0/towernav/fix/sensor_msgs::msg::dds_::NavSatFix_/{}",
            msgs::NAV_SAT_FIX.type_hash()
        )
    );
    assert_eq!(
        key_of("nav_msgs/msg/Odometry"),
        format!(
            "0/towernav/odometry/nav_msgs::msg::dds_::Odometry_/{}",
            msgs::ODOMETRY.type_hash()
        )
    );
    assert_eq!(
        key_of("px4_msgs/msg/AuxGlobalPosition"),
        format!(
            "0/fmu/in/aux_global_position/px4_msgs::msg::dds_::AuxGlobalPosition_/{}",
            msgs::AUX_GLOBAL_POSITION.type_hash()
        )
    );

    // Liveliness: the node, a publisher per topic, the attitude subscription;
    // all alive while the edge ran, all gone after.
    let alive: Vec<&str> = array(&heard["alive"])
        .iter()
        .filter_map(Value::as_str)
        .collect();
    let node = alive
        .iter()
        .find(|k| k.ends_with("/NN/%/%/towernav_edge"))
        .unwrap_or_else(|| panic!("no node token in {alive:?}"));
    let zid = node.split('/').nth(2).unwrap_or_default();
    assert_eq!(*node, format!("@ros2_lv/0/{zid}/0/0/NN/%/%/towernav_edge"));
    for (kind, topic, t, qos) in [
        ("MP", "%towernav%fix", &msgs::NAV_SAT_FIX, "::,10:,:,:,,"),
        (
            "MP",
            "%towernav%pose",
            &msgs::POSE_WITH_COVARIANCE_STAMPED,
            "::,10:,:,:,,",
        ),
        ("MP", "%towernav%odometry", &msgs::ODOMETRY, "::,10:,:,:,,"),
        (
            "MP",
            "%fmu%in%aux_global_position",
            &msgs::AUX_GLOBAL_POSITION,
            "2::,10:,:,:,,",
        ),
        (
            "MS",
            "%fmu%out%vehicle_attitude",
            &msgs::VEHICLE_ATTITUDE,
            "2::,10:,:,:,,",
        ),
    ] {
        let tail = format!(
            "/{kind}/%/%/towernav_edge/{topic}/{}/{}/{qos}",
            t.dds_name(),
            t.type_hash()
        );
        assert!(
            alive
                .iter()
                .any(|k| k.starts_with(&format!("@ros2_lv/0/{zid}/0/")) && k.ends_with(&tail)),
            "no token ending {tail} in {alive:?}"
        );
    }
    let tokens = array(&heard["tokens"]);
    let deleted = tokens
        .iter()
        .filter(|t| t[1].as_str().is_some_and(|k| k.contains("DELETE")))
        .count();
    assert!(
        deleted >= 6,
        "every token is withdrawn when the edge stops: {tokens:?}"
    );

    // Attachments: consecutive sequence numbers per publisher, the send time, a GID each.
    let now_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)?
        .as_nanos() as i64;
    let mut gids = std::collections::HashSet::new();
    for t in [
        "sensor_msgs/msg/NavSatFix",
        "nav_msgs/msg/Odometry",
        "px4_msgs/msg/AuxGlobalPosition",
    ] {
        let samples = array(&topics[t]);
        assert!(samples.len() >= 40, "{t}: {} samples", samples.len());
        // The first sample or two may go out before the router has the route.
        let first = samples[0]["attachment"]["sequence"]
            .as_i64()
            .unwrap_or_default();
        assert!((1..=3).contains(&first), "{t}: first sequence {first}");
        for (i, s) in samples.iter().enumerate() {
            let a = &s["attachment"];
            assert_eq!(
                a["sequence"].as_i64(),
                Some(first + i as i64),
                "{t}: none lost or reordered"
            );
            assert_eq!(a["gid_len"].as_i64(), Some(16));
            let sent = a["unix_ns"].as_i64().unwrap_or_default();
            assert!(
                (now_ns - sent).abs() < 60_000_000_000,
                "{t}: sent at {sent}"
            );
        }
        let gid = samples[0]["attachment"]["gid"]
            .as_str()
            .unwrap_or_default()
            .to_owned();
        assert!(
            samples
                .iter()
                .all(|s| s["attachment"]["gid"] == gid.as_str())
        );
        gids.insert(gid);
    }
    assert_eq!(gids.len(), 3, "a GID per publisher");

    // The payloads, decoded by rosbags (XCDR1) and pycdr2 (PX4's XCDR2).
    let fixes = array(&topics["sensor_msgs/msg/NavSatFix"]);
    let agps = array(&topics["px4_msgs/msg/AuxGlobalPosition"]);
    let poses = array(&topics["geometry_msgs/msg/PoseWithCovarianceStamped"]);
    let odometry = array(&topics["nav_msgs/msg/Odometry"]);
    let datum = towernav_sim::Scenario::paper(11).world.datum;
    let mut fresh_pairs = 0;
    // Both go out on every tick: the same sequence number is the same tick.
    let sequence = |s: &Value| s["attachment"]["sequence"].as_i64();
    let pairs = fixes.iter().filter_map(|f| {
        agps.iter()
            .find(|a| sequence(a) == sequence(f))
            .map(|a| (f, a))
    });
    for (fix, agp) in pairs {
        assert_eq!(fix["header"], "00010000");
        assert_eq!(agp["header"], "00070000", "PX4's payload is XCDR2");
        let (f, a) = (&fix["msg"], &agp["msg"]);
        assert_eq!(f["header"]["frame_id"], "base_link");
        assert_eq!((a["id"].as_u64(), a["source"].as_u64()), (Some(1), Some(2)));
        let sample_us = a["timestamp_sample"].as_u64().unwrap_or_default();
        assert!(
            (PX4_CLOCK_US..PX4_CLOCK_US + 30_000_000).contains(&sample_us),
            "stamped on PX4's clock: {sample_us}"
        );
        if f["status"]["status"].as_i64() != Some(0) {
            assert!(
                f["latitude"].is_null() && a["lat"].is_null(),
                "no fix: NaN everywhere"
            );
            continue;
        }
        assert_eq!(f["position_covariance_type"].as_u64(), Some(3));
        let cov: Vec<f64> = array(&f["position_covariance"])
            .iter()
            .filter_map(Value::as_f64)
            .collect();
        assert!(cov[0] > 0.0 && cov[4] > 0.0 && cov[8] > 0.0 && (cov[1] - cov[3]).abs() < 1e-12);
        let (lat, lon) = (
            f["latitude"].as_f64().unwrap_or_default(),
            f["longitude"].as_f64().unwrap_or_default(),
        );
        let enu = datum.to_enu(&towernav_geometry::Geodetic::new(lat, lon, 0.0)?);
        assert!(
            enu.x.abs() < 2000.0 && enu.y.abs() < 2000.0,
            "near the field: {enu}"
        );
        if let Some(alat) = a["lat"].as_f64() {
            fresh_pairs += 1;
            assert!(
                (alat - lat).abs() < 1e-9
                    && (a["lon"].as_f64().unwrap_or_default() - lon).abs() < 1e-9
            );
            let eph = a["eph"].as_f64().unwrap_or_default();
            assert!(
                eph > 0.0 && eph * eph >= cov[0].max(cov[4]) - 1e-6,
                "eph {eph} vs {cov:?}"
            );
        }
    }
    assert!(fresh_pairs >= 20, "{fresh_pairs} fresh fixes to PX4");
    assert!(!poses.is_empty() && poses.len() == odometry.len());
    for (p, o) in poses.iter().zip(odometry) {
        let (p, o) = (&p["msg"], &o["msg"]);
        assert_eq!(
            (
                p["header"]["frame_id"].as_str(),
                o["child_frame_id"].as_str()
            ),
            (Some("map"), Some("base_link"))
        );
        assert_eq!(p["pose"], o["pose"]);
        let q = &p["pose"]["pose"]["orientation"];
        let norm: f64 = ["x", "y", "z", "w"]
            .iter()
            .map(|k| q[k].as_f64().unwrap_or_default().powi(2))
            .sum();
        assert!((norm - 1.0).abs() < 1e-9);
        assert_eq!(array(&p["pose"]["covariance"]).len(), 36);
    }
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn px4_s_vehicle_attitude_is_an_attitude_source_and_a_clock() -> anyhow::Result<()> {
    let Some(pythonpath) = python() else {
        eprintln!("skipped: no eclipse-zenoh, rosbags or pycdr2 (cargo xtask test installs them)");
        return Ok(());
    };
    let (onboard, _router) = onboard_router().await?;
    let dir = tempfile::tempdir()?;
    let out = dir.path().join("heard.json");
    let child = listener(&pythonpath, &onboard, 6.0, &out);
    let mut config = edge_config(&onboard, 1);
    (config.ros2.enabled, config.px4.enabled) = (false, false);
    config.attitude.kind = AttitudeKind::Px4;
    let (mut bus, attitude) = towernav_edge::daemon::ros2_out::OnboardBus::open(&config)
        .await?
        .ok_or_else(|| anyhow::anyhow!("attitude.kind = px4 opens the onboard Zenoh"))?;
    let clock = tokio::time::timeout(Duration::from_secs(8), async {
        bus.px4_times().recv().await
    })
    .await?
    .ok_or_else(|| anyhow::anyhow!("no PX4 time"))?;
    assert!(
        (PX4_CLOCK_US..PX4_CLOCK_US + 10_000_000).contains(&clock),
        "{clock}"
    );
    let a = attitude
        .latest(Duration::from_secs(1))
        .ok_or_else(|| anyhow::anyhow!("no attitude"))?;
    // The listener flies level, heading east.
    assert!(
        (a.yaw_from_north().to_degrees() - 90.0).abs() < 0.01,
        "{a:?}"
    );
    assert!(a.roll.abs() < 1e-6 && a.pitch.abs() < 1e-6);
    drop(bus);
    finish(child, &out)?;
    Ok(())
}

/// PX4's payloads written as classic CDR (`[px4] cdr = "xcdr1"`; rosbags
/// reads no XCDR2, and v1.17's VehicleGlobalPosition is laid out the same in
/// both), decoded by rosbags with `px4_msgs` registered from their `.msg` text.
#[test]
fn px4_payloads_decode_in_rosbags_as_px4_msgs_defines_them() -> anyhow::Result<()> {
    use msgs::{Px4AuxMessage, Px4GlobalPosition};
    use towernav_protocol::ros2::cdr::CdrVersion;
    let Some(pythonpath) = towernav_tests::python_module("rosbags") else {
        eprintln!("skipped: no rosbags (cargo xtask test installs it)");
        return Ok(());
    };
    let fix = Px4GlobalPosition {
        timestamp_us: 5_000_123_456,
        timestamp_sample_us: 5_000_100_000,
        id: 7,
        lat_deg: 30.512_345_678,
        lon_deg: 114.356_789_012,
        alt_amsl_m: 48.25,
        alt_ellipsoid_m: 36.5,
        eph_m: 1.75,
        epv_m: 3.5,
        lat_lon_reset_counter: 2,
    };
    let lost = Px4GlobalPosition {
        lat_deg: f64::NAN,
        lon_deg: f64::NAN,
        ..fix.clone()
    };
    let dir = tempfile::tempdir()?;
    let mut args = Vec::new();
    let cases = [
        (
            "agp",
            &fix,
            Px4AuxMessage::AuxGlobalPosition,
            CdrVersion::Xcdr1,
        ),
        (
            "vgp",
            &fix,
            Px4AuxMessage::VehicleGlobalPosition,
            CdrVersion::Xcdr1,
        ),
        (
            "lost",
            &lost,
            Px4AuxMessage::VehicleGlobalPosition,
            CdrVersion::Xcdr1,
        ),
    ];
    for (name, m, message, version) in &cases {
        let path = dir.path().join(name);
        std::fs::write(&path, m.to_cdr(*message, *version))?;
        args.push(format!("{}={}", message.msg_type().name, path.display()));
    }
    let out = std::process::Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("python/ros2_decode.py"))
        .arg(fixtures())
        .args(&args)
        .env("PYTHONPATH", &pythonpath)
        .output()?;
    anyhow::ensure!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let decoded: Value = serde_json::from_slice(&out.stdout)?;
    let get = |name: &str| decoded[dir.path().join(name).display().to_string()].clone();
    let agp = get("agp");
    assert_eq!(agp["timestamp"].as_u64(), Some(5_000_123_456));
    assert_eq!(agp["timestamp_sample"].as_u64(), Some(5_000_100_000));
    assert_eq!(
        (agp["id"].as_u64(), agp["source"].as_u64()),
        (Some(7), Some(2))
    );
    assert_eq!(agp["lat"].as_f64(), Some(30.512_345_678));
    assert_eq!(agp["lon"].as_f64(), Some(114.356_789_012));
    assert_eq!(
        (
            agp["alt"].as_f64(),
            agp["eph"].as_f64(),
            agp["epv"].as_f64()
        ),
        (Some(48.25), Some(1.75), Some(3.5))
    );
    assert_eq!(agp["lat_lon_reset_counter"].as_u64(), Some(2));
    let vgp = get("vgp");
    assert_eq!(vgp["lat"].as_f64(), Some(30.512_345_678));
    assert_eq!(
        (vgp["alt"].as_f64(), vgp["alt_ellipsoid"].as_f64()),
        (Some(48.25), Some(36.5))
    );
    assert_eq!(vgp["lat_lon_valid"].as_bool(), Some(true));
    assert_eq!(
        (vgp["eph"].as_f64(), vgp["epv"].as_f64()),
        (Some(1.75), Some(3.5))
    );
    assert_eq!(vgp["lat_lon_reset_counter"].as_u64(), Some(2));
    assert_eq!(vgp["dead_reckoning"].as_bool(), Some(false));
    let lost = get("lost");
    assert!(lost["lat"].is_null() && lost["lon"].is_null());
    assert_eq!(lost["lat_lon_valid"].as_bool(), Some(false));
    Ok(())
}
