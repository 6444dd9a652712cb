//! The readers on logs that real autopilots wrote (the sibling
//! `shared/logs/` folder, read in place), against what pymavlink's
//! `DFReader` 2.4.50 and pyulog 1.3.0 read from the same files. Where the
//! folder is absent, each test says so and passes.

use std::path::PathBuf;

use crate::FlightLog;

fn shared_log(name: &str) -> Option<PathBuf> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/logs")
        .join(name);
    if path.is_file() {
        Some(path)
    } else {
        eprintln!("skipped: no {} here", path.display());
        None
    }
}

fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance
}

/// `DFReader_binary(f).recv_match(type=['ATT','GPS'])`: ATT messages at
/// distinct times (`copter_83.bin` logs 743 of its 4721 twice in the same
/// millisecond; the first is kept), the first, middle and last of those
/// (TimeMS s, Roll, Pitch, Yaw deg), fixes with Status >= 3, and the first
/// and last fix's (Lat, Lng, Alt).
#[test]
fn ardupilot_dataflash_logs_read_as_pymavlink_reads_them() {
    type Att = (f64, f64, f64, f64);
    type Fix = (f64, f64, f64);
    type Case = (&'static str, usize, [Att; 3], usize, [Fix; 2]);
    const CASES: [Case; 3] = [
        (
            "ardupilot/copter_loiter_rtl.bin",
            2356,
            [
                (20.664, 0.27, 0.58, 0.58),
                (160.89, 4.71, 3.45, 73.92),
                (278.59, -0.29, -0.46, 56.15),
            ],
            990,
            [
                (42.845769, -2.6885322, 521.31),
                (42.8457736, -2.6884622, 517.81),
            ],
        ),
        (
            "ardupilot/copter_83.bin",
            3978,
            [
                (8.869, 0.3, 0.55, 182.11),
                (88.245, -5.98, 0.86, 10.27),
                (127.627, -0.13, -0.65, 138.66),
            ],
            377,
            [
                (42.8458017, -2.6885744, 521.08),
                (42.8457814, -2.6885222, 520.28),
            ],
        ),
        (
            "ardupilot/plane_329.bin",
            6145,
            [
                (9.739, 0.25, 1.16, 271.81),
                (316.939, 28.12, -6.52, 223.18),
                (624.139, 1.34, -5.52, 280.09),
            ],
            3290,
            [
                (42.8539031, -2.6451317, 510.53),
                (42.8539051, -2.6451872, 513.96),
            ],
        ),
    ];
    for (name, att_count, atts, fix_count, fixes) in CASES {
        let Some(path) = shared_log(name) else {
            continue;
        };
        let log = FlightLog::read(&path).expect(name);
        assert_eq!(log.attitude.len(), att_count, "{name}");
        for (sample, (t, roll, pitch, yaw)) in [0, att_count / 2, att_count - 1]
            .map(|i| log.attitude[i])
            .iter()
            .zip(atts)
        {
            let a = sample.attitude;
            let heading = a.yaw_from_north().to_degrees().rem_euclid(360.0);
            assert!(
                close(sample.time_s, t, 1e-6)
                    && close(a.roll.to_degrees(), roll, 1e-9)
                    && close(a.pitch.to_degrees(), pitch, 1e-9)
                    && close(heading, yaw, 1e-9),
                "{name}: {sample:?} against ({t}, {roll}, {pitch}, {yaw})"
            );
        }
        assert_eq!(log.gnss.len(), fix_count, "{name}");
        for (g, (lat, lon, alt)) in [log.gnss[0], log.gnss[fix_count - 1]].iter().zip(fixes) {
            assert!(
                close(g.lat_deg, lat, 1e-9)
                    && close(g.lon_deg, lon, 1e-9)
                    && close(g.alt_msl_m, alt, 1e-9),
                "{name}: {g:?} against ({lat}, {lon}, {alt})"
            );
        }
        // Fixes sit on the boot clock, inside the attitude's span.
        let (start, end) = log.span();
        assert!(
            log.gnss
                .iter()
                .all(|g| g.time_s >= start - 1.0 && g.time_s <= end + 1.0),
            "{name}"
        );
    }
}

/// pyulog: `vehicle_attitude` (multi_id 0) sample count, first and last
/// timestamp, and the middle sample's quaternion as roll, pitch and
/// heading (degrees, ZYX); `vehicle_gps_position` fixes (fix_type >= 3)
/// and the first one's lat, lon (1e-7 deg) and alt (mm).
#[test]
fn px4_ulogs_read_as_pyulog_reads_them() {
    const CASES: [(&str, usize, [u64; 3], [f64; 3]); 2] = [
        (
            "px4/sample.ulg",
            6461,
            [112574307, 146991907, 181488706],
            [2.6770614221811395, 6.837444299474463, -34.988784524736054],
        ),
        (
            "px4/sample_log_small.ulg",
            1298,
            [20326716, 23655443, 26822868],
            [1.0846526574960869, -0.08512362506412176, 4.831758649099613],
        ),
    ];
    for (name, count, [first, mid, last], [roll, pitch, heading]) in CASES {
        let Some(path) = shared_log(name) else {
            continue;
        };
        let log = FlightLog::read(&path).expect(name);
        assert_eq!(log.attitude.len(), count, "{name}");
        let t = |i: usize| log.attitude[i].time_s;
        assert!(close(t(0), first as f64 / 1e6, 1e-9), "{name}");
        assert!(close(t(count / 2), mid as f64 / 1e6, 1e-9), "{name}");
        assert!(close(t(count - 1), last as f64 / 1e6, 1e-9), "{name}");
        let a = log.attitude[count / 2].attitude;
        // The log's quaternion is f32: agreement to 1e-4 degrees.
        assert!(
            close(a.roll.to_degrees(), roll, 1e-4)
                && close(a.pitch.to_degrees(), pitch, 1e-4)
                && close(a.yaw_from_north().to_degrees(), heading, 1e-4),
            "{name}: {a:?}"
        );
    }
    if let Some(path) = shared_log("px4/sample_log_small.ulg") {
        let log = FlightLog::read(&path).expect("small");
        assert_eq!(log.gnss.len(), 32);
        let g = log.gnss[0];
        assert!(close(g.time_s, 20.471648, 1e-9));
        assert!(close(g.lat_deg, 63.4170622, 1e-9) && close(g.lon_deg, 10.4082151, 1e-9));
        assert!(close(g.alt_msl_m, 66.814, 1e-9));
    }
    if let Some(path) = shared_log("px4/sample.ulg") {
        assert!(
            FlightLog::read(&path).expect("sample").gnss.is_empty(),
            "no global position in it"
        );
    }
}

#[test]
fn cut_and_foreign_logs_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "junk.bin",
            b"hello world".to_vec(),
            "not an ArduPilot .bin log",
        ),
        ("junk.ulg", b"hello world".to_vec(), "not a ULog file"),
        ("junk.tlog", vec![0; 20], "no MAVLink frame"),
        (
            "empty.csv",
            b"time_s,roll_deg,pitch_deg,heading_deg\n".to_vec(),
            "no attitude",
        ),
        ("flight.txt", b"x".to_vec(), "extension"),
    ];
    for (name, bytes, expected) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        let err = FlightLog::read(&path).expect_err(name).to_string();
        assert!(err.contains(name) && err.contains(expected), "{err}");
    }
    // A real log cut in the middle of a message reads up to the cut; cut
    // inside its header, nothing is left to read.
    if let Some(path) = shared_log("px4/sample_log_small.ulg") {
        let bytes = std::fs::read(&path).expect("read");
        let cut = dir.path().join("cut.ulg");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).expect("write");
        match FlightLog::read(&cut) {
            Ok(log) => assert!(log.attitude.len() < 1298),
            Err(e) => assert!(e.to_string().contains("cut.ulg"), "{e}"),
        }
        std::fs::write(&cut, &bytes[..10]).expect("write");
        let err = FlightLog::read(&cut).expect_err("header only").to_string();
        assert!(err.contains("cut.ulg"), "{err}");
    }
    if let Some(path) = shared_log("ardupilot/copter_83.bin") {
        let bytes = std::fs::read(&path).expect("read");
        let cut = dir.path().join("cut.bin");
        std::fs::write(&cut, &bytes[..bytes.len() / 3]).expect("write");
        let log = FlightLog::read(&cut).expect("a cut log reads up to the cut");
        assert!(log.attitude.len() < 3978 && log.attitude.len() > 1000);
    }
}

