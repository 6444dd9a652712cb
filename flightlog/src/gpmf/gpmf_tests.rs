//! The reader on GoPro's own sample videos (`tests/fixtures/gopro/`,
//! Apache-2.0 or MIT, from gpmf-parser's samples), against values GoPro's
//! parser prints for them (its Python binding, `py-gpmf-parser` 0.1.1).

use super::*;

fn fixture(name: &str) -> Telemetry {
    let path = format!(
        "{}/../tests/fixtures/gopro/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let file = std::fs::File::open(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    Telemetry::read(&mut std::io::BufReader::new(file))
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .unwrap_or_else(|| panic!("{name}: no GPMF track"))
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn karma_mavlink_attitude_and_position_read_as_gopro_reads_them() {
    let t = fixture("karma.mp4");
    let attd = t.stream("ATTD").expect("ATTD");
    assert_eq!(attd.device_name, "GoPro Karma v1.0");
    assert_eq!(attd.samples.len(), 47);
    let first = &attd.samples[0].values;
    assert!(
        close(
            &first[..4],
            &[146.065, -0.0773103312, -0.1803593934, -0.4963531494],
            1e-9
        ),
        "{first:?}"
    );
    let glpi = t.stream("GLPI").expect("GLPI");
    assert!(
        close(
            &glpi.samples[46].values[..5],
            &[157.663, 33.1260123, -117.3314792, 16.223, 2.515],
            1e-9
        ),
        "{:?}",
        glpi.samples[46].values
    );
    assert_eq!(t.stream("ACCL").expect("ACCL").samples.len(), 2397);
    assert!(
        (12.0..13.1).contains(&t.duration_s),
        "{}: the video's 12 s",
        t.duration_s
    );
}

#[test]
fn max_gps_gravity_and_orientation_read_as_gopro_reads_them() {
    let t = fixture("max-heromode.mp4");
    let gps = t.stream("GPS5").expect("GPS5");
    assert_eq!(gps.samples.len(), 191);
    assert!(close(
        &gps.samples[0].values,
        &[33.12677, -117.3273436, -22.959, 1.046, 1.0],
        1e-9
    ));
    assert_eq!(
        t.stream("GPSP").expect("GPSP").samples[0].values,
        vec![154.0]
    );
    let grav = t.stream("GRAV").expect("GRAV");
    assert_eq!(grav.samples.len(), 316);
    assert!(close(
        &grav.samples[0].values,
        &[0.0471510971, 0.9900204474, 0.1326944792],
        1e-9
    ));
    let cori = t.stream("CORI").expect("CORI");
    assert!(close(
        &cori.samples[315].values,
        &[0.9829706717, 0.0278023621, -0.1603747673, 0.0850245674],
        1e-9
    ));
}

#[test]
fn samples_share_their_payload_s_span() {
    let t = fixture("max-heromode.mp4");
    let grav = t.stream("GRAV").expect("GRAV");
    // The first payload spans 0 to 1.001 s and holds 30 GRAV samples.
    let in_first: Vec<_> = grav
        .samples
        .iter()
        .take_while(|s| s.time_s < 1.001)
        .collect();
    assert_eq!(in_first.len(), 30);
    assert!((in_first[1].time_s - 1.001 / 30.0).abs() < 1e-9);
    assert!(grav.samples.windows(2).all(|w| w[0].time_s < w[1].time_s));
}

#[test]
fn karma_flies_on_the_vehicle_s_attitude_and_position() {
    let log = flight_log(&fixture("karma.mp4")).expect("a log");
    assert_eq!(log.attitude.len(), 47);
    let a = log.attitude[0].attitude;
    assert!((a.yaw_from_north() - -0.4963531494).abs() < 1e-9, "{a:?}");
    assert_eq!(log.gnss.len(), 47);
    // GLOBAL_POSITION_INT's altitude is above sea level already.
    assert!((log.gnss[0].alt_msl_m - 15.711).abs() < 1e-9);
    assert!((log.barometer[0].altitude_m - 2.003).abs() < 1e-9);
}

#[test]
fn max_flies_on_its_gravity_and_its_course_with_gps_above_sea_level() {
    let log = flight_log(&fixture("max-heromode.mp4")).expect("a log");
    // GPS5 is above the ellipsoid: -23 m there is about 12 m above the sea,
    // next to the Karma's 15.7 m above the sea a few hundred metres away.
    let msl = log.gnss[0].alt_msl_m;
    assert!((5.0..20.0).contains(&msl), "{msl}");
    assert!(!log.attitude.is_empty());
    let a = log.attitude[0].attitude;
    // (0.047, 0.990, 0.133): held upright, looking 7.6 degrees down.
    assert!((a.pitch.to_degrees() - -7.62).abs() < 0.05, "{a:?}");
    assert!((a.roll.to_degrees() - 2.73).abs() < 0.05, "{a:?}");
}

#[test]
fn a_camera_without_gravity_or_karma_is_refused_saying_what_to_give() {
    let mut t = fixture("karma.mp4");
    t.streams.retain(|s| s.device_name == "Camera");
    let err = flight_log(&t).unwrap_err();
    assert!(err.reason.contains("--log"), "{err}");
    assert!(err.reason.contains("ACCL"), "names what it found: {err}");
}

#[test]
fn a_cut_video_is_refused_not_read_short() {
    let path = format!(
        "{}/../tests/fixtures/gopro/karma.mp4",
        env!("CARGO_MANIFEST_DIR")
    );
    let bytes = std::fs::read(path).expect("fixture");
    for keep in [100, bytes.len() / 2, bytes.len() - 10] {
        let cut = &bytes[..keep];
        assert!(
            Telemetry::read(&mut std::io::Cursor::new(cut)).is_err(),
            "cut at {keep} bytes"
        );
    }
}

#[test]
fn a_video_without_gpmf_has_no_telemetry() {
    // ftyp + an empty moov: a valid MP4 with no tracks.
    let mut mp4 = vec![
        0, 0, 0, 16, b'f', b't', b'y', b'p', b'i', b's', b'o', b'm', 0, 0, 0, 0,
    ];
    mp4.extend([0, 0, 0, 8, b'm', b'o', b'o', b'v']);
    assert_eq!(
        Telemetry::read(&mut std::io::Cursor::new(mp4)).unwrap(),
        None
    );
}

#[test]
fn gps9_fixes_without_a_3d_lock_or_with_a_poor_dop_are_dropped() {
    // HERO11 and later: lat, lon, alt, 2D and 3D speed, days, seconds, DOP, fix.
    let fix = |t: f64, dop: f64, lock: f64| Sample {
        time_s: t,
        values: vec![
            33.1 + t * 1e-4,
            -117.3,
            -20.0,
            5.0,
            5.0,
            9000.0,
            100.0 + t,
            dop,
            lock,
        ],
    };
    let t = Telemetry {
        streams: vec![
            Stream {
                device_id: 1,
                device_name: "Camera".into(),
                name: "GPS (Lat., Long., Alt., 2D, 3D, days, secs, DOP, fix)".into(),
                key: "GPS9".into(),
                samples: vec![
                    fix(0.0, 1.2, 3.0),
                    fix(0.1, 7.0, 3.0),
                    fix(0.2, 1.0, 0.0),
                    fix(1.5, 1.1, 2.0),
                ],
            },
            Stream {
                device_id: 1,
                device_name: "Camera".into(),
                name: "Gravity Vector".into(),
                key: "GRAV".into(),
                samples: vec![Sample {
                    time_s: 0.5,
                    values: vec![0.0, 1.0, 0.0],
                }],
            },
        ],
        duration_s: 2.0,
    };
    let log = flight_log(&t).expect("a log");
    let times: Vec<f64> = log.gnss.iter().map(|g| g.time_s).collect();
    assert_eq!(times, vec![0.0, 1.5], "DOP 7 and no lock dropped");
    // Above the ellipsoid in, above the sea out (the geoid is about -35 m there).
    assert!(
        (log.gnss[0].alt_msl_m - 15.0).abs() < 3.0,
        "{}",
        log.gnss[0].alt_msl_m
    );
}
