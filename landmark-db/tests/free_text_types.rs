//! Free-text tower types (a line's own design names) come back from every
//! export format: CSV, GeoJSON and OSM XML (with towernav's mapping and with
//! none). Its own test binary: types are interned per process, and the unit
//! tests' fuzzers fill that table with random names.

use towernav_landmark_db::formats::{parse_geojson, parse_osm_xml};
use towernav_landmark_db::{OsmMapping, export_csv, export_geojson, export_osm_xml, read_csv};
use towernav_protocol::{LandmarkRecord, TowerType};

const TYPES: [&str; 11] = [
    "A",
    "D",
    "Donau 110",
    "lattice",
    "H-frame (wood)",
    "tubular/steel",
    "2x+1",
    "Typ_A.3",
    "110",
    "0.5",
    "N2-45 portal",
];

fn towers() -> Vec<LandmarkRecord> {
    TYPES
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let mut r = LandmarkRecord::new(
                format!("T{i}"),
                TowerType::new(t).expect("a valid type"),
                30.5 + i as f64 * 1e-3,
                114.3,
                20.0,
                30.0 + i as f64,
            );
            r.line_name = Some("North 220".into());
            r
        })
        .collect()
}

#[test]
fn csv_and_geojson_exports_bring_every_type_back() {
    let towers = towers();
    let mut csv = Vec::new();
    export_csv(&towers, &mut csv).expect("csv export");
    assert_eq!(
        read_csv(csv.as_slice(), "export.csv").expect("csv import"),
        towers
    );
    let geojson = export_geojson(&towers).expect("geojson export");
    let back = parse_geojson(&geojson, "export.geojson")
        .and_then(|p| p.all_or_nothing("export.geojson"))
        .expect("geojson import");
    assert_eq!(back, towers);
}

#[test]
fn osm_exports_bring_every_type_back_with_or_without_a_mapping() {
    let towers = towers();
    let xml = export_osm_xml(&towers);
    for mapping in [OsmMapping::towernav(), OsmMapping::default()] {
        let back = parse_osm_xml(&xml, "export.osm", &mapping)
            .and_then(|p| p.all_or_nothing("export.osm"))
            .expect("osm import");
        let types: Vec<String> = back.iter().map(|r| r.tower_type.to_string()).collect();
        assert_eq!(types, TYPES, "{mapping:?}");
    }
}

#[test]
fn an_operators_osm_rule_wins_over_the_written_type() {
    let towers = towers();
    let xml = export_osm_xml(&towers[2..3]);
    let mapping = OsmMapping {
        rules: vec![OsmMapping::parse_rule("power=tower=B").expect("rule")],
        ..OsmMapping::default()
    };
    let back = parse_osm_xml(&xml, "export.osm", &mapping).expect("parse");
    assert_eq!(back.records[0].tower_type, TowerType::B);
}
