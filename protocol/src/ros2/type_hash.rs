//! ROS 2 interface type hashes (REP 2011, `RIHS01_<sha256>`), computed the
//! way `rosidl_generator_type_description` does: the type's description and
//! every type it refers to (sorted by name, default values left out) as JSON
//! with `", "` and `": "` separators, hashed with SHA-256.
//!
//! rmw_zenoh (Jazzy and later) and PX4's Zenoh module put the hash in every
//! topic's key, so a publisher whose hash differs is never matched.

use std::collections::BTreeMap;
use std::fmt::Write;

/// A field's element type, as the `.msg` file names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
    Bool,
    String,
    Nested(&'static MsgType),
}

impl FieldType {
    /// `type_description_interfaces/msg/FieldType`'s id for one element.
    fn id(self) -> u8 {
        match self {
            Self::Nested(_) => 1,
            Self::Int8 => 2,
            Self::UInt8 => 3,
            Self::Int16 => 4,
            Self::UInt16 => 5,
            Self::Int32 => 6,
            Self::UInt32 => 7,
            Self::Int64 => 8,
            Self::UInt64 => 9,
            Self::Float32 => 10,
            Self::Float64 => 11,
            Self::Bool => 15,
            Self::String => 17,
        }
    }
}

/// One field: a single value, or a fixed-size array (`float64[9]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    pub name: &'static str,
    pub ty: FieldType,
    /// `Some(n)`: an array of `n`.
    pub array: Option<u32>,
}

impl Field {
    pub const fn one(name: &'static str, ty: FieldType) -> Self {
        Self {
            name,
            ty,
            array: None,
        }
    }
    pub const fn array(name: &'static str, ty: FieldType, n: u32) -> Self {
        Self {
            name,
            ty,
            array: Some(n),
        }
    }
}

/// A message type: `package/msg/Name` and its fields in order.
#[derive(Debug, PartialEq, Eq)]
pub struct MsgType {
    pub name: &'static str,
    pub fields: &'static [Field],
}

impl MsgType {
    /// The name DDS and rmw_zenoh's keys use: `pkg::msg::dds_::Name_`.
    pub fn dds_name(&self) -> String {
        let mut parts: Vec<&str> = self.name.split('/').collect();
        let last = parts.pop().unwrap_or_default();
        format!("{}::dds_::{last}_", parts.join("::"))
    }

    /// Its REP 2011 hash, `RIHS01_` and 64 hex digits.
    pub fn type_hash(&self) -> String {
        let digest = ring::digest::digest(&ring::digest::SHA256, self.hashed_json().as_bytes());
        let mut out = String::from("RIHS01_");
        for b in digest.as_ref() {
            let _ = write!(out, "{b:02x}");
        }
        out
    }

    /// The JSON text the hash is taken of.
    pub fn hashed_json(&self) -> String {
        let mut referenced = BTreeMap::new();
        self.collect_referenced(&mut referenced);
        let refs: Vec<String> = referenced.values().map(|t| t.description()).collect();
        format!(
            "{{\"type_description\": {}, \"referenced_type_descriptions\": [{}]}}",
            self.description(),
            refs.join(", ")
        )
    }

    fn collect_referenced(&self, into: &mut BTreeMap<&'static str, &'static MsgType>) {
        for field in self.fields {
            if let FieldType::Nested(t) = field.ty
                && into.insert(t.name, t).is_none()
            {
                t.collect_referenced(into);
            }
        }
    }

    fn description(&self) -> String {
        let fields: Vec<String> = self
            .fields
            .iter()
            .map(|f| {
                let (offset, capacity) = match f.array {
                    Some(n) => (48, n),
                    None => (0, 0),
                };
                let nested = match f.ty {
                    FieldType::Nested(t) => t.name,
                    _ => "",
                };
                format!(
                    "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": {capacity}, \
                     \"string_capacity\": 0, \"nested_type_name\": \"{nested}\"}}}}",
                    f.name,
                    u32::from(f.ty.id()) + offset
                )
            })
            .collect();
        format!(
            "{{\"type_name\": \"{}\", \"fields\": [{}]}}",
            self.name,
            fields.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::FieldType::*;
    use super::*;
    use crate::ros2::msgs;

    const STRING: MsgType = MsgType {
        name: "std_msgs/msg/String",
        fields: &[Field::one("data", String)],
    };

    /// Hashes as ROS 2 itself publishes them: `std_msgs/String` from
    /// rmw_zenoh's design document; the rest as `ros2 topic info -v` shows
    /// them on Jazzy (the same in every distribution since, their definitions
    /// being unchanged).
    #[test]
    fn hashes_agree_with_the_ones_ros_2_publishes() {
        for (t, hash) in [
            (
                &STRING,
                "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
            ),
            (
                &msgs::HEADER,
                "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
            ),
            (
                &msgs::NAV_SAT_FIX,
                "RIHS01_62223ab3fe210a15976021da7afddc9e200dc9ec75231c1b6a557fc598a65404",
            ),
            (
                &msgs::POSE_WITH_COVARIANCE_STAMPED,
                "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e",
            ),
            (
                &msgs::ODOMETRY,
                "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
            ),
        ] {
            assert_eq!(t.type_hash(), hash, "{}", t.name);
        }
    }

    #[test]
    fn dds_names_follow_the_idl_mangling() {
        assert_eq!(
            msgs::NAV_SAT_FIX.dds_name(),
            "sensor_msgs::msg::dds_::NavSatFix_"
        );
        assert_eq!(
            msgs::AUX_GLOBAL_POSITION.dds_name(),
            "px4_msgs::msg::dds_::AuxGlobalPosition_"
        );
    }

    #[test]
    fn referenced_types_are_listed_once_in_name_order() {
        let json = msgs::ODOMETRY.hashed_json();
        let names: Vec<&str> = json
            .match_indices("\"type_name\": \"")
            .map(|(i, m)| {
                let rest = &json[i + m.len()..];
                &rest[..rest.find('"').unwrap_or(0)]
            })
            .collect();
        assert_eq!(names[0], "nav_msgs/msg/Odometry");
        let refs = &names[1..];
        assert!(refs.windows(2).all(|w| w[0] < w[1]), "{refs:?}");
        assert_eq!(refs.len(), 9, "{refs:?}");
        assert!(!json.contains("default_value"));
    }
}
