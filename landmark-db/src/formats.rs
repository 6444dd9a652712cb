//! GeoJSON and OpenStreetMap exchange.
//!
//! - GeoJSON: a FeatureCollection of Points `[lon, lat]` or `[lon, lat, ground_elev_m]`;
//!   the CSV column names are the feature properties (the feature's own `id` stands in
//!   for a missing `id` property).
//! - OSM: `power=tower` nodes, from OSM XML or Overpass JSON. `ref` is the id, `height`
//!   may carry units ("35", "35 m", "115 ft"), `ele` is the ground elevation, and
//!   `design`/`structure` map to a tower type through [`OsmMapping`].

use std::collections::BTreeMap;

use geojson::{Feature, FeatureCollection, Geometry, GeometryValue, JsonObject, JsonValue};
use towernav_protocol::{LandmarkRecord, TowerType};

use crate::error::{ImportError, RowProblem};
use crate::fields::{Collector, build_record};
use crate::parsed::Parsed;

pub fn parse_geojson(text: &str, file: &str) -> Result<Parsed, ImportError> {
    let collection: FeatureCollection =
        serde_json::from_str(text).map_err(|e| ImportError::Read {
            file: file.into(),
            reason: format!("not a GeoJSON FeatureCollection: {e}"),
        })?;
    let mut out = Collector::default();
    for (i, feature) in collection.features.iter().enumerate() {
        let at = format!("feature {}", i + 1);
        out.push(&at, feature_record(&at, feature));
    }
    Ok(out.finish())
}

fn feature_record(at: &str, feature: &Feature) -> Result<LandmarkRecord, RowProblem> {
    let props = feature.properties.clone().unwrap_or_default();
    let feature_id = feature.id.as_ref().map(|id| match id {
        geojson::feature::Id::String(s) => s.clone(),
        geojson::feature::Id::Number(n) => n.to_string(),
    });
    let point = match feature.geometry.as_ref().map(|g| &g.value) {
        Some(GeometryValue::Point { coordinates }) if coordinates.len() >= 2 => {
            coordinates.as_slice().to_vec()
        }
        _ => {
            return Err(RowProblem {
                at: at.into(),
                id: text(&props, "id").or(feature_id).unwrap_or_default(),
                field: "geometry".into(),
                reason: "must be a Point [lon, lat] or [lon, lat, elevation]".into(),
            });
        }
    };
    // A type is a name: a number there is most often a design code whose
    // leading zeros or decimals were lost on the way, so it is refused, not guessed.
    if let Some(JsonValue::Number(n)) = props.get("tower_type") {
        return Err(RowProblem {
            at: at.into(),
            id: text(&props, "id").or(feature_id).unwrap_or_default(),
            field: "tower_type".into(),
            reason: format!("is the number {n}; a tower type is text: write it as \"{n}\""),
        });
    }
    let get = |name: &str| -> Option<String> {
        match name {
            "lon_deg" => Some(point[0].to_string()),
            "lat_deg" => Some(point[1].to_string()),
            "ground_elev_m" => text(&props, name).or_else(|| point.get(2).map(f64::to_string)),
            "id" => text(&props, name).or_else(|| feature_id.clone()),
            _ => text(&props, name),
        }
    };
    build_record(at, &get)
}

fn text(props: &JsonObject, name: &str) -> Option<String> {
    match props.get(name)? {
        JsonValue::String(s) if !s.trim().is_empty() => Some(s.trim().to_owned()),
        JsonValue::Number(n) => Some(n.to_string()),
        _ => None,
    }
}

pub fn export_geojson(records: &[LandmarkRecord]) -> Result<String, serde_json::Error> {
    let features = records
        .iter()
        .map(|r| {
            let mut properties = match serde_json::to_value(r)? {
                JsonValue::Object(map) => map,
                _ => JsonObject::new(),
            };
            properties.remove("lat_deg");
            properties.remove("lon_deg");
            properties.retain(|_, v| !v.is_null());
            Ok(Feature {
                bbox: None,
                geometry: Some(Geometry::new(GeometryValue::Point {
                    coordinates: vec![r.lon_deg, r.lat_deg, r.ground_elev_m].into(),
                })),
                id: Some(geojson::feature::Id::String(r.id.clone())),
                properties: Some(properties),
                foreign_members: None,
            })
        })
        .collect::<Result<Vec<_>, serde_json::Error>>()?;
    serde_json::to_string_pretty(&FeatureCollection {
        bbox: None,
        features,
        foreign_members: None,
    })
}

