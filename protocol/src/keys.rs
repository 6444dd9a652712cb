//! Zenoh key expressions: built and parsed here and nowhere else.
//!
//! - `towernav/<fleet>/uav/<uav>/<topic>`: per-UAV traffic (see [`Topic`]);
//! - `towernav/<fleet>/landmarks/changes`: published landmark changes;
//! - `towernav/<fleet>/landmarks/query`: queryable for the landmark set.

use crate::codec::Message;
use crate::ids::{IdError, NodeId};

const ROOT: &str = "towernav";

/// What a per-UAV key carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Topic {
    /// [`crate::PoseEstimate`], edge -> anyone.
    Pose,
    /// [`crate::TrackReport`], edge -> anyone.
    Tracks,
    /// [`crate::StatusHeartbeat`], edge -> anyone.
    Status,
    /// [`crate::IdCorrection`], ground station -> edge.
    Correction,
    /// [`crate::CorrectionAck`], edge -> ground station.
    CorrectionAck,
    /// [`crate::DetectionReport`], edge -> anyone.
    Detections,
    /// [`crate::Preview`], edge -> anyone, a few times a second.
    Preview,
    /// [`crate::TruthPose`], simulated edges only: where the UAV really was.
    Truth,
}

impl Topic {
    pub const ALL: [Topic; 8] = [
        Topic::Pose,
        Topic::Tracks,
        Topic::Status,
        Topic::Correction,
        Topic::CorrectionAck,
        Topic::Detections,
        Topic::Preview,
        Topic::Truth,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Topic::Pose => "pose",
            Topic::Tracks => "tracks",
            Topic::Status => "status",
            Topic::Correction => "correction",
            Topic::CorrectionAck => "correction_ack",
            Topic::Detections => "detections",
            Topic::Preview => "preview",
            Topic::Truth => "truth",
        }
    }

    fn parse(s: &str) -> Option<Topic> {
        Topic::ALL.into_iter().find(|t| t.as_str() == s)
    }
}

/// A payload that travels on a per-UAV key: its topic is paired with it
/// here, in code, so a key cannot be built for the wrong payload.
pub trait UavMessage: Message {
    const TOPIC: Topic;
    /// The UAV the payload speaks for; it must be the one of its key.
    fn uav(&self) -> &NodeId;
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KeyError {
    #[error("key {key:?} is not of the form towernav/<fleet>/uav/<uav>/<topic>")]
    Shape { key: String },
    #[error("key {key:?} names an unknown topic {topic:?}")]
    Topic { key: String, topic: String },
    #[error("key {key:?} has a bad id: {source}")]
    Id {
        key: String,
        #[source]
        source: IdError,
    },
}

/// A parsed per-UAV key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UavKey {
    pub fleet: NodeId,
    pub uav: NodeId,
    pub topic: Topic,
}

/// Key builder for one fleet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Keys {
    fleet: NodeId,
}

impl Keys {
    pub fn new(fleet: NodeId) -> Self {
        Self { fleet }
    }

    pub fn fleet(&self) -> &NodeId {
        &self.fleet
    }

    pub fn uav(&self, uav: &NodeId, topic: Topic) -> String {
        format!("{ROOT}/{}/uav/{uav}/{}", self.fleet, topic.as_str())
    }

    /// The key one UAV's `M` travels on.
    pub fn uav_key<M: UavMessage>(&self, uav: &NodeId) -> String {
        self.uav(uav, M::TOPIC)
    }

    /// Every UAV's key for `M`, e.g. all poses of the fleet.
    pub fn all_uavs_of<M: UavMessage>(&self) -> String {
        self.all_uavs(M::TOPIC)
    }

    /// Every UAV's key for one topic, e.g. all poses of the fleet.
    pub fn all_uavs(&self, topic: Topic) -> String {
        format!("{ROOT}/{}/uav/*/{}", self.fleet, topic.as_str())
    }

    /// Every per-UAV key of the fleet, whatever the topic.
    pub fn all_uavs_any_topic(&self) -> String {
        format!("{ROOT}/{}/uav/*/*", self.fleet)
    }

    /// The liveliness token an edge holds while it runs: the ground station's
    /// "online" list.
    pub fn alive(&self, uav: &NodeId) -> String {
        format!("{ROOT}/{}/alive/{uav}", self.fleet)
    }

