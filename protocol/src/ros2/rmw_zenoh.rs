//! rmw_zenoh's names on Zenoh, as its design document gives them
//! (`docs/design.md`, "Topic and Service name mapping" and "Graph Cache"):
//!
//! - a topic's key: `<domain>/<fully qualified name>/<DDS type>/<type hash>`;
//! - liveliness tokens, which `ros2 node list` and `ros2 topic list` read:
//!   `@ros2_lv/<domain>/<session>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>`
//!   and, for a publisher or subscription, `/<topic>/<type>/<hash>/<qos>`,
//!   each name with `/` written `%` (an empty one as `%`);
//! - each sample's attachment: sequence number and source time (i64, little
//!   endian) and the publisher's 16-byte GID behind its length.

use super::type_hash::MsgType;

/// What distributions before Jazzy put where the hash goes.
pub const TYPE_HASH_NOT_SUPPORTED: &str = "TypeHashNotSupported";

/// The edge's ROS 2 topics, relative to its namespace.
pub const FIX_TOPIC: &str = "towernav/fix";
pub const POSE_TOPIC: &str = "towernav/pose";
pub const ODOMETRY_TOPIC: &str = "towernav/odometry";

/// A ROS node's place in the graph.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RosNode {
    pub domain_id: u32,
    /// `""` or absolute (`/uav7`).
    pub namespace: String,
    pub name: String,
    /// Whether keys carry the type hash (Jazzy and later) or
    /// `TypeHashNotSupported` (Humble).
    pub type_hash: bool,
}

/// A publisher's or subscription's QoS, as far as rmw_zenoh's token says it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    pub reliable: bool,
    pub depth: u32,
}

impl Qos {
    /// rmw_zenoh's `qos_to_keyexpr`: each policy left empty where it is
    /// rmw_zenoh's default (reliable, volatile, keep last, infinite deadline,
    /// lifespan and lease, automatic liveliness).
    pub fn keyexpr(self) -> String {
        // RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT is 2.
        let reliability = if self.reliable { "" } else { "2" };
        format!("{reliability}::,{}:,:,:,,", self.depth)
    }
}

/// Whether a token announces a publisher or a subscription.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endpoint {
    Publisher,
    Subscription,
}

/// `/` to `%`; an empty name is `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

impl RosNode {
    /// A topic's fully qualified name: absolute names (`/fmu/in/...`) as
    /// they are, relative ones under the namespace.
    pub fn fully_qualified(&self, topic: &str) -> String {
        if topic.starts_with('/') {
            topic.to_owned()
        } else {
            format!("{}/{topic}", self.namespace.trim_end_matches('/'))
        }
    }

    fn hash_of(&self, t: &MsgType) -> String {
        if self.type_hash {
            t.type_hash()
        } else {
            TYPE_HASH_NOT_SUPPORTED.into()
        }
    }

    /// The key a topic's samples go on.
    pub fn topic_key(&self, topic: &str, t: &MsgType) -> String {
        format!(
            "{}/{}/{}/{}",
            self.domain_id,
            self.fully_qualified(topic).trim_matches('/'),
            t.dds_name(),
            self.hash_of(t)
        )
    }

    /// A topic's key whatever the type's hash (a subscriber that takes
    /// every release of a type whose layout has not changed).
    pub fn topic_key_any_hash(&self, topic: &str, t: &MsgType) -> String {
        format!(
            "{}/{}/{}/*",
            self.domain_id,
            self.fully_qualified(topic).trim_matches('/'),
            t.dds_name()
        )
    }

    /// The node's own token; `session` is the Zenoh session id as text.
    pub fn node_token(&self, session: &str, node_id: u32) -> String {
        format!(
            "@ros2_lv/{}/{session}/{node_id}/{node_id}/NN/%/{}/{}",
            self.domain_id,
            mangle(&self.namespace),
            self.name
        )
    }

    /// A publisher's or subscription's token.
    #[allow(clippy::too_many_arguments)]
    pub fn endpoint_token(
        &self,
        session: &str,
        node_id: u32,
        entity_id: u32,
        kind: Endpoint,
        topic: &str,
        t: &MsgType,
        qos: Qos,
    ) -> String {
        let kind = match kind {
            Endpoint::Publisher => "MP",
            Endpoint::Subscription => "MS",
        };
        format!(
            "@ros2_lv/{}/{session}/{node_id}/{entity_id}/{kind}/%/{}/{}/{}/{}/{}/{}",
            self.domain_id,
            mangle(&self.namespace),
            self.name,
            mangle(&self.fully_qualified(topic)),
            t.dds_name(),
            self.hash_of(t),
            qos.keyexpr()
        )
    }
}

