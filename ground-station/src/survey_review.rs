//! Towers a survey flight measured (`towernav-edge map-towers`'s
//! `towers-mapped.geojson`), reviewed before they reach the database: each
//! proposal accepted, rejected or taken into the form to edit; the accepted
//! written together, as one import, under the operator's name. Pure: text
//! in, decisions and records out.

use serde_json::Value;
use towernav_protocol::LandmarkRecord;

/// What the survey says a proposal is.
#[derive(Debug, Clone, PartialEq)]
pub enum ProposalStatus {
    /// The known tower `known_id`, measured `offset_m` from its record and
    /// `height_difference_m` taller (negative: shorter).
    Confirmed {
        known_id: String,
        offset_m: f64,
        height_difference_m: Option<f64>,
    },
    /// Not in the landmark file the survey was given.
    New,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    Pending,
    Accept,
    Reject,
    /// Taken into the form: the operator saves it there, edited.
    Edited,
}

/// One measured tower.
#[derive(Debug, Clone, PartialEq)]
pub struct Proposal {
    pub record: LandmarkRecord,
    pub status: ProposalStatus,
    /// One-sigma semi-axes of its ellipse, metres, and the major axis's
    /// bearing, degrees clockwise from north.
    pub sigma_major_m: f64,
    pub sigma_minor_m: f64,
    pub ellipse_bearing_deg: f64,
    pub views: u64,
    pub decision: Decision,
}

impl Proposal {
    /// Its ellipse's covariance in (east, north), m^2.
    pub fn covariance_en(&self) -> [[f64; 2]; 2] {
        let b = self.ellipse_bearing_deg.to_radians();
        // The major axis's unit vector in (east, north).
        let (e, n) = (b.sin(), b.cos());
        let (l1, l2) = (self.sigma_major_m.powi(2), self.sigma_minor_m.powi(2));
        [
            [l1 * e * e + l2 * n * n, (l1 - l2) * e * n],
            [(l1 - l2) * e * n, l1 * n * n + l2 * e * e],
        ]
    }

    pub fn summary(&self) -> String {
        match &self.status {
            ProposalStatus::Confirmed {
                known_id,
                offset_m,
                height_difference_m,
            } => format!(
                "confirms {known_id}: {offset_m:.1} m off, height {}",
                height_difference_m.map_or("not measured".into(), |d| format!("{d:+.1} m"))
            ),
            ProposalStatus::New => "new: not in the database".into(),
        }
    }
}

/// A survey's proposals, and what else it reported (missed and uncertain
/// towers), in the file's order.
#[derive(Debug, Clone, PartialEq)]
pub struct SurveyReview {
    pub file: String,
    pub proposals: Vec<Proposal>,
    /// (id, status, note): towers it lists but does not propose.
    pub others: Vec<(String, String, String)>,
}

fn number(props: &serde_json::Map<String, Value>, key: &str) -> Option<f64> {
    props.get(key).and_then(Value::as_f64)
}

