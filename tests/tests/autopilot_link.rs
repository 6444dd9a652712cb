//! MAVLink on loopback UDP: pymavlink, an independent decoder, checks what the
//! edge sends through a flight that loses and regains its towers; ATTITUDE sent
//! by an autopilot is read back in the ENU convention.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::Context;
use mavlink::dialects::common::{ATTITUDE_DATA, MavMessage};
use mavlink::{MavConnection, MavHeader};
use towernav_edge::daemon::attitude::MavlinkAttitude;
use towernav_edge::daemon::config::{DetectorKind, EdgeConfig};
use towernav_edge::edge_cmd::run_edge;

/// A UDP port no other test of this binary is given (binding port 0 and
/// dropping it would let two tests share one).
fn free_udp_port() -> u16 {
    towernav_tests::loopback_port()
}

/// What pymavlink decoded: each message with its header and arrival time.
#[derive(serde::Deserialize)]
struct Heard {
    bad: u64,
    messages: Vec<HeardMessage>,
}

#[derive(serde::Deserialize)]
struct HeardMessage {
    #[serde(rename = "type")]
    kind: String,
    t: f64,
    sys: u8,
    comp: u8,
    seq: u8,
    v2: bool,
    fields: serde_json::Value,
}

impl HeardMessage {
    fn f64(&self, field: &str) -> f64 {
        self.fields[field].as_f64().unwrap_or(f64::NAN)
    }
}

impl Heard {
    fn of(&self, kind: &str) -> Vec<&HeardMessage> {
        self.messages.iter().filter(|m| m.kind == kind).collect()
    }
}

/// tests/python/mavlink_listen.py on `port`, answering as an autopilot would.
struct Listener {
    child: std::process::Child,
    errors: std::thread::JoinHandle<String>,
}

impl Listener {
    fn start(port: u16, pythonpath: &std::ffi::OsStr) -> anyhow::Result<Self> {
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/python/mavlink_listen.py");
        let mut child = std::process::Command::new("python3")
            .arg(script)
            .args([&port.to_string(), "120", "reply"])
            .env("PYTHONPATH", pythonpath)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()?;
        // Its first line says it is bound; the rest is drained so it never blocks.
        let stderr = child.stderr.take().expect("piped");
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let errors = std::thread::spawn(move || {
            let mut lines = std::io::BufRead::lines(std::io::BufReader::new(stderr));
            let _ = ready_tx.send(lines.next().and_then(Result::ok).unwrap_or_default());
            lines.map_while(Result::ok).collect::<Vec<_>>().join("\n")
        });
        let ready = ready_rx.recv_timeout(Duration::from_secs(30))?;
        anyhow::ensure!(ready.contains("listening"), "listener: {ready}");
        Ok(Self { child, errors })
    }