/// A publisher's GID: 16 bytes taken from its token, so that it is the same
/// for the same publisher and differs between publishers.
pub fn gid_of(token: &str) -> [u8; 16] {
    let digest = ring::digest::digest(&ring::digest::SHA256, token.as_bytes());
    let mut gid = [0; 16];
    gid.copy_from_slice(&digest.as_ref()[..16]);
    gid
}

/// The attachment rmw_zenoh sends with each sample (zenoh-ext's serializer:
/// two i64 little endian, then the GID as a byte sequence, its length a
/// one-byte LEB128).
pub fn attachment(sequence: i64, source_unix_ns: i64, gid: &[u8; 16]) -> Vec<u8> {
    let mut out = Vec::with_capacity(33);
    out.extend_from_slice(&sequence.to_le_bytes());
    out.extend_from_slice(&source_unix_ns.to_le_bytes());
    out.push(16);
    out.extend_from_slice(gid);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::type_hash::{Field, FieldType};

    const STRING: MsgType = MsgType {
        name: "std_msgs/msg/String",
        fields: &[Field::one("data", FieldType::String)],
    };
    const CHATTER_HASH: &str =
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

    fn node(domain_id: u32, namespace: &str, name: &str) -> RosNode {
        RosNode {
            domain_id,
            namespace: namespace.into(),
            name: name.into(),
            type_hash: true,
        }
    }

    /// The design document's own examples, rebuilt.
    #[test]
    fn keys_and_tokens_are_the_design_document_s() {
        assert_eq!(
            node(0, "", "talker").topic_key("chatter", &STRING),
            format!("0/chatter/std_msgs::msg::dds_::String_/{CHATTER_HASH}")
        );
        assert_eq!(
            node(0, "/robot1", "talker").topic_key("chatter", &STRING),
            format!("0/robot1/chatter/std_msgs::msg::dds_::String_/{CHATTER_HASH}")
        );
        assert_eq!(
            node(2, "", "listener").node_token("aac3178e146ba6f1fc6e6a4085e77f21", 0),
            "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
        );
        assert_eq!(
            node(2, "", "talker").endpoint_token(
                "8b20917502ee955ac4476e0266340d5c",
                0,
                10,
                Endpoint::Publisher,
                "chatter",
                &STRING,
                Qos {
                    reliable: true,
                    depth: 7
                }
            ),
            format!(
                "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/\
                 std_msgs::msg::dds_::String_/{CHATTER_HASH}/::,7:,:,:,,"
            )
        );
        assert_eq!(
            node(2, "", "listener").endpoint_token(
                "aac3178e146ba6f1fc6e6a4085e77f21",
                0,
                10,
                Endpoint::Subscription,
                "chatter",
                &STRING,
                Qos {
                    reliable: true,
                    depth: 10
                }
            ),
            format!(
                "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/\
                 std_msgs::msg::dds_::String_/{CHATTER_HASH}/::,10:,:,:,,"
            )
        );
    }

    #[test]
    fn absolute_topics_keep_their_place_and_humble_gets_no_hash() {
        let mut n = node(0, "/uav7", "towernav_edge");
        assert_eq!(n.fully_qualified("/fmu/in/x"), "/fmu/in/x");
        assert_eq!(n.fully_qualified("towernav/fix"), "/uav7/towernav/fix");
        assert_eq!(
            n.topic_key_any_hash("/fmu/out/vehicle_attitude", &STRING),
            "0/fmu/out/vehicle_attitude/std_msgs::msg::dds_::String_/*"
        );
        n.type_hash = false;
        assert_eq!(
            n.topic_key("towernav/fix", &STRING),
            "0/uav7/towernav/fix/std_msgs::msg::dds_::String_/TypeHashNotSupported"
        );
        assert_eq!(
            Qos {
                reliable: false,
                depth: 5
            }
            .keyexpr(),
            "2::,5:,:,:,,"
        );
    }

    #[test]
    fn the_attachment_is_33_bytes_as_documented() {
        let gid = gid_of("token");
        let a = attachment(7, 1_700_000_000_000_000_000, &gid);
        assert_eq!(a.len(), 8 + 8 + 1 + 16);
        assert_eq!(&a[..8], &7i64.to_le_bytes());
        assert_eq!(a[16], 16);
        assert_eq!(&a[17..], &gid);
        assert_ne!(gid_of("token"), gid_of("other"));
    }
}