impl SurveyReview {
    /// Reads `map-towers`' GeoJSON; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, String> {
        let json: Value =
            serde_json::from_str(text).map_err(|e| format!("{file}: not JSON: {e}"))?;
        let features = json["features"]
            .as_array()
            .ok_or_else(|| format!("{file}: not a GeoJSON FeatureCollection"))?;
        let mut review = SurveyReview {
            file: file.to_owned(),
            proposals: Vec::new(),
            others: Vec::new(),
        };
        for (i, f) in features.iter().enumerate() {
            let at = |what: &str| format!("{file}: feature {}: {what}", i + 1);
            let props = f["properties"]
                .as_object()
                .ok_or_else(|| at("no properties"))?;
            let status = props
                .get("status")
                .and_then(Value::as_str)
                .ok_or_else(|| at("no status (not written by map-towers?)"))?;
            let id = props
                .get("id")
                .and_then(Value::as_str)
                .unwrap_or_default()
                .to_owned();
            if !matches!(status, "confirmed" | "new") {
                let note = props
                    .get("notes")
                    .and_then(Value::as_str)
                    .unwrap_or_default()
                    .to_owned();
                review.others.push((id, status.to_owned(), note));
                continue;
            }
            let coords = f["geometry"]["coordinates"]
                .as_array()
                .filter(|c| c.len() >= 2)
                .ok_or_else(|| at("no point"))?;
            let mut fields = props.clone();
            fields.insert("lat_deg".into(), coords[1].clone());
            fields.insert("lon_deg".into(), coords[0].clone());
            let record: LandmarkRecord = serde_json::from_value(Value::Object(fields))
                .map_err(|e| at(&format!("tower {id}: {e}")))?;
            let status = match status {
                "confirmed" => ProposalStatus::Confirmed {
                    known_id: props
                        .get("known_id")
                        .and_then(Value::as_str)
                        .unwrap_or(&record.id)
                        .to_owned(),
                    offset_m: number(props, "offset_east_m")
                        .unwrap_or(0.0)
                        .hypot(number(props, "offset_north_m").unwrap_or(0.0)),
                    height_difference_m: number(props, "height_difference_m"),
                },
                _ => ProposalStatus::New,
            };
            review.proposals.push(Proposal {
                status,
                sigma_major_m: number(props, "sigma_major_m")
                    .or(record.sigma_horizontal_m)
                    .unwrap_or(0.0),
                sigma_minor_m: number(props, "sigma_minor_m").unwrap_or(0.0),
                ellipse_bearing_deg: number(props, "ellipse_bearing_deg").unwrap_or(0.0),
                views: props.get("views").and_then(Value::as_u64).unwrap_or(0),
                decision: Decision::Pending,
                record,
            });
        }
        Ok(review)
    }

    /// The accepted proposals' records, to write as one import.
    pub fn accepted(&self) -> Vec<LandmarkRecord> {
        self.proposals
            .iter()
            .filter(|p| p.decision == Decision::Accept)
            .map(|p| p.record.clone())
            .collect()
    }

    pub fn count(&self, decision: Decision) -> usize {
        self.proposals
            .iter()
            .filter(|p| p.decision == decision)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two proposals and a missed tower, as `map-towers` writes them.
    pub const SURVEY: &str = r#"{"type":"FeatureCollection","features":[
      {"type":"Feature","id":"A1","geometry":{"type":"Point","coordinates":[114.36125,30.5227,25.0]},
       "properties":{"id":"A1","tower_type":"A","ground_elev_m":25.0,"height_m":31.4,"status":"confirmed",
        "known_id":"A1","offset_east_m":-6.0,"offset_north_m":8.0,"height_difference_m":-0.6,
        "sigma_major_m":1.2,"sigma_minor_m":0.5,"ellipse_bearing_deg":90.0,"views":812,
        "sigma_horizontal_m":1.2,"survey_source":"towernav-edge map-towers","notes":"confirms A1"}},
      {"type":"Feature","id":"NEW-1","geometry":{"type":"Point","coordinates":[114.3634,30.5227,25.0]},
       "properties":{"id":"NEW-1","tower_type":"A","ground_elev_m":25.0,"height_m":32.2,"status":"new",
        "sigma_major_m":0.9,"sigma_minor_m":0.6,"ellipse_bearing_deg":0.0,"views":640}},
      {"type":"Feature","id":"B3","geometry":{"type":"Point","coordinates":[114.365,30.5218,25.0]},
       "properties":{"id":"B3","tower_type":"B","ground_elev_m":25.0,"height_m":38.0,"status":"missed",
        "frames_in_view":44}}
    ]}"#;

    #[test]
    fn proposals_and_the_rest_are_read_apart() {
        let r = SurveyReview::parse(SURVEY, "towers-mapped.geojson").expect("parses");
        assert_eq!(r.proposals.len(), 2);
        assert_eq!(
            r.others,
            vec![("B3".into(), "missed".into(), String::new())]
        );
        let a1 = &r.proposals[0];
        assert_eq!(a1.record.lat_deg, 30.5227);
        assert_eq!(a1.summary(), "confirms A1: 10.0 m off, height -0.6 m");
        assert_eq!(r.proposals[1].status, ProposalStatus::New);
        // The major axis east-west: all the variance on east.
        let c = a1.covariance_en();
        assert!((c[0][0] - 1.44).abs() < 1e-9 && (c[1][1] - 0.25).abs() < 1e-9);
    }

    #[test]
    fn only_accepted_proposals_are_written() {
        let mut r = SurveyReview::parse(SURVEY, "f").expect("parses");
        assert!(r.accepted().is_empty(), "nothing is accepted by default");
        r.proposals[1].decision = Decision::Accept;
        r.proposals[0].decision = Decision::Reject;
        let ids: Vec<_> = r.accepted().into_iter().map(|t| t.id).collect();
        assert_eq!(ids, vec!["NEW-1"]);
    }

    #[test]
    fn a_file_that_is_not_a_survey_says_so() {
        let err = SurveyReview::parse(
            r#"{"type":"FeatureCollection","features":[{"properties":{"id":"x"}}]}"#,
            "towers.geojson",
        )
        .unwrap_err();
        assert!(
            err.contains("towers.geojson: feature 1: no status"),
            "{err}"
        );
        assert!(
            SurveyReview::parse("[", "f")
                .unwrap_err()
                .contains("not JSON")
        );
    }
}
