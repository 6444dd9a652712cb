//! The log readers on a MAVLink telemetry log that pymavlink wrote (the
//! project's own writer is not the judge), and the edge's attitude from a
//! log on the camera's clock.

use towernav_flightlog::FlightLog;

#[test]
fn a_tlog_written_by_pymavlink_reads_the_vehicle_s_attitude_and_fixes() {
    let Some(pythonpath) = towernav_tests::pymavlink() else {
        eprintln!("skipped: no pymavlink (cargo xtask test installs it)");
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("flight.tlog");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/python/write_tlog.py");
    let status = std::process::Command::new("python3")
        .arg(script)
        .arg(&path)
        .env("PYTHONPATH", pythonpath)
        .status()
        .expect("python3 runs");
    assert!(status.success(), "write_tlog.py failed");

    let log = FlightLog::read(&path).expect("reads");
    // System 1's 500 ATTITUDE, none of system 2's.
    assert_eq!(log.attitude.len(), 500);
    let (start, end) = log.span();
    assert!((start - 10.0).abs() < 1e-9 && (end - 19.98).abs() < 1e-9);
    let t = 12.345;
    let a = log.attitude_at(t).expect("inside");
    // Between samples 20 ms apart the slerp is within the curve's sag.
    assert!((a.roll - 0.2 * t.sin()).abs() < 1e-4, "{a:?}");
    assert!((a.pitch - 0.1 * t.cos()).abs() < 1e-4, "{a:?}");
    let heading = a.yaw_from_north();
    assert!(
        (towernav_geometry::wrap_angle(heading - 0.3 * t)).abs() < 1e-4,
        "{heading}"
    );
    // GPS_RAW_INT, placed on the boot clock by its receive time: within
    // the 20 ms it spent on the link.
    assert_eq!(log.gnss.len(), 50);
    for (i, g) in log.gnss.iter().enumerate() {
        let sent = 10.0 + 0.2 * i as f64;
        assert!((g.time_s - sent).abs() <= 0.021, "{i}: {}", g.time_s);
        assert!((g.lat_deg - (47.1 + 1e-7 * 100.0 * i as f64)).abs() < 1e-9);
        assert!((g.alt_msl_m - (512.0 + 0.01 * i as f64)).abs() < 1e-9);
    }

    // ALTITUDE's barometric climb, system 1's only, on the boot clock.
    assert_eq!(log.barometer.len(), 100);
    let climb = log.barometer_at(15.05).expect("inside");
    assert!((climb - (100.0 + 0.01 * 252.5)).abs() < 1e-4, "{climb}");

    // Cut in the middle of a record: refused, naming the file and where.
    let bytes = std::fs::read(&path).expect("read");
    let cut = dir.path().join("cut.tlog");
    std::fs::write(&cut, &bytes[..bytes.len() - 7]).expect("write");
    let err = FlightLog::read(&cut).expect_err("cut").to_string();
    assert!(
        err.contains("cut.tlog") && err.contains("cut short at byte"),
        "{err}"
    );
    // Frames outside the log are refused, saying by how much.
    let err = log.check_covers(9.5, 15.0).expect_err("early").to_string();
    assert!(err.contains("0.500 s before"), "{err}");
    let err = log.check_covers(11.0, 21.0).expect_err("late").to_string();
    assert!(err.contains("1.020 s after"), "{err}");
    log.check_covers(10.0, 19.98).expect("covered");
}
