//! The reader against values read by hand from real files, three cues of
//! each family (`tests/fixtures/dji-srt/`, MIT, from DJI_SRT_Parser's samples).

use super::*;

fn fixture(name: &str) -> Vec<SrtFrame> {
    let path = format!(
        "{}/../tests/fixtures/dji-srt/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    parse_frames(&text).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn mavic3_bracketed_with_relative_and_absolute_heights() {
    let f = fixture("mavic3.srt");
    assert_eq!(f.len(), 3);
    assert_eq!(
        f.iter().map(|f| f.time_s).collect::<Vec<_>>(),
        vec![0.0, 0.02, 0.04]
    );
    assert!(close(f[0].lat_deg, 3.41531) && close(f[0].lon_deg, -3.37440));
    assert_eq!((f[0].rel_alt_m, f[0].abs_alt_m), (Some(-2.4), Some(0.401)));
    assert_eq!(f[0].focal_len, Some(24.0));
    assert_eq!(f[0].gimbal_ypr_deg, None);
}

#[test]
fn air2s_bracketed_with_one_absolute_altitude() {
    let f = fixture("air2s.srt");
    assert_eq!(f.len(), 3);
    assert!(close(f[1].time_s, 0.033));
    assert!(close(f[0].lat_deg, 41.424724) && close(f[0].lon_deg, 2.234156));
    assert!(close(f[1].lon_deg, 2.234147));
    assert_eq!((f[0].rel_alt_m, f[0].abs_alt_m), (None, Some(117.0)));
    assert_eq!(f[0].focal_len, Some(240.0));
}

#[test]
fn mavic2_style_without_cues_is_timed_by_its_date_lines() {
    let f = fixture("mavic2-style.srt");
    assert_eq!(f.len(), 3);
    let t: Vec<f64> = f.iter().map(|f| f.time_s).collect();
    assert!(
        close(t[0], 0.0) && close(t[1], 1.0) && close(t[2], 2.0),
        "{t:?}"
    );
    // "longtitude", as the file spells it.
    assert!(close(f[0].lat_deg, -20.2533) && close(f[0].lon_deg, 149.0251));
    assert_eq!((f[0].rel_alt_m, f[0].abs_alt_m), (None, None));
}

#[test]
fn mavic_pro_gps_is_longitude_first_and_the_barometer_is_relative() {
    let f = fixture("mavic-pro.srt");
    assert_eq!(f.len(), 3);
    assert_eq!(f[0].time_s, 1.0);
    assert!(close(f[0].lat_deg, -20.2533) && close(f[0].lon_deg, 149.0251));
    // The third number is the satellite count, not a height.
    assert_eq!((f[0].rel_alt_m, f[0].abs_alt_m), (Some(1.9), None));
}

#[test]
fn matrice300_gps_is_latitude_first_with_its_altitude_in_metres() {
    let f = fixture("matrice300.srt");
    assert_eq!(f.len(), 3);
    assert!(close(f[0].lat_deg, 36.6146) && close(f[0].lon_deg, -6.1120));
    // 0.0M is no altitude; the barometer says 0.3, then 0.3, then 0.8 m.
    assert_eq!(f[0].abs_alt_m, None);
    let rel: Vec<Option<f64>> = f.iter().map(|f| f.rel_alt_m).collect();
    assert_eq!(rel, vec![Some(0.3), Some(0.3), Some(0.8)]);
}

#[test]
fn p4_rtk_has_the_gimbals_and_the_aircrafts_angles() {
    let f = fixture("p4-rtk.srt");
    assert_eq!(f.len(), 3);
    assert!(close(f[0].lat_deg, -34.237922) && close(f[0].lon_deg, -58.851745));
    assert_eq!(f[0].rel_alt_m, Some(85.8));
    // G.PRY (-24.4°, 0.0°, 110.4°): pitch, roll, yaw; kept as yaw, pitch, roll.
    assert_eq!(f[0].gimbal_ypr_deg, Some([110.4, -24.4, 0.0]));
    assert_eq!(f[2].aircraft_ypr_deg, Some([110.2, 4.6, -20.8]));
}

#[test]
fn a_file_with_gimbal_angles_is_a_flight_log_and_one_without_says_what_it_needs() {
    let bytes = std::fs::read(format!(
        "{}/../tests/fixtures/dji-srt/p4-rtk.srt",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("fixture");
    let log = parse(&bytes).expect("a log");
    assert_eq!(
        (log.attitude.len(), log.gnss.len(), log.barometer.len()),
        (3, 3, 3)
    );
    let a = log.attitude_at(0.0).expect("attitude");
    assert!((a.pitch.to_degrees() + 24.4).abs() < 1e-6, "{a:?}");
    assert!(
        (a.yaw_from_north().to_degrees() - 110.4).abs() < 1e-6,
        "{a:?}"
    );

    let bytes = std::fs::read(format!(
        "{}/../tests/fixtures/dji-srt/mavic3.srt",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("fixture");
    let err = parse(&bytes).expect_err("no attitude");
    assert!(
        err.reason.contains("no gimbal angles") && err.reason.contains("--log"),
        "{err}"
    );
}

#[test]
fn the_newer_bracketed_gimbal_angles_are_read() {
    let text = "1\n00:00:01,500 --> 00:00:01,533\n<font size=\"28\">FrameCnt: 46, DiffTime: 33ms\n\
        2025-03-02 10:00:01.512\n[focal_len: 24.00] [latitude: 47.123456] [longitude: 8.654321] \
        [rel_alt: 35.200 abs_alt: 512.700] [gb_yaw: -12.5 gb_pitch: -30.1 gb_roll: 0.0] </font>\n";
    let f = parse_frames(text).expect("parses");
    assert_eq!(f[0].time_s, 1.5);
    assert_eq!(f[0].gimbal_ypr_deg, Some([-12.5, -30.1, 0.0]));
    assert_eq!((f[0].rel_alt_m, f[0].abs_alt_m), (Some(35.2), Some(512.7)));
}

#[test]
fn a_file_without_positions_and_a_position_out_of_range_are_refused() {
    let err = parse_frames("1\n00:00:00,000 --> 00:00:01,000\nHello\n").expect_err("no position");
    assert!(err.reason.contains("latitude"), "{err}");
    let err = parse_frames("1\n00:00:00,000 --> 00:00:01,000\n[latitude: 95.0] [longitude: 8.0]\n")
        .expect_err("out of range");
    assert!(err.reason.contains("cue 1"), "{err}");
}