    /// Closes its stdin, which ends it, and reads what it heard.
    fn finish(mut self) -> anyhow::Result<Heard> {
        drop(self.child.stdin.take());
        let out = self.child.wait_with_output()?;
        let errors = self.errors.join().unwrap_or_default();
        anyhow::ensure!(out.status.success(), "listener: {:?}: {errors}", out.status);
        Ok(serde_json::from_slice(&out.stdout)?)
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Every frame decoded, MAVLink 2, our ids, no sequence gap on loopback.
fn check_framing(heard: &Heard, sent: u64) {
    assert_eq!(heard.bad, 0, "frames pymavlink could not decode");
    assert!(heard.messages.len() as u64 >= sent * 9 / 10);
    assert!(
        heard
            .messages
            .iter()
            .all(|m| m.v2 && m.sys == 1 && m.comp == 197)
    );
    let gaps = heard
        .messages
        .windows(2)
        .filter(|w| w[1].seq != w[0].seq.wrapping_add(1))
        .count();
    assert_eq!(gaps, 0, "sequence gaps");
}

/// GPS_INPUT at its rate throughout, the fix 3-D, then lost, then 3-D again;
/// the seconds it was lost. The loss is the longest stretch without a fix
/// between two 3-D fixes: an uncertain fix held back also drops it, briefly.
fn check_fix_sequence(gps: &[&HeardMessage], wall_s: f64) -> f64 {
    assert!(
        gps.len() as f64 >= 4.0 * wall_s,
        "{} GPS_INPUT in {wall_s:.1} s",
        gps.len()
    );
    let fix: Vec<u8> = gps.iter().map(|g| g.f64("fix_type") as u8).collect();
    let first_3d = fix.iter().position(|&f| f == 3).expect("a 3-D fix");
    let mut stretches = Vec::new();
    let mut from = first_3d;
    while let Some(lost) = fix[from..].iter().position(|&f| f <= 1).map(|i| from + i) {
        let Some(back) = fix[lost..].iter().position(|&f| f == 3).map(|i| lost + i) else {
            break;
        };
        stretches.push((lost, back));
        from = back;
    }
    let (lost, back) = stretches
        .into_iter()
        .max_by(|a, b| (gps[a.1].t - gps[a.0].t).total_cmp(&(gps[b.1].t - gps[b.0].t)))
        .expect("lost, and regained");
    let lost_s = gps[back].t - gps[lost].t;
    assert!(lost_s > 2.0, "lost for {lost_s:.1} s");
    let lost_rate = (back - lost) as f64 / lost_s;
    assert!(lost_rate > 4.0, "NO_FIX at {lost_rate:.1} Hz while lost");
    assert!(
        gps[lost..back]
            .iter()
            .all(|g| g.f64("satellites_visible") == 0.0),
        "no satellites claimed while lost"
    );
    lost_s
}

/// GPS_INPUT's altitude is the poses' ellipsoidal height less EGM96; its
/// accuracy is the poses' covariance, not a constant. (altitude, pose
/// altitude, geoid, median accuracy, median sigma)
fn check_altitude_and_accuracy(
    fixed: &[&HeardMessage],
    poses: &[serde_json::Value],
) -> (f64, f64, f64, f64, f64) {
    let pose_alt = median(poses.iter().filter_map(|p| p["alt_m"].as_f64()).collect());
    let gps_alt = median(fixed.iter().map(|g| g.f64("alt")).collect());
    let (lat, lon) = (fixed[0].f64("lat") / 1e7, fixed[0].f64("lon") / 1e7);
    let geoid = towernav_geometry::geoid_height_m(lat, lon);
    assert!(
        geoid.abs() > 5.0,
        "a test that can tell: geoid {geoid:.1} m"
    );
    assert!(
        (gps_alt - (pose_alt - geoid)).abs() < 1.5,
        "GPS_INPUT alt {gps_alt:.1} m, poses {pose_alt:.1} m ellipsoidal, geoid {geoid:.1} m"
    );
    let sigmas: Vec<f64> = poses
        .iter()
        .filter_map(|p| {
            let c = &p["covariance"];
            Some((c[0][0].as_f64()? + c[1][1].as_f64()?).sqrt())
        })
        .collect();
    let smallest = sigmas.iter().copied().fold(f64::INFINITY, f64::min);
    let accuracy: Vec<f64> = fixed.iter().map(|g| g.f64("horiz_accuracy")).collect();
    assert!(
        accuracy.iter().all(|&a| a >= smallest * 0.999),
        "below any pose's sigma"
    );
    let (accuracy, sigma) = (median(accuracy), median(sigmas));
    assert!(
        (accuracy - sigma).abs() < 0.5 * sigma,
        "median accuracy {accuracy:.2} m, median sigma {sigma:.2} m"
    );
    (gps_alt, pose_alt, geoid, accuracy, sigma)
}

fn leave_and_return(port: u16, jsonl: std::path::PathBuf) -> EdgeConfig {
    let mut config = EdgeConfig {
        fleet: "mav".into(),
        ..EdgeConfig::default()
    };
    config.zenoh.listen = vec![towernav_tests::loopback_endpoint()];
    config.detector.kind = DetectorKind::Oracle;
    config.source.fps = 10.0;
    // Paced, as an autopilot link is, slowly enough to leave room for other work.
    config.source.speed = Some(3.0);
    config.source.flight = Some(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/fixtures/leave-and-return.toml"
        )
        .into(),
    );
    config.output.autopilot_log = Some(jsonl.with_file_name("autopilot.jsonl"));
    config.output.jsonl = Some(jsonl);
    config.mavlink.enabled = true;
    config.mavlink.address = format!("udpout:127.0.0.1:{port}");
    // This flight judges the link, not the report bound: on a busy machine
    // the return's first fixes (far towers, few frames) stay over 5 m long
    // enough to outlast the flight, so every estimate within 50 m is sent.
    config.pipeline.max_report_sigma_m = 50.0;
    config
}

/// A flight that leaves the paper's towers until the pose is lost and comes
/// back, with MAVLink on; pymavlink, listening as the autopilot would, checks
/// what the edge sends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pymavlink_decodes_an_honest_link_through_a_flight_that_leaves_the_towers()
-> anyhow::Result<()> {
    let Some(pythonpath) = towernav_tests::pymavlink() else {
        eprintln!("skipped: pymavlink is not installed (cargo xtask test installs it)");
        return Ok(());
    };
    let port = free_udp_port();
    let listener = Listener::start(port, &pythonpath)?;
    let dir = tempfile::tempdir()?;
    let config = leave_and_return(port, dir.path().join("poses.jsonl"));
    let started = Instant::now();
    let summary = run_edge(&config, None, Arc::new(AtomicBool::new(false))).await?;
    let wall_s = started.elapsed().as_secs_f64();
    let heard = listener.finish()?;
    check_framing(&heard, summary.mavlink_sent);

    // HEARTBEAT at 1 Hz: an onboard controller, not an autopilot.
    let beats = heard.of("HEARTBEAT");
    assert!(
        (beats.len() as f64 - wall_s).abs() <= 2.0,
        "{} heartbeats in {wall_s:.1} s",
        beats.len()
    );
    assert!(
        beats
            .iter()
            .all(|b| b.f64("type") == 18.0 && b.f64("autopilot") == 8.0)
    );
    let gps = heard.of("GPS_INPUT");
    let lost_s = check_fix_sequence(&gps, wall_s);
    let texts: Vec<String> = heard
        .of("STATUSTEXT")
        .iter()
        .map(|t| t.fields["text"].as_str().unwrap_or("").to_string())
        .collect();
    assert!(
        texts.iter().any(|t| t.contains("position lost")),
        "{texts:?}"
    );
    assert!(
        texts.iter().filter(|t| t.contains("3D fix")).count() >= 2,
        "{texts:?}"
    );
    let poses: Vec<serde_json::Value> = std::fs::read_to_string(dir.path().join("poses.jsonl"))?
        .lines()
        .map(serde_json::from_str)
        .collect::<Result<_, _>>()?;
    let fixed: Vec<&HeardMessage> = gps
        .iter()
        .copied()
        .filter(|g| g.f64("fix_type") == 3.0)
        .collect();
    let (gps_alt, pose_alt, geoid, accuracy, sigma) = check_altitude_and_accuracy(&fixed, &poses);
    eprintln!(
        "{} messages in {wall_s:.1} s: {} HEARTBEAT, {} GPS_INPUT, lost {lost_s:.1} s; \
         MSL {gps_alt:.2} m vs {pose_alt:.2} - ({geoid:.2}) m; accuracy {accuracy:.2} m vs sigma {sigma:.2} m; {texts:?}",
        heard.messages.len(),
        beats.len(),
        gps.len()
    );
    // The edge answers the autopilot's TIMESYNC requests.
    let syncs = heard.of("TIMESYNC");
    assert!(!syncs.is_empty(), "no TIMESYNC answer");
    assert!(syncs.iter().all(|s| s.f64("tc1") > 0.0));
    // And records the autopilot's GNSS positions, each with its frame.
    let log = std::fs::read_to_string(dir.path().join("autopilot.jsonl"))?;
    let records: Vec<serde_json::Value> = log
        .lines()
        .map(serde_json::from_str)
        .collect::<Result<_, _>>()?;
    assert!(
        records.len() as f64 >= wall_s - 3.0,
        "{} records",
        records.len()
    );
    let last = records.last().expect("a record");
    assert!((last["lat_deg"].as_f64().unwrap_or(0.0) - 30.5205).abs() < 1e-9);
    let n = towernav_geometry::geoid_height_m(30.5205, 114.3601);
    assert!((last["height_m"].as_f64().unwrap_or(0.0) - (50.0 + n)).abs() < 1e-3);
    assert_eq!(last["heading_deg"].as_f64(), Some(90.0));
    assert!(last["frame_seq"].as_u64().is_some(), "{last}");
    Ok(())
}

#[test]
fn attitude_from_the_autopilot_is_read_in_enu() -> anyhow::Result<()> {
    // Another process may take a port between its check and this bind: try the next.
    let (port, input) = (0..5)
        .find_map(|_| {
            let port = free_udp_port();
            MavlinkAttitude::listen(&format!("udpin:127.0.0.1:{port}"))
                .ok()
                .map(|input| (port, input))
        })
        .context("no UDP port to listen on")?;
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