/// OSM XML of the towers (`power=tower` nodes, new objects with negative ids as
/// JOSM expects), with `ref`, `height`, `ele` and the type in [`OSM_TYPE_TAG`].
pub fn export_osm_xml(records: &[LandmarkRecord]) -> String {
    // Tabs and line breaks as character references: literal ones in an
    // attribute are read back as spaces. Validation keeps other control
    // characters out of the database, as XML 1.0 cannot hold them.
    fn esc(s: &str) -> String {
        s.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
            .replace('\t', "&#9;")
            .replace('\n', "&#10;")
            .replace('\r', "&#13;")
    }
    let mut out = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osm version=\"0.6\" generator=\"towernav\">\n",
    );
    for (i, r) in records.iter().enumerate() {
        out += &format!(
            "  <node id=\"-{}\" lat=\"{}\" lon=\"{}\">\n",
            i + 1,
            r.lat_deg,
            r.lon_deg
        );
        let mut tags = vec![
            ("power", "tower".to_owned()),
            ("ref", r.id.clone()),
            (OSM_TYPE_TAG, r.tower_type.to_string()),
            ("height", format!("{}", r.height_m)),
            ("ele", format!("{}", r.ground_elev_m)),
        ];
        if let Some(line) = &r.line_name {
            tags.push(("line_name", line.clone()));
        }
        if let Some(source) = &r.survey_source {
            tags.push(("source", source.clone()));
        }
        for (k, v) in tags {
            out += &format!("    <tag k=\"{}\" v=\"{}\"/>\n", esc(k), esc(&v));
        }
        out += "  </node>\n";
    }
    out += "</osm>\n";
    out
}

/// How OSM tags choose a tower type: the first rule whose tag matches wins, else `default`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OsmMapping {
    /// (tag key, tag value, type), e.g. ("design", "donau", A).
    pub rules: Vec<(String, String, TowerType)>,
    pub default: Option<TowerType>,
    /// Ground elevation for nodes without an `ele` tag, metres above the WGS84 ellipsoid.
    pub default_ground_elev_m: Option<f64>,
}

/// The tag `export_osm_xml` writes the tower type in; `OsmMapping::towernav` reads it back.
pub const OSM_TYPE_TAG: &str = "towernav:type";

impl OsmMapping {
    /// Reads the types towernav wrote (`towernav:type=A` ...), as in its own OSM exports.
    pub fn towernav() -> Self {
        Self {
            rules: TowerType::ALL
                .iter()
                .map(|t| (OSM_TYPE_TAG.to_owned(), t.to_string(), *t))
                .collect(),
            default: None,
            default_ground_elev_m: None,
        }
    }

    /// Parses a rule written `key=value=TYPE`, e.g. `design=donau=A`.
    pub fn parse_rule(s: &str) -> Result<(String, String, TowerType), String> {
        let parts: Vec<&str> = s.splitn(3, '=').collect();
        let [key, value, t] = parts.as_slice() else {
            return Err(format!("{s:?} is not key=value=TYPE (e.g. design=donau=A)"));
        };
        Ok((
            (*key).into(),
            (*value).into(),
            t.parse()
                .map_err(|e: towernav_protocol::TowerTypeError| e.to_string())?,
        ))
    }
}

struct OsmNode {
    id: i64,
    lat: f64,
    lon: f64,
    tags: BTreeMap<String, String>,
}

pub fn parse_osm_xml(text: &str, file: &str, mapping: &OsmMapping) -> Result<Parsed, ImportError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| ImportError::Read {
        file: file.into(),
        reason: format!("not OSM XML: {e}"),
    })?;
    let mut nodes = Vec::new();
    for n in doc.descendants().filter(|n| n.has_tag_name("node")) {
        let attr = |name: &str| n.attribute(name).and_then(|v| v.parse::<f64>().ok());
        let (Some(id), Some(lat), Some(lon)) = (attr("id"), attr("lat"), attr("lon")) else {
            return Err(ImportError::Read {
                file: file.into(),
                reason: format!(
                    "node at byte {} lacks a numeric id, lat or lon",
                    n.range().start
                ),
            });
        };
        let tags = n
            .children()
            .filter(|c| c.has_tag_name("tag"))
            .filter_map(|c| Some((c.attribute("k")?.to_owned(), c.attribute("v")?.to_owned())))
            .collect();
        nodes.push(OsmNode {
            id: id as i64,
            lat,
            lon,
            tags,
        });
    }
    Ok(osm_records(nodes, mapping))
}