    pub fn all_alive(&self) -> String {
        format!("{ROOT}/{}/alive/*", self.fleet)
    }

    /// The UAV a liveliness token names.
    pub fn parse_alive(key: &str) -> Result<NodeId, KeyError> {
        match key.split('/').collect::<Vec<_>>().as_slice() {
            [root, _fleet, "alive", uav] if *root == ROOT => {
                NodeId::new(*uav).map_err(|source| KeyError::Id {
                    key: key.into(),
                    source,
                })
            }
            _ => Err(KeyError::Shape { key: key.into() }),
        }
    }

    pub fn landmark_changes(&self) -> String {
        format!("{ROOT}/{}/landmarks/changes", self.fleet)
    }

    pub fn landmark_query(&self) -> String {
        format!("{ROOT}/{}/landmarks/query", self.fleet)
    }

    /// Parses a concrete per-UAV key as it arrives on a sample.
    pub fn parse_uav(key: &str) -> Result<UavKey, KeyError> {
        let parts: Vec<&str> = key.split('/').collect();
        let [root, fleet, uav_literal, uav, topic] = parts.as_slice() else {
            return Err(KeyError::Shape { key: key.into() });
        };
        if *root != ROOT || *uav_literal != "uav" {
            return Err(KeyError::Shape { key: key.into() });
        }
        let id = |s: &str| {
            NodeId::new(s).map_err(|source| KeyError::Id {
                key: key.into(),
                source,
            })
        };
        let topic = Topic::parse(topic).ok_or_else(|| KeyError::Topic {
            key: key.into(),
            topic: (*topic).into(),
        })?;
        Ok(UavKey {
            fleet: id(fleet)?,
            uav: id(uav)?,
            topic,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn pose_key_has_the_documented_shape() {
        let keys = Keys::new(NodeId::new("demo").expect("valid"));
        let uav = NodeId::new("uav1").expect("valid");
        assert_eq!(keys.uav(&uav, Topic::Pose), "towernav/demo/uav/uav1/pose");
        assert_eq!(keys.all_uavs(Topic::Pose), "towernav/demo/uav/*/pose");
        assert_eq!(keys.landmark_query(), "towernav/demo/landmarks/query");
    }

    #[test]
    fn malformed_keys_are_typed_errors() {
        assert!(matches!(
            Keys::parse_uav("towernav/demo/uav/u1"),
            Err(KeyError::Shape { .. })
        ));
        assert!(matches!(
            Keys::parse_uav("other/demo/uav/u1/pose"),
            Err(KeyError::Shape { .. })
        ));
        assert!(matches!(
            Keys::parse_uav("towernav/demo/uav/u1/nope"),
            Err(KeyError::Topic { .. })
        ));
        assert!(matches!(
            Keys::parse_uav("towernav/demo/uav/*/pose"),
            Err(KeyError::Id { .. })
        ));
    }

    proptest! {
        #[test]
        fn built_keys_parse_back(fleet in "[A-Za-z0-9_-]{1,20}", uav in "[A-Za-z0-9_-]{1,20}", t in 0usize..7) {
            let keys = Keys::new(NodeId::new(fleet.clone()).expect("valid"));
            let topic = Topic::ALL[t];
            let key = keys.uav(&NodeId::new(uav.clone()).expect("valid"), topic);
            let parsed = Keys::parse_uav(&key).expect("round trip");
            prop_assert_eq!(parsed.fleet.as_str(), fleet.as_str());
            prop_assert_eq!(parsed.uav.as_str(), uav.as_str());
            prop_assert_eq!(parsed.topic, topic);
        }

        #[test]
        fn parsing_arbitrary_text_never_panics(s in ".{0,80}") {
            let _ = Keys::parse_uav(&s);
            let _ = Keys::parse_alive(&s);
        }

        #[test]
        fn alive_keys_parse_back(uav in "[A-Za-z0-9_-]{1,20}") {
            let keys = Keys::new(NodeId::new("fleet").expect("valid"));
            let id = NodeId::new(uav.clone()).expect("valid");
            prop_assert_eq!(Keys::parse_alive(&keys.alive(&id)).expect("round trip"), id);
        }
    }
}
