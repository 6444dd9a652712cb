//! JSON envelope `{"schema": 1, "kind": "...", "body": {...}}`.
//!
//! The header is checked before the body so that a newer or foreign message is
//! reported as such, not as a confusing field error.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// Bumped on any change a v1 reader could misread.
pub const SCHEMA_VERSION: u32 = 1;

pub trait Message: Serialize + DeserializeOwned {
    /// The envelope's `kind`.
    const KIND: &'static str;
}

#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    #[error("payload is not a towernav envelope: {0}")]
    Malformed(#[source] serde_json::Error),
    #[error("payload has schema version {found}, this build reads {expected}")]
    WrongVersion { found: u32, expected: u32 },
    #[error("payload is a {found:?} message, expected {expected:?}")]
    WrongKind {
        found: String,
        expected: &'static str,
    },
    #[error("{kind} body is invalid: {source}")]
    Body {
        kind: &'static str,
        #[source]
        source: serde_json::Error,
    },
}

#[derive(Debug, thiserror::Error)]
#[error("cannot encode {kind}: {source}")]
pub struct EncodeError {
    kind: &'static str,
    #[source]
    source: serde_json::Error,
}

#[derive(Serialize)]
struct EnvelopeOut<'a, M> {
    schema: u32,
    kind: &'static str,
    body: &'a M,
}

#[derive(Deserialize)]
struct Header {
    schema: u32,
    kind: String,
}

#[derive(Deserialize)]
struct EnvelopeIn<M> {
    body: M,
}

pub fn encode<M: Message>(message: &M) -> Result<Vec<u8>, EncodeError> {
    serde_json::to_vec(&EnvelopeOut {
        schema: SCHEMA_VERSION,
        kind: M::KIND,
        body: message,
    })
    .map_err(|source| EncodeError {
        kind: M::KIND,
        source,
    })
}

pub fn decode<M: Message>(payload: &[u8]) -> Result<M, DecodeError> {
    let header: Header = serde_json::from_slice(payload).map_err(DecodeError::Malformed)?;
    if header.schema != SCHEMA_VERSION {
        return Err(DecodeError::WrongVersion {
            found: header.schema,
            expected: SCHEMA_VERSION,
        });
    }
    if header.kind != M::KIND {
        return Err(DecodeError::WrongKind {
            found: header.kind,
            expected: M::KIND,
        });
    }
    let envelope: EnvelopeIn<M> =
        serde_json::from_slice(payload).map_err(|source| DecodeError::Body {
            kind: M::KIND,
            source,
        })?;
    Ok(envelope.body)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::NodeId;
    use crate::messages::*;
    use proptest::prelude::*;
    use towernav_geometry::PixelBox;

    fn pose(east: f64, north: f64, seq: u64, towers: Vec<String>) -> PoseEstimate {
        PoseEstimate {
            uav: NodeId::new("uav1").expect("valid"),
            time_s: seq as f64 / 30.0,
            seq,
            east_m: east,
            north_m: north,
            up_m: 30.0,
            lat_deg: 30.5,
            lon_deg: 114.3,
            alt_m: 50.0,
            yaw_rad: 0.1,
            covariance: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 4.0, 0.0],
                [0.0, 0.0, 0.0, 0.01],
            ],
            method: PoseMethod::PaperLbl,
            towers_used: towers,
            coast_s: 0.0,
        }
    }

    #[test]
    fn envelope_carries_schema_and_kind() {
        let bytes = encode(&pose(1.0, 2.0, 3, vec!["A1".into()])).expect("encode");
        let value: serde_json::Value = serde_json::from_slice(&bytes).expect("json");
        assert_eq!(value["schema"], 1);
        assert_eq!(value["kind"], "pose");
        assert_eq!(value["body"]["towers_used"][0], "A1");
    }

    #[test]
    fn wrong_version_and_kind_are_typed_errors() {
        let future = br#"{"schema": 2, "kind": "pose", "body": {}}"#;
        assert!(matches!(
            decode::<PoseEstimate>(future),
            Err(DecodeError::WrongVersion {
                found: 2,
                expected: 1
            })
        ));
        let ack = encode(&CorrectionAck {
            uav: NodeId::new("u").expect("valid"),
            request_id: 1,
            accepted: true,
            reason: None,
        })
        .expect("encode");
        assert!(matches!(
            decode::<PoseEstimate>(&ack),
            Err(DecodeError::WrongKind { .. })
        ));
        assert!(matches!(
            decode::<PoseEstimate>(b"not json"),
            Err(DecodeError::Malformed(_))
        ));
        let bad_body = br#"{"schema": 1, "kind": "pose", "body": {"uav": "a/b"}}"#;
        assert!(matches!(
            decode::<PoseEstimate>(bad_body),
            Err(DecodeError::Body { .. })
        ));
    }

    #[test]
    fn track_report_and_landmark_change_round_trip() {
        let report = TrackReport {
            uav: NodeId::new("u").expect("valid"),
            time_s: 1.0,
            seq: 30,
            tracks: vec![Track {
                track_id: 7,
                bbox: PixelBox::new(1.0, 2.0, 30.0, 200.0),
                tower_type: TowerType::C,
                tower_id: Some("C2".into()),
                pinned: false,
                confidence: Some(0.75),
            }],
            session: 0,
        };
        assert_eq!(
            decode::<TrackReport>(&encode(&report).expect("encode")).expect("decode"),
            report
        );
        let change = LandmarkChange {
            revision: 9,
            change: LandmarkChangeOp::Remove { id: "A1".into() },
        };
        assert_eq!(
            decode::<LandmarkChange>(&encode(&change).expect("encode")).expect("decode"),
            change
        );
    }

    proptest! {
        #[test]
        fn pose_round_trips(east in -1e6f64..1e6, north in -1e6f64..1e6, seq in any::<u64>(),
                            towers in proptest::collection::vec("[A-D][0-9]{1,2}", 0..5)) {
            let p = pose(east, north, seq, towers);
            let back: PoseEstimate = decode(&encode(&p).expect("encode")).expect("decode");
            prop_assert_eq!(back, p);
        }

        #[test]
        fn previews_round_trip_any_bytes(jpeg in proptest::collection::vec(any::<u8>(), 0..512), seq in any::<u64>()) {
            let p = Preview {
                uav: NodeId::new("u1").expect("valid"),
                time_s: 1.5,
                seq,
                frame_width: 1280,
                frame_height: 720,
                jpeg,
            };
            let back: Preview = decode(&encode(&p).expect("encode")).expect("decode");
            prop_assert_eq!(back, p);
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let _ = decode::<PoseEstimate>(&bytes);
            let _ = decode::<LandmarkChange>(&bytes);
            let _ = decode::<Preview>(&bytes);
        }
    }
}
