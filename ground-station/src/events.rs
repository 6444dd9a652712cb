//! What the network thread (or a replayed recording) hands the UI, and how a
//! Zenoh sample becomes one. Pure: the same decoding serves live traffic and replay.

use std::sync::Arc;

use towernav_protocol::{
    CorrectionAck, Keys, NodeId, PoseEstimate, Preview, StatusHeartbeat, Topic, TrackReport,
    TruthPose, UavMessage, decode_on_key,
};

/// A camera preview with its JPEG already decoded (off the UI thread).
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedPreview {
    pub meta: Preview,
    pub image: Arc<egui::ColorImage>,
}

/// A message from the network thread.
#[derive(Debug, Clone, PartialEq)]
pub enum NetEvent {
    Pose(PoseEstimate),
    Tracks(TrackReport),
    Status(StatusHeartbeat),
    Preview(DecodedPreview),
    Truth(TruthPose),
    Ack(CorrectionAck),
    /// A UAV's liveliness token appeared (`true`) or went away.
    Alive {
        uav: NodeId,
        alive: bool,
    },
    /// A payload that did not decode: shown to the operator, never silently dropped.
    Rejected {
        key: String,
        error: String,
    },
    /// Something the operator should read: a send failed, a recording ended.
    Notice(String),
    /// Whether a recording is running: `Some(path)` once its file is open,
    /// `None` when it stopped or could not start (a notice says why).
    Recording(Option<std::path::PathBuf>),
    /// The network side failed and stopped.
    Failed(String),
}

/// The event a sample on a per-UAV key stands for. `None` for what the app
/// does not draw (its own corrections, raw detections).
pub fn decode_sample(key: &str, bytes: &[u8]) -> Option<NetEvent> {
    let rejected = |error: String| NetEvent::Rejected {
        key: key.to_owned(),
        error,
    };
    let topic = match Keys::parse_uav(key) {
        Ok(parsed) => parsed.topic,
        Err(e) => return Some(rejected(e.to_string())),
    };
    // The UAV is the one whose key the sample came on: the fleet's access
    // rules let an edge publish on its own keys only, so a payload naming
    // another UAV is an edge posing as it, and `decode_on_key` drops it.
    fn on_key<M: UavMessage>(
        key: &str,
        bytes: &[u8],
        event: fn(M) -> NetEvent,
    ) -> Result<NetEvent, String> {
        decode_on_key(key, bytes)
            .map(event)
            .map_err(|e| e.to_string())
    }
    let event = match topic {
        Topic::Pose => on_key(key, bytes, NetEvent::Pose),
        Topic::Tracks => on_key(key, bytes, NetEvent::Tracks),
        Topic::Status => on_key(key, bytes, NetEvent::Status),
        Topic::Truth => on_key(key, bytes, NetEvent::Truth),
        Topic::CorrectionAck => on_key(key, bytes, NetEvent::Ack),
        Topic::Preview => decode_on_key::<Preview>(key, bytes)
            .map_err(|e| e.to_string())
            .and_then(|meta| match decode_jpeg(&meta.jpeg) {
                Ok(image) => Ok(NetEvent::Preview(DecodedPreview {
                    meta,
                    image: Arc::new(image),
                })),
                Err(e) => Err(format!("preview JPEG: {e}")),
            }),
        // The ground station's own corrections, and raw boxes (the camera view
        // draws tracks): recorded, not decoded.
        Topic::Correction | Topic::Detections => return None,
    };
    Some(event.unwrap_or_else(rejected))
}

/// A liveliness sample: a token put or deleted on `towernav/<fleet>/alive/<uav>`.
pub fn decode_alive(key: &str, alive: bool) -> NetEvent {
    match Keys::parse_alive(key) {
        Ok(uav) => NetEvent::Alive { uav, alive },
        Err(e) => NetEvent::Rejected {
            key: key.to_owned(),
            error: e.to_string(),
        },
    }
}

fn decode_jpeg(jpeg: &[u8]) -> Result<egui::ColorImage, image::ImageError> {
    let rgb = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg)?.to_rgb8();
    let size = [rgb.width() as usize, rgb.height() as usize];
    Ok(egui::ColorImage::from_rgb(size, rgb.as_raw()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_protocol::encode;

    fn key(topic: Topic) -> String {
        Keys::new(NodeId::new("demo").expect("valid"))
            .uav(&NodeId::new("u1").expect("valid"), topic)
    }

    #[test]
    fn a_preview_arrives_decoded_and_a_bad_jpeg_is_rejected_with_its_key() {
        let jpeg = crate::test_support::jpeg(8, 4, [200, 10, 10]);
        let mut preview = Preview {
            uav: NodeId::new("u1").expect("valid"),
            time_s: 1.0,
            seq: 3,
            frame_width: 1280,
            frame_height: 720,
            jpeg,
        };
        let bytes = encode(&preview).expect("encode");
        match decode_sample(&key(Topic::Preview), &bytes) {
            Some(NetEvent::Preview(p)) => {
                assert_eq!(p.image.size, [8, 4]);
                assert!(p.image.pixels[0].r() > 150, "{:?}", p.image.pixels[0]);
            }
            other => panic!("expected a preview, got {other:?}"),
        }
        preview.jpeg = b"not a jpeg".to_vec();
        let bytes = encode(&preview).expect("encode");
        match decode_sample(&key(Topic::Preview), &bytes) {
            Some(NetEvent::Rejected { key: k, error }) => {
                assert_eq!(k, key(Topic::Preview));
                assert!(error.contains("preview JPEG"), "{error}");
            }
            other => panic!("expected a rejection, got {other:?}"),
        }
    }

    #[test]
    fn a_payload_naming_another_uav_than_its_key_is_dropped_naming_both() {
        let pose = crate::test_support::pose("u2", 30.52, 114.36, 1);
        let bytes = encode(&pose).expect("encode");
        match decode_sample(&key(Topic::Pose), &bytes) {
            Some(NetEvent::Rejected { key: k, error }) => {
                assert_eq!(k, key(Topic::Pose));
                assert!(
                    error.contains("u2") && error.contains("u1's key"),
                    "{error}"
                );
            }
            other => panic!("expected a rejection, got {other:?}"),
        }
        // On its own key the same pose is taken.
        let own_key = Keys::new(NodeId::new("demo").expect("valid"))
            .uav(&NodeId::new("u2").expect("valid"), Topic::Pose);
        assert!(matches!(
            decode_sample(&own_key, &bytes),
            Some(NetEvent::Pose(_))
        ));
        // A forged refusal of another UAV's correction is dropped too.
        let ack = CorrectionAck {
            uav: NodeId::new("u2").expect("valid"),
            request_id: 7,
            accepted: false,
            reason: Some("forged".into()),
        };
        let bytes = encode(&ack).expect("encode");
        assert!(matches!(
            decode_sample(&key(Topic::CorrectionAck), &bytes),
            Some(NetEvent::Rejected { .. })
        ));
    }

    #[test]
    fn own_corrections_are_skipped_and_bad_keys_rejected() {
        assert_eq!(decode_sample(&key(Topic::Correction), b"{}"), None);
        assert!(matches!(
            decode_sample("not/a/uav/key", b"{}"),
            Some(NetEvent::Rejected { .. })
        ));
        assert!(matches!(
            decode_alive(
                &Keys::new(NodeId::new("demo").expect("valid"))
                    .alive(&NodeId::new("u1").expect("valid")),
                false
            ),
            NetEvent::Alive { alive: false, .. }
        ));
    }
}