/// The barometer against pymavlink's `DFReader_binary` 2.4.50 (`BARO`,
/// instance 0, `Alt`, the first reading at each time) and pyulog 1.3.0
/// (`vehicle_air_data` `baro_alt_meter`; `sample.ulg`'s older
/// `sensor_combined` marks every reading invalid, INT32_MAX): the number of
/// readings, and the first, middle and last (time s, altitude m).
#[test]
fn barometers_read_as_pymavlink_and_pyulog_read_them() {
    type Case = (&'static str, usize, [(f64, f64); 3]);
    const CASES: [Case; 5] = [
        (
            "ardupilot/copter_83.bin",
            787,
            [(8.869, -0.0324), (88.265, 0.7602), (127.567, 0.0568)],
        ),
        (
            "ardupilot/copter_loiter_rtl.bin",
            2357,
            [(20.664, 0.0439), (160.789, 2.8740), (278.589, 0.4977)],
        ),
        ("ardupilot/plane_329.bin", 0, [(0.0, 0.0); 3]),
        (
            "px4/sample_log_small.ulg",
            120,
            [
                (20.328449, 86.1502),
                (23.64688, 86.0471),
                (26.813814, 86.1925),
            ],
        ),
        ("px4/sample.ulg", 0, [(0.0, 0.0); 3]),
    ];
    for (name, count, picks) in CASES {
        let Some(path) = shared_log(name) else {
            continue;
        };
        let log = FlightLog::read(&path).expect("reads");
        let baro = &log.barometer;
        assert_eq!(baro.len(), count, "{name}");
        if count == 0 {
            assert_eq!(log.barometer_at(50.0), None, "{name}");
            continue;
        }
        for (i, (t, alt)) in [0, count / 2, count - 1].into_iter().zip(picks) {
            assert!(
                close(baro[i].time_s, t, 1e-3) && close(baro[i].altitude_m, alt, 1e-3),
                "{name} reading {i}: {:?} against {t}, {alt}",
                baro[i]
            );
        }
        let (t, alt) = picks[1];
        let between = log.barometer_at(t).expect("inside");
        assert!(close(between, alt, 1e-3), "{name}: {between}");
    }
}

/// The receivers' velocities, integrated over 5 s, against how far their
/// positions moved in that time: the same to a few percent where the
/// velocity's axes, units and signs are read right (a swapped axis or a
/// course read in the wrong unit misses by the whole distance).
#[test]
fn ground_velocities_agree_with_the_positions_they_move() {
    let cases = [
        "ardupilot/copter_loiter_rtl.bin",
        "ardupilot/copter_83.bin",
        "ardupilot/plane_329.bin",
        "px4/sample_log_small.ulg",
    ];
    for name in cases {
        let Some(path) = shared_log(name) else {
            continue;
        };
        let log = FlightLog::read(&path).expect(name);
        let fixes = &log.gnss;
        let with_velocity = fixes.iter().filter(|g| g.velocity.is_some()).count();
        assert!(
            with_velocity * 10 >= fixes.len() * 9,
            "{name}: {with_velocity} of {}",
            fixes.len()
        );
        let mut misses = Vec::new();
        for i in 0..fixes.len() {
            let Some(j) = (i + 1..fixes.len()).find(|&j| fixes[j].time_s - fixes[i].time_s >= 10.0)
            else {
                break;
            };
            let window = &fixes[i..=j];
            if window
                .windows(2)
                .any(|w| w[1].time_s - w[0].time_s > crate::MAX_GNSS_GAP_S)
            {
                continue;
            }
            let mut flown = [0.0, 0.0];
            for w in window.windows(2) {
                let (Some(a), Some(b)) = (w[0].velocity, w[1].velocity) else {
                    continue;
                };
                let dt = w[1].time_s - w[0].time_s;
                flown[0] += 0.5 * (a.north_mps + b.north_mps) * dt;
                flown[1] += 0.5 * (a.east_mps + b.east_mps) * dt;
            }
            let metres_per_deg = 111_320.0;
            let moved = [
                (fixes[j].lat_deg - fixes[i].lat_deg) * metres_per_deg,
                (fixes[j].lon_deg - fixes[i].lon_deg)
                    * metres_per_deg
                    * fixes[i].lat_deg.to_radians().cos(),
            ];
            // Where it flew: hovering, the position's own wander is all.
            let distance = moved[0].hypot(moved[1]);
            if distance >= 10.0 {
                misses.push((moved[0] - flown[0]).hypot(moved[1] - flown[1]) / distance);
            }
        }
        if misses.len() < 10 {
            eprintln!("{name}: {} windows", misses.len());
            continue;
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let miss = median(&mut misses);
        let worst = misses[misses.len() * 9 / 10];
        eprintln!(
            "{name}: {} windows of 10 s over 10 m, velocities miss by {:.1} % (median), {:.1} % (p90)",
            misses.len(),
            100.0 * miss,
            100.0 * worst
        );
        assert!(
            miss < 0.25 && worst < 0.5,
            "{name}: median miss {:.1} %",
            100.0 * miss
        );
    }
}
