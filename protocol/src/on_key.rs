//! A per-UAV payload read together with the key it came on.
//!
//! The fleet's access rules check keys, not payloads: an edge may publish on
//! its own UAV's keys only, but nothing stops it writing another UAV's id in
//! the payload. So the key is the identity, and a payload that names another
//! UAV is refused here, once, for every consumer.

use crate::codec::{DecodeError, decode};
use crate::ids::NodeId;
use crate::keys::{KeyError, Keys, Topic, UavMessage};

#[derive(Debug, thiserror::Error)]
pub enum OnKeyError {
    #[error(transparent)]
    Key(#[from] KeyError),
    #[error("key {key:?} carries {found:?}, not {expected:?}")]
    Topic {
        key: String,
        found: Topic,
        expected: Topic,
    },
    #[error("{key}: {source}")]
    Decode {
        key: String,
        #[source]
        source: DecodeError,
    },
    /// An edge speaking for another UAV on its own key.
    #[error("payload names UAV {named} but came on {on_key}'s key {key:?}: dropped")]
    Impostor {
        key: String,
        on_key: NodeId,
        named: NodeId,
    },
}

impl OnKeyError {
    /// Both names of an impostor payload: `(the key's UAV, the payload's)`.
    pub fn impostor(&self) -> Option<(&NodeId, &NodeId)> {
        match self {
            OnKeyError::Impostor { on_key, named, .. } => Some((on_key, named)),
            _ => None,
        }
    }
}

/// Decodes `bytes` received on `key` as an `M`, which must be the key's topic
/// and name the key's UAV.
pub fn decode_on_key<M: UavMessage>(key: &str, bytes: &[u8]) -> Result<M, OnKeyError> {
    let parsed = Keys::parse_uav(key)?;
    if parsed.topic != M::TOPIC {
        return Err(OnKeyError::Topic {
            key: key.to_owned(),
            found: parsed.topic,
            expected: M::TOPIC,
        });
    }
    let message: M = decode(bytes).map_err(|source| OnKeyError::Decode {
        key: key.to_owned(),
        source,
    })?;
    if *message.uav() != parsed.uav {
        return Err(OnKeyError::Impostor {
            key: key.to_owned(),
            on_key: parsed.uav,
            named: message.uav().clone(),
        });
    }
    Ok(message)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::encode;
    use crate::messages::CorrectionAck;

    fn ack(uav: &str) -> CorrectionAck {
        CorrectionAck {
            uav: NodeId::new(uav).expect("valid"),
            request_id: 7,
            accepted: false,
            reason: Some("refused".into()),
        }
    }

    fn key(uav: &str, topic: Topic) -> String {
        Keys::new(NodeId::new("f").expect("valid")).uav(&NodeId::new(uav).expect("valid"), topic)
    }

    #[test]
    fn a_payload_on_its_own_uavs_key_is_read() {
        let bytes = encode(&ack("u7")).expect("encodes");
        let got: CorrectionAck =
            decode_on_key(&key("u7", Topic::CorrectionAck), &bytes).expect("own key");
        assert_eq!(got, ack("u7"));
    }

    #[test]
    fn a_payload_naming_another_uav_is_refused_with_both_names() {
        let bytes = encode(&ack("u7")).expect("encodes");
        let err = decode_on_key::<CorrectionAck>(&key("u8", Topic::CorrectionAck), &bytes)
            .expect_err("impostor");
        let (on_key, named) = err.impostor().expect("an impostor");
        assert_eq!((on_key.as_str(), named.as_str()), ("u8", "u7"));
        assert!(err.to_string().contains("u7") && err.to_string().contains("u8"));
    }

    #[test]
    fn a_payload_on_another_topics_key_is_refused() {
        let bytes = encode(&ack("u7")).expect("encodes");
        let err = decode_on_key::<CorrectionAck>(&key("u7", Topic::Pose), &bytes)
            .expect_err("wrong topic");
        assert!(matches!(err, OnKeyError::Topic { .. }), "{err}");
    }
}
