//! `[ros2]` and `[px4]`: the fix for a ROS 2 stack (rmw_zenoh) and for PX4's
//! own Zenoh module, on the vehicle's onboard Zenoh (rmw_zenoh's router, or
//! the `zenohd` PX4 connects to), apart from the fleet's link to the ground.

use std::time::Duration;

use serde::{Deserialize, Serialize};
use towernav_core::fix_keeper::FixRules;
use towernav_core::ros_link::RosLinkConfig;
use towernav_protocol::ros2::cdr::CdrVersion;
use towernav_protocol::ros2::msgs::Px4AuxMessage;
use towernav_protocol::ros2::rmw_zenoh::{self, RosNode};

use super::config::ConfigError;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2Section {
    /// Publish the fix as ROS 2 topics: `NavSatFix`, `PoseWithCovarianceStamped`
    /// and `Odometry`, as rmw_zenoh does (`ros2 topic echo` sees them).
    pub enabled: bool,
    /// `ROS_DOMAIN_ID`; PX4's topics use it too.
    pub domain_id: u32,
    /// The node's namespace: empty, or absolute (`/uav7`).
    pub namespace: String,
    pub node: String,
    /// Topic names, relative to the namespace.
    pub fix_topic: String,
    pub pose_topic: String,
    pub odometry_topic: String,
    /// The local frame (ENU at the mission datum) and the body's (FLU).
    pub map_frame: String,
    pub base_frame: String,
    /// How often the topics go out, Hz (each the fix predicted to that moment).
    pub rate_hz: f64,
    /// Put each type's hash in its keys (Jazzy and later); `false` for
    /// Humble's rmw_zenoh, which sends `TypeHashNotSupported`.
    pub type_hash: bool,
    /// The onboard Zenoh: rmw_zenoh's router (`ros2 run rmw_zenoh_cpp
    /// rmw_zenohd`, `tcp/127.0.0.1:7447`), or PX4's `zenohd`.
    pub connect: Vec<String>,
    pub listen: Vec<String>,
}

impl Default for Ros2Section {
    fn default() -> Self {
        Self {
            enabled: false,
            domain_id: 0,
            namespace: String::new(),
            node: "towernav_edge".into(),
            fix_topic: rmw_zenoh::FIX_TOPIC.into(),
            pose_topic: rmw_zenoh::POSE_TOPIC.into(),
            odometry_topic: rmw_zenoh::ODOMETRY_TOPIC.into(),
            map_frame: "map".into(),
            base_frame: "base_link".into(),
            rate_hz: 10.0,
            type_hash: true,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            listen: vec![],
        }
    }
}

/// Which message PX4's auxiliary global position topic takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Px4Message {
    /// `px4_msgs/msg/AuxGlobalPosition`: PX4 v1.18 and later.
    AuxGlobalPosition,
    /// `px4_msgs/msg/VehicleGlobalPosition`: PX4 v1.17.
    VehicleGlobalPosition,
}

/// How the payloads for PX4 are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Px4Cdr {
    /// As PX4's Zenoh module reads them (Cyclone's XCDR2 stream).
    Xcdr2,
    /// Classic CDR, as a ROS 2 node with `px4_msgs` writes them.
    Xcdr1,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Px4Section {
    /// Publish the fix to PX4's EKF2 as its auxiliary global position (AGP).
    pub enabled: bool,
    /// PX4's namespace on a multi-vehicle bus: empty, or `/px4_1`.
    pub namespace: String,
    pub message: Px4Message,
    /// The topic PX4's Zenoh module subscribes to (`zenoh config`).
    pub topic: String,
    /// Where PX4 publishes its attitude: its clock, and the attitude source
    /// with `attitude.kind = "px4"`.
    pub attitude_topic: String,
    /// This source's id among PX4's AGP sources.
    pub source_id: u8,
    pub cdr: Px4Cdr,
}

impl Default for Px4Section {
    fn default() -> Self {
        Self {
            enabled: false,
            namespace: String::new(),
            message: Px4Message::AuxGlobalPosition,
            topic: "/fmu/in/aux_global_position".into(),
            attitude_topic: "/fmu/out/vehicle_attitude".into(),
            source_id: 1,
            cdr: Px4Cdr::Xcdr2,
        }
    }
}

impl Px4Section {
    pub fn aux_message(&self) -> Px4AuxMessage {
        match self.message {
            Px4Message::AuxGlobalPosition => Px4AuxMessage::AuxGlobalPosition,
            Px4Message::VehicleGlobalPosition => Px4AuxMessage::VehicleGlobalPosition,
        }
    }

    pub fn cdr_version(&self) -> CdrVersion {
        match self.cdr {
            Px4Cdr::Xcdr2 => CdrVersion::Xcdr2,
            Px4Cdr::Xcdr1 => CdrVersion::Xcdr1,
        }
    }