pub fn parse_overpass_json(
    text: &str,
    file: &str,
    mapping: &OsmMapping,
) -> Result<Parsed, ImportError> {
    #[derive(serde::Deserialize)]
    struct Response {
        elements: Vec<Element>,
    }
    #[derive(serde::Deserialize)]
    struct Element {
        #[serde(rename = "type")]
        kind: String,
        id: i64,
        lat: Option<f64>,
        lon: Option<f64>,
        #[serde(default)]
        tags: BTreeMap<String, String>,
    }
    let response: Response = serde_json::from_str(text).map_err(|e| ImportError::Read {
        file: file.into(),
        reason: format!("not Overpass JSON: {e}"),
    })?;
    let mut nodes = Vec::new();
    for e in response.elements.into_iter().filter(|e| e.kind == "node") {
        let (Some(lat), Some(lon)) = (e.lat, e.lon) else {
            return Err(ImportError::Read {
                file: file.into(),
                reason: format!("node {} has no lat/lon", e.id),
            });
        };
        nodes.push(OsmNode {
            id: e.id,
            lat,
            lon,
            tags: e.tags,
        });
    }
    Ok(osm_records(nodes, mapping))
}

fn osm_records(nodes: Vec<OsmNode>, mapping: &OsmMapping) -> Parsed {
    let mut out = Collector::default();
    for node in nodes
        .iter()
        .filter(|n| n.tags.get("power").is_some_and(|p| p == "tower"))
    {
        let at = format!("node {}", node.id);
        let tag = |k: &str| {
            node.tags
                .get(k)
                .map(|v| v.trim().to_owned())
                .filter(|v| !v.is_empty())
        };
        let problem = |field: &str, reason: String| RowProblem {
            at: at.clone(),
            id: tag("ref").unwrap_or_default(),
            field: field.into(),
            reason,
        };
        let result = (|| {
            let id = tag("ref").ok_or_else(|| {
                problem(
                    "ref",
                    "is missing: towernav needs the tower's number as its id".into(),
                )
            })?;
            // The operator's rules first; then the type towernav's own export
            // wrote, whatever its name; then the default.
            let written = tag(OSM_TYPE_TAG)
                .map(|t| TowerType::new(&t).map_err(|e| problem(OSM_TYPE_TAG, e.to_string())))
                .transpose()?;
            let tower_type = mapping
                .rules
                .iter()
                .find(|(k, v, _)| node.tags.get(k) == Some(v))
                .map(|r| r.2)
                .or(written)
                .or(mapping.default)
                .ok_or_else(|| {
                    problem(
                        "tower_type",
                        format!(
                            "no mapping for design={:?} structure={:?} (add --osm-map key=value=TYPE)",
                            tag("design").unwrap_or_default(),
                            tag("structure").unwrap_or_default()
                        ),
                    )
                })?;
            let height = tag("height")
                .ok_or_else(|| problem("height", "is missing".into()))
                .and_then(|h| parse_height(&h).map_err(|e| problem("height", e)))?;
            let elev = match tag("ele") {
                Some(e) => parse_height(&e).map_err(|e| problem("ele", e))?,
                None => mapping.default_ground_elev_m.ok_or_else(|| {
                    problem(
                        "ele",
                        "is missing and no default ground elevation was given".into(),
                    )
                })?,
            };
            let fields = BTreeMap::from([
                ("id", id),
                ("tower_type", tower_type.to_string()),
                ("lat_deg", node.lat.to_string()),
                ("lon_deg", node.lon.to_string()),
                ("ground_elev_m", elev.to_string()),
                ("height_m", height.to_string()),
                (
                    "line_name",
                    tag("line_name")
                        .or_else(|| tag("operator"))
                        .unwrap_or_default(),
                ),
                // A `source` tag (towernav's exports write one) else the node itself.
                (
                    "survey_source",
                    tag("source").unwrap_or_else(|| format!("OSM node {}", node.id)),
                ),
            ]);
            build_record(&at, &|name| {
                fields.get(name).filter(|v| !v.is_empty()).cloned()
            })
        })();
        out.push(&at, result);
    }
    out.finish()
}

