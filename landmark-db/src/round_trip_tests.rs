//! Every export imports back unchanged: CSV and GeoJSON carry every field,
//! OSM XML the ones it has tags for. Records range over the extremes that
//! validation accepts, tiny heights and line breaks in text included.

use proptest::prelude::*;
use towernav_protocol::{LandmarkRecord, TowerType};

use crate::formats::{OsmMapping, export_geojson, export_osm_xml, parse_geojson, parse_osm_xml};
use crate::{export_csv, read_csv, validate};

fn text() -> impl Strategy<Value = String> {
    // Printable ASCII, a little Unicode, and the control characters XML can carry.
    "[a-zA-Z0-9 ,;\"'<>&=é\t\n\r-]{1,16}"
        .prop_filter("not only blanks", |s| !s.trim().is_empty())
        .prop_map(|s| s.trim().to_string())
}

fn record() -> impl Strategy<Value = LandmarkRecord> {
    (
        "[A-Za-z0-9_.-]{1,32}",
        0..4usize,
        (-90.0..=90.0f64, -180.0..=180.0f64, -500.0..=9000.0f64),
        prop_oneof![0.0001..0.001f64, 0.001..=200.0f64],
        proptest::option::of(prop_oneof![0.0001..0.001f64, 0.001..=50.0f64]),
        proptest::option::of(text()),
        proptest::option::of(text()),
        proptest::option::of(0.0..=100.0f64),
        proptest::option::of(0.0..=100.0f64),
        proptest::option::of(text()),
    )
        .prop_map(
            |(id, t, (lat, lon, elev), height, base, line, source, sh, sv, notes)| LandmarkRecord {
                base_width_m: base,
                line_name: line,
                survey_source: source,
                sigma_horizontal_m: sh,
                sigma_vertical_m: sv,
                notes: notes.unwrap_or_default(),
                ..LandmarkRecord::new(id, TowerType::ALL[t], lat, lon, elev, height)
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn csv_exports_import_back_unchanged(r in record()) {
        prop_assert_eq!(validate(&r), Ok(()));
        let mut out = Vec::new();
        export_csv(std::slice::from_ref(&r), &mut out).expect("export");
        let back = read_csv(out.as_slice(), "export.csv").expect("imports back");
        prop_assert_eq!(back, vec![r]);
    }

    #[test]
    fn geojson_exports_import_back_unchanged(r in record()) {
        let text = export_geojson(std::slice::from_ref(&r)).expect("export");
        let back = parse_geojson(&text, "export.geojson")
            .and_then(|p| p.all_or_nothing("export.geojson"))
            .expect("imports back");
        prop_assert_eq!(back, vec![r]);
    }

    #[test]
    fn osm_exports_import_back_with_every_field_they_carry(r in record()) {
        let text = export_osm_xml(std::slice::from_ref(&r));
        let back = parse_osm_xml(&text, "export.osm", &OsmMapping::towernav())
            .and_then(|p| p.all_or_nothing("export.osm"))
            .expect("imports back");
        prop_assert_eq!(back.len(), 1);
        let b = &back[0];
        prop_assert_eq!(&b.id, &r.id);
        prop_assert_eq!(b.tower_type, r.tower_type);
        prop_assert_eq!((b.lat_deg, b.lon_deg), (r.lat_deg, r.lon_deg));
        prop_assert_eq!((b.ground_elev_m, b.height_m), (r.ground_elev_m, r.height_m));
        prop_assert_eq!(&b.line_name, &r.line_name);
        match &r.survey_source {
            Some(source) => prop_assert_eq!(b.survey_source.as_ref(), Some(source)),
            // Without a source tag the importer names the node it came from.
            None => prop_assert!(b.survey_source.as_deref().is_some_and(|s| s.starts_with("OSM node"))),
        }
    }

    #[test]
    fn control_characters_xml_cannot_hold_are_refused(c in (1u32..32).prop_filter("not tab or breaks", |c| ![9, 10, 13].contains(c))) {
        let mut r = LandmarkRecord::new("A1", TowerType::A, 30.0, 114.0, 20.0, 30.0);
        r.notes = format!("a{}b", char::from_u32(c).expect("ascii"));
        let e = validate(&r).expect_err("refused");
        prop_assert_eq!(e.field, "notes");
    }
}