    /// A PX4 topic under its namespace, absolute.
    pub fn topic_in_namespace(&self, topic: &str) -> String {
        format!(
            "{}/{}",
            self.namespace.trim_end_matches('/'),
            topic.trim_start_matches('/')
        )
    }
}

impl Ros2Section {
    pub fn node(&self) -> RosNode {
        RosNode {
            domain_id: self.domain_id,
            namespace: self.namespace.clone(),
            name: self.node.clone(),
            type_hash: self.type_hash,
        }
    }

    pub fn link_config(&self, px4: &Px4Section, fix: FixRules) -> RosLinkConfig {
        RosLinkConfig {
            every: Duration::from_secs_f64(1.0 / self.rate_hz),
            ros2: self.enabled,
            px4_source_id: px4.enabled.then_some(px4.source_id),
            fix,
            map_frame: self.map_frame.clone(),
            base_frame: self.base_frame.clone(),
            roll_pitch_sigma_rad: 1f64.to_radians(),
        }
    }

    pub fn validate(&self, px4: &Px4Section) -> Result<(), ConfigError> {
        let invalid =
            |field: &'static str, reason: String| Err(ConfigError::Invalid { field, reason });
        if !(self.rate_hz > 0.0 && self.rate_hz <= 200.0) {
            return invalid(
                "ros2.rate_hz",
                format!("{} is not in (0, 200]", self.rate_hz),
            );
        }
        if !(self.namespace.is_empty() || self.namespace.starts_with('/')) {
            return invalid(
                "ros2.namespace",
                format!(
                    "{:?}: a namespace is empty or absolute (/uav7)",
                    self.namespace
                ),
            );
        }
        if !(px4.namespace.is_empty() || px4.namespace.starts_with('/')) {
            return invalid(
                "px4.namespace",
                format!(
                    "{:?}: a namespace is empty or absolute (/px4_1)",
                    px4.namespace
                ),
            );
        }
        let name_ok = |n: &str| {
            !n.is_empty()
                && n.chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/')
                && !n.starts_with(|c: char| c.is_ascii_digit())
                && !n.contains("//")
        };
        for (field, name) in [
            ("ros2.node", &self.node),
            ("ros2.fix_topic", &self.fix_topic),
            ("ros2.pose_topic", &self.pose_topic),
            ("ros2.odometry_topic", &self.odometry_topic),
            ("ros2.map_frame", &self.map_frame),
            ("ros2.base_frame", &self.base_frame),
            ("px4.topic", &px4.topic),
            ("px4.attitude_topic", &px4.attitude_topic),
        ] {
            if !name_ok(name.trim_start_matches('/'))
                || (field == "ros2.node" && name.contains('/'))
            {
                return invalid(
                    field,
                    format!("{name:?} is not a ROS name (letters, digits, _ and /)"),
                );
            }
        }
        for endpoint in self.listen.iter().chain(&self.connect) {
            if !endpoint.starts_with("tcp/") {
                return invalid(
                    "ros2.listen/connect",
                    format!("{endpoint:?}: the onboard Zenoh is tcp/<host>:<port>"),
                );
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_names_and_rates_are_refused_by_field() {
        let px4 = Px4Section::default();
        assert!(Ros2Section::default().validate(&px4).is_ok());
        for (section, field) in [
            (
                Ros2Section {
                    rate_hz: 0.0,
                    ..Default::default()
                },
                "ros2.rate_hz",
            ),
            (
                Ros2Section {
                    namespace: "uav7".into(),
                    ..Default::default()
                },
                "ros2.namespace",
            ),
            (
                Ros2Section {
                    fix_topic: "fix now".into(),
                    ..Default::default()
                },
                "ros2.fix_topic",
            ),
            (
                Ros2Section {
                    node: "a/b".into(),
                    ..Default::default()
                },
                "ros2.node",
            ),
            (
                Ros2Section {
                    connect: vec!["udp/127.0.0.1:7447".into()],
                    ..Default::default()
                },
                "ros2.listen/connect",
            ),
        ] {
            match section.validate(&px4) {
                Err(ConfigError::Invalid { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }

    #[test]
    fn px4_topics_sit_under_its_namespace() {
        let px4 = Px4Section {
            namespace: "/px4_1".into(),
            ..Default::default()
        };
        assert_eq!(
            px4.topic_in_namespace(&px4.topic),
            "/px4_1/fmu/in/aux_global_position"
        );
        assert_eq!(
            Px4Section::default().topic_in_namespace("/fmu/out/vehicle_attitude"),
            "/fmu/out/vehicle_attitude"
        );
    }
}