/// OSM lengths: "35", "35 m", "35m", "115 ft", "115'".
pub fn parse_height(s: &str) -> Result<f64, String> {
    let t = s.trim();
    let (number, factor) = if let Some(n) = t.strip_suffix("ft").or_else(|| t.strip_suffix('\'')) {
        (n, 0.3048)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    number
        .trim()
        .parse::<f64>()
        .map(|v| v * factor)
        .map_err(|_| format!("{s:?} is not a length (e.g. 35, 35 m, 115 ft)"))
}

#[cfg(test)]
mod osm_export_tests {
    use super::*;

    #[test]
    fn an_osm_export_imports_back_to_the_same_towers() {
        let mut a = LandmarkRecord::new("L1-07", TowerType::C, 30.5205, 114.3601, 23.5, 41.0);
        a.line_name = Some("220kV <Xinjin> & II".into());
        let b = LandmarkRecord::new("L1-08", TowerType::A, 30.5215, 114.3611, 24.0, 33.0);
        let xml = export_osm_xml(&[a.clone(), b.clone()]);
        let parsed = parse_osm_xml(&xml, "export.osm", &OsmMapping::towernav()).expect("parse");
        assert!(parsed.problems.is_empty(), "{:?}", parsed.problems);
        let back = &parsed.records;
        assert_eq!(back.len(), 2);
        for (got, want) in back.iter().zip([&a, &b]) {
            assert_eq!(
                (got.id.as_str(), got.tower_type),
                (want.id.as_str(), want.tower_type)
            );
            assert!((got.lat_deg - want.lat_deg).abs() < 1e-9);
            assert!((got.height_m - want.height_m).abs() < 1e-9);
            assert!((got.ground_elev_m - want.ground_elev_m).abs() < 1e-9);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn mapping() -> OsmMapping {
        OsmMapping {
            rules: vec![OsmMapping::parse_rule("design=donau=A").expect("rule")],
            default: None,
            default_ground_elev_m: Some(20.0),
        }
    }

    #[test]
    fn geojson_round_trip_loses_nothing() {
        let records = vec![
            LandmarkRecord {
                base_width_m: Some(7.5),
                line_name: Some("North".into()),
                sigma_vertical_m: Some(0.2),
                notes: "checked".into(),
                ..LandmarkRecord::new("B3", TowerType::B, 30.5, 114.3, 21.5, 38.0)
            },
            LandmarkRecord::new("C1", TowerType::C, 30.6, 114.2, 19.0, 45.0),
        ];
        let text = export_geojson(&records).expect("export");
        let back = parse_geojson(&text, "x.geojson")
            .expect("parse")
            .all_or_nothing("x.geojson")
            .expect("valid");
        assert_eq!(back, records);
    }

    #[test]
    fn geojson_problems_name_the_feature_and_field() {
        let text = r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","id":"A1","geometry":{"type":"Point","coordinates":[114.3,30.5]},"properties":{"tower_type":"A","ground_elev_m":20,"height_m":32}},
            {"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,0],[1,1]]},"properties":{"id":"L1"}},
            {"type":"Feature","geometry":{"type":"Point","coordinates":[114.3,30.6]},"properties":{"id":"A2","tower_type":"A","ground_elev_m":20}}]}"#;
        let parsed = parse_geojson(text, "x").expect("parse");
        assert_eq!(parsed.records.len(), 1);
        let problems: Vec<_> = parsed
            .problems
            .iter()
            .map(|p| (p.at.as_str(), p.field.as_str()))
            .collect();
        assert_eq!(
            problems,
            [("feature 2", "geometry"), ("feature 3", "height_m")]
        );
    }

    #[test]
    fn a_numeric_geojson_tower_type_is_refused_naming_the_feature() {
        let text = r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","geometry":{"type":"Point","coordinates":[114.3,30.5]},"properties":{"id":"A1","tower_type":"110","ground_elev_m":20,"height_m":32}},
            {"type":"Feature","geometry":{"type":"Point","coordinates":[114.3,30.6]},"properties":{"id":"A2","tower_type":110.0,"ground_elev_m":20,"height_m":32}}]}"#;
        let parsed = parse_geojson(text, "x").expect("parse");
        assert_eq!(parsed.records.len(), 1);
        assert_eq!(parsed.records[0].tower_type.to_string(), "110");
        let p = &parsed.problems[0];
        assert_eq!(
            (p.at.as_str(), p.id.as_str(), p.field.as_str()),
            ("feature 2", "A2", "tower_type")
        );
        assert!(p.reason.contains("text"), "{}", p.reason);
    }

    #[test]
    fn osm_xml_and_overpass_json_give_the_same_towers() {
        let xml = r#"<osm version="0.6">
          <node id="101" lat="30.5" lon="114.3"><tag k="power" v="tower"/><tag k="ref" v="17"/><tag k="design" v="donau"/><tag k="height" v="35 m"/></node>
          <node id="102" lat="30.51" lon="114.3"><tag k="power" v="tower"/><tag k="ref" v="18"/><tag k="design" v="barrel"/><tag k="height" v="115 ft"/></node>
          <node id="103" lat="30.52" lon="114.3"><tag k="power" v="pole"/></node>
          <node id="104" lat="30.53" lon="114.3"><tag k="power" v="tower"/><tag k="design" v="donau"/><tag k="height" v="30"/></node>
        </osm>"#;
        let json = r#"{"elements":[
          {"type":"node","id":101,"lat":30.5,"lon":114.3,"tags":{"power":"tower","ref":"17","design":"donau","height":"35 m"}},
          {"type":"node","id":102,"lat":30.51,"lon":114.3,"tags":{"power":"tower","ref":"18","design":"barrel","height":"115 ft"}},
          {"type":"node","id":103,"lat":30.52,"lon":114.3,"tags":{"power":"pole"}},
          {"type":"node","id":104,"lat":30.53,"lon":114.3,"tags":{"power":"tower","design":"donau","height":"30"}}]}"#;
        let a = parse_osm_xml(xml, "x.osm", &mapping()).expect("xml");
        let b = parse_overpass_json(json, "x.json", &mapping()).expect("json");
        assert_eq!(a, b);
        assert_eq!(a.records.len(), 1);
        assert_eq!(
            (
                a.records[0].id.as_str(),
                a.records[0].height_m,
                a.records[0].tower_type
            ),
            ("17", 35.0, TowerType::A)
        );
        let problems: Vec<_> = a
            .problems
            .iter()
            .map(|p| (p.at.as_str(), p.field.as_str()))
            .collect();
        assert_eq!(problems, [("node 102", "tower_type"), ("node 104", "ref")]);
    }

    #[test]
    fn heights_with_units() {
        assert_eq!(parse_height("35"), Ok(35.0));
        assert_eq!(parse_height("35 m"), Ok(35.0));
        assert!((parse_height("100 ft").expect("ft") - 30.48).abs() < 1e-9);
        assert!(parse_height("tall").is_err());
    }

    proptest! {
        /// Whatever the bytes, every parser returns records, problems or a read error: never a panic.
        #[test]
        fn malformed_files_never_panic(text in ".{0,400}") {
            let _ = parse_geojson(&text, "f");
            let _ = parse_osm_xml(&text, "f", &mapping());
            let _ = parse_overpass_json(&text, "f", &mapping());
            let _ = crate::csv_io::parse_csv(text.as_bytes(), "f");
        }

        /// Damaged CSV rows are reported with where and what, never dropped silently.
        #[test]
        fn every_csv_row_is_a_record_or_a_problem(cells in proptest::collection::vec("[A-D0-9.,x-]{0,8}", 1..30)) {
            let mut text = String::from("id,tower_type,lat_deg,lon_deg,ground_elev_m,height_m\n");
            for (i, c) in cells.iter().enumerate() {
                text.push_str(&format!("T{i},{c},30.5,114.3,20,35\n"));
            }
            let parsed = crate::csv_io::parse_csv(text.as_bytes(), "f").expect("readable");
            prop_assert_eq!(parsed.records.len() + parsed.problems.len(), cells.len());
            for p in &parsed.problems {
                prop_assert!(p.at.starts_with("line ") && !p.field.is_empty() && !p.reason.is_empty());
            }
        }
    }
}
