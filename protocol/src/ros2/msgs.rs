//! The ROS 2 and PX4 messages the edge sends and reads, with their
//! definitions (for the type hash) and their CDR encoding.
//!
//! Standard types follow their `.msg` files in `common_interfaces`;
//! PX4's follow `px4_msgs` (`tests/fixtures/px4_msgs/` holds the `.msg` text
//! at the PX4 releases named there).

use super::cdr::{CdrError, CdrReader, CdrVersion, CdrWriter};
use super::type_hash::FieldType::*;
use super::type_hash::{Field, MsgType};

pub const TIME: MsgType = MsgType {
    name: "builtin_interfaces/msg/Time",
    fields: &[Field::one("sec", Int32), Field::one("nanosec", UInt32)],
};
pub const HEADER: MsgType = MsgType {
    name: "std_msgs/msg/Header",
    fields: &[
        Field::one("stamp", Nested(&TIME)),
        Field::one("frame_id", String),
    ],
};
pub const NAV_SAT_STATUS: MsgType = MsgType {
    name: "sensor_msgs/msg/NavSatStatus",
    fields: &[Field::one("status", Int8), Field::one("service", UInt16)],
};
pub const NAV_SAT_FIX: MsgType = MsgType {
    name: "sensor_msgs/msg/NavSatFix",
    fields: &[
        Field::one("header", Nested(&HEADER)),
        Field::one("status", Nested(&NAV_SAT_STATUS)),
        Field::one("latitude", Float64),
        Field::one("longitude", Float64),
        Field::one("altitude", Float64),
        Field::array("position_covariance", Float64, 9),
        Field::one("position_covariance_type", UInt8),
    ],
};
pub const POINT: MsgType = MsgType {
    name: "geometry_msgs/msg/Point",
    fields: &[
        Field::one("x", Float64),
        Field::one("y", Float64),
        Field::one("z", Float64),
    ],
};
pub const QUATERNION: MsgType = MsgType {
    name: "geometry_msgs/msg/Quaternion",
    fields: &[
        Field::one("x", Float64),
        Field::one("y", Float64),
        Field::one("z", Float64),
        Field::one("w", Float64),
    ],
};
pub const POSE: MsgType = MsgType {
    name: "geometry_msgs/msg/Pose",
    fields: &[
        Field::one("position", Nested(&POINT)),
        Field::one("orientation", Nested(&QUATERNION)),
    ],
};
pub const POSE_WITH_COVARIANCE: MsgType = MsgType {
    name: "geometry_msgs/msg/PoseWithCovariance",
    fields: &[
        Field::one("pose", Nested(&POSE)),
        Field::array("covariance", Float64, 36),
    ],
};
pub const POSE_WITH_COVARIANCE_STAMPED: MsgType = MsgType {
    name: "geometry_msgs/msg/PoseWithCovarianceStamped",
    fields: &[
        Field::one("header", Nested(&HEADER)),
        Field::one("pose", Nested(&POSE_WITH_COVARIANCE)),
    ],
};
pub const VECTOR3: MsgType = MsgType {
    name: "geometry_msgs/msg/Vector3",
    fields: &[
        Field::one("x", Float64),
        Field::one("y", Float64),
        Field::one("z", Float64),
    ],
};
pub const TWIST: MsgType = MsgType {
    name: "geometry_msgs/msg/Twist",
    fields: &[
        Field::one("linear", Nested(&VECTOR3)),
        Field::one("angular", Nested(&VECTOR3)),
    ],
};
pub const TWIST_WITH_COVARIANCE: MsgType = MsgType {
    name: "geometry_msgs/msg/TwistWithCovariance",
    fields: &[
        Field::one("twist", Nested(&TWIST)),
        Field::array("covariance", Float64, 36),
    ],
};
pub const ODOMETRY: MsgType = MsgType {
    name: "nav_msgs/msg/Odometry",
    fields: &[
        Field::one("header", Nested(&HEADER)),
        Field::one("child_frame_id", String),
        Field::one("pose", Nested(&POSE_WITH_COVARIANCE)),
        Field::one("twist", Nested(&TWIST_WITH_COVARIANCE)),
    ],
};

/// PX4 v1.18 and later: `px4_msgs/msg/AuxGlobalPosition` (MESSAGE_VERSION 1).
pub const AUX_GLOBAL_POSITION: MsgType = MsgType {
    name: "px4_msgs/msg/AuxGlobalPosition",
    fields: &[
        Field::one("timestamp", UInt64),
        Field::one("timestamp_sample", UInt64),
        Field::one("id", UInt8),
        Field::one("source", UInt8),
        Field::one("lat", Float64),
        Field::one("lon", Float64),
        Field::one("alt", Float32),
        Field::one("eph", Float32),
        Field::one("epv", Float32),
        Field::one("lat_lon_reset_counter", UInt8),
    ],
};
/// PX4 v1.17: `aux_global_position` is a `VehicleGlobalPosition` (MESSAGE_VERSION 0).
pub const VEHICLE_GLOBAL_POSITION: MsgType = MsgType {
    name: "px4_msgs/msg/VehicleGlobalPosition",
    fields: &[
        Field::one("timestamp", UInt64),
        Field::one("timestamp_sample", UInt64),
        Field::one("lat", Float64),
        Field::one("lon", Float64),
        Field::one("alt", Float32),
        Field::one("alt_ellipsoid", Float32),
        Field::one("lat_lon_valid", Bool),
        Field::one("alt_valid", Bool),
        Field::one("delta_alt", Float32),
        Field::one("delta_terrain", Float32),
        Field::one("lat_lon_reset_counter", UInt8),
        Field::one("alt_reset_counter", UInt8),
        Field::one("terrain_reset_counter", UInt8),
        Field::one("eph", Float32),
        Field::one("epv", Float32),
        Field::one("terrain_alt", Float32),
        Field::one("terrain_alt_valid", Bool),
        Field::one("dead_reckoning", Bool),
    ],
};
/// `px4_msgs/msg/VehicleAttitude` (MESSAGE_VERSION 0, v1.17 and v1.18).
pub const VEHICLE_ATTITUDE: MsgType = MsgType {
    name: "px4_msgs/msg/VehicleAttitude",
    fields: &[
        Field::one("timestamp", UInt64),
        Field::one("timestamp_sample", UInt64),
        Field::array("q", Float32, 4),
        Field::array("delta_q_reset", Float32, 4),
        Field::one("quat_reset_counter", UInt8),
    ],
};

/// A ROS time stamp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Stamp {
    pub sec: i32,
    pub nanosec: u32,
}

impl Stamp {
    pub fn from_unix_us(us: u64) -> Self {
        Self {
            sec: (us / 1_000_000).min(i32::MAX as u64) as i32,
            nanosec: (us % 1_000_000) as u32 * 1000,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Header {
    pub stamp: Stamp,
    pub frame_id: std::string::String,
}

impl Header {
    fn write(&self, w: &mut CdrWriter) {
        w.i32(self.stamp.sec);
        w.u32(self.stamp.nanosec);
        w.string(&self.frame_id);
    }
}

/// `sensor_msgs/NavSatStatus` values.
pub mod nav_sat_status {
    pub const STATUS_NO_FIX: i8 = -1;
    pub const STATUS_FIX: i8 = 0;
    /// `position_covariance_type`: the full matrix is known.
    pub const COVARIANCE_TYPE_UNKNOWN: u8 = 0;
    pub const COVARIANCE_TYPE_KNOWN: u8 = 3;
}

#[derive(Debug, Clone, PartialEq)]
pub struct NavSatFix {
    pub header: Header,
    pub status: i8,
    pub service: u16,
    pub latitude: f64,
    pub longitude: f64,
    /// Above the WGS84 ellipsoid, metres.
    pub altitude: f64,
    /// East, north, up; row-major, m^2.
    pub position_covariance: [f64; 9],
    pub position_covariance_type: u8,
}

/// A pose with its 6x6 covariance (x, y, z, rotation about x, y, z; row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseWithCovariance {
    pub position: [f64; 3],
    /// x, y, z, w.
    pub orientation: [f64; 4],
    pub covariance: [f64; 36],
}

impl PoseWithCovariance {
    fn write(&self, w: &mut CdrWriter) {
        w.f64s(&self.position);
        w.f64s(&self.orientation);
        w.f64s(&self.covariance);
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct PoseWithCovarianceStamped {
    pub header: Header,
    pub pose: PoseWithCovariance,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Odometry {
    pub header: Header,
    pub child_frame_id: std::string::String,
    pub pose: PoseWithCovariance,
    /// In `child_frame_id`'s axes, m/s and rad/s.
    pub linear: [f64; 3],
    pub angular: [f64; 3],
    pub twist_covariance: [f64; 36],
}

/// A global position fix for PX4's EKF2 auxiliary global position fusion,
/// written as whichever message the autopilot's release takes.
#[derive(Debug, Clone, PartialEq)]
pub struct Px4GlobalPosition {
    /// The autopilot's clock, microseconds since its boot (PX4 stamps
    /// `timestamp` itself on arrival; `timestamp_sample` is what it fuses at).
    pub timestamp_us: u64,
    pub timestamp_sample_us: u64,
    /// This source's id among the autopilot's AGP sources.
    pub id: u8,
    /// Degrees; NaN tells PX4 to stop fusing at once.
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_amsl_m: f32,
    pub alt_ellipsoid_m: f32,
    pub eph_m: f32,
    pub epv_m: f32,
    pub lat_lon_reset_counter: u8,
}

/// `AuxGlobalPosition.SOURCE_VISION`.
pub const PX4_SOURCE_VISION: u8 = 2;

/// A message that goes out on a topic.
pub trait RosMessage {
    const TYPE: &'static MsgType;
    fn write(&self, w: &mut CdrWriter);
    fn to_cdr(&self, version: CdrVersion) -> Vec<u8> {
        let mut w = CdrWriter::new(version);
        self.write(&mut w);
        w.finish()
    }
}

impl RosMessage for NavSatFix {
    const TYPE: &'static MsgType = &NAV_SAT_FIX;
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.i8(self.status);
        w.u16(self.service);
        w.f64(self.latitude);
        w.f64(self.longitude);
        w.f64(self.altitude);
        w.f64s(&self.position_covariance);
        w.u8(self.position_covariance_type);
    }
}

impl RosMessage for PoseWithCovarianceStamped {
    const TYPE: &'static MsgType = &POSE_WITH_COVARIANCE_STAMPED;
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.pose.write(w);
    }
}

impl RosMessage for Odometry {
    const TYPE: &'static MsgType = &ODOMETRY;
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string(&self.child_frame_id);
        self.pose.write(w);
        w.f64s(&self.linear);
        w.f64s(&self.angular);
        w.f64s(&self.twist_covariance);
    }
}

/// Which message PX4's `/fmu/in/aux_global_position` takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Px4AuxMessage {
    /// `AuxGlobalPosition`: PX4 v1.18 and later.
    AuxGlobalPosition,
    /// `VehicleGlobalPosition`: PX4 v1.17.
    VehicleGlobalPosition,
}

impl Px4AuxMessage {
    pub fn msg_type(self) -> &'static MsgType {
        match self {
            Self::AuxGlobalPosition => &AUX_GLOBAL_POSITION,
            Self::VehicleGlobalPosition => &VEHICLE_GLOBAL_POSITION,
        }
    }
}

impl Px4GlobalPosition {
    pub fn to_cdr(&self, message: Px4AuxMessage, version: CdrVersion) -> Vec<u8> {
        let mut w = CdrWriter::new(version);
        w.u64(self.timestamp_us);
        w.u64(self.timestamp_sample_us);
        let valid = self.lat_deg.is_finite() && self.lon_deg.is_finite();
        match message {
            Px4AuxMessage::AuxGlobalPosition => {
                w.u8(self.id);
                w.u8(PX4_SOURCE_VISION);
                w.f64(self.lat_deg);
                w.f64(self.lon_deg);
                w.f32(self.alt_amsl_m);
                w.f32(self.eph_m);
                w.f32(self.epv_m);
                w.u8(self.lat_lon_reset_counter);
            }
            Px4AuxMessage::VehicleGlobalPosition => {
                w.f64(self.lat_deg);
                w.f64(self.lon_deg);
                w.f32(self.alt_amsl_m);
                w.f32(self.alt_ellipsoid_m);
                w.u8(u8::from(valid));
                w.u8(u8::from(valid && self.alt_amsl_m.is_finite()));
                w.f32(0.0); // delta_alt
                w.f32(0.0); // delta_terrain
                w.u8(self.lat_lon_reset_counter);
                w.u8(0); // alt_reset_counter
                w.u8(0); // terrain_reset_counter
                w.f32(self.eph_m);
                w.f32(self.epv_m);
                w.f32(f32::NAN); // terrain_alt
                w.u8(0); // terrain_alt_valid
                w.u8(0); // dead_reckoning
            }
        }
        w.finish()
    }
}

/// PX4's `vehicle_attitude`: the body's FRD axes in NED.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleAttitude {
    /// The autopilot's clock, microseconds since boot.
    pub timestamp_us: u64,
    pub timestamp_sample_us: u64,
    /// w, x, y, z (Hamilton), FRD body to NED.
    pub q: [f32; 4],
}

impl VehicleAttitude {
    /// Reads PX4's payload. Its Zenoh module writes XCDR2 under a `00 01`
    /// header; the fields here align the same in both flavours.
    pub fn from_cdr(payload: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(payload, Some(CdrVersion::Xcdr2))?;
        let timestamp_us = r.u64("timestamp")?;
        let timestamp_sample_us = r.u64("timestamp_sample")?;
        let mut q = [0.0; 4];
        for v in &mut q {
            *v = r.f32("q")?;
        }
        Ok(Self {
            timestamp_us,
            timestamp_sample_us,
            q,
        })
    }

    pub fn to_cdr(&self) -> Vec<u8> {
        let mut w = CdrWriter::new(CdrVersion::Xcdr1);
        w.u64(self.timestamp_us);
        w.u64(self.timestamp_sample_us);
        for v in self.q {
            w.f32(v);
        }
        for v in [1.0, 0.0, 0.0, 0.0] {
            w.f32(v);
        }
        w.u8(0);
        w.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn position() -> Px4GlobalPosition {
        Px4GlobalPosition {
            timestamp_us: 1,
            timestamp_sample_us: 2,
            id: 3,
            lat_deg: 30.5,
            lon_deg: 114.3,
            alt_amsl_m: 40.0,
            alt_ellipsoid_m: 30.0,
            eph_m: 1.5,
            epv_m: 2.5,
            lat_lon_reset_counter: 4,
        }
    }

    #[test]
    fn aux_global_position_places_lat_where_each_flavour_aligns_it() {
        let p = position();
        let x2 = p.to_cdr(Px4AuxMessage::AuxGlobalPosition, CdrVersion::Xcdr2);
        let x1 = p.to_cdr(Px4AuxMessage::AuxGlobalPosition, CdrVersion::Xcdr1);
        // Body: two u64, id, source, then lat at 20 (XCDR2) or 24 (XCDR1).
        assert_eq!(&x2[4 + 16..4 + 18], &[3, PX4_SOURCE_VISION]);
        assert_eq!(&x2[4 + 20..4 + 28], &30.5f64.to_le_bytes());
        assert_eq!(&x1[4 + 24..4 + 32], &30.5f64.to_le_bytes());
        assert_eq!(x2.len(), 4 + 20 + 16 + 12 + 1);
        assert_eq!(x1.len(), 4 + 24 + 16 + 12 + 1);
    }

    /// The same values as pycdr2 (Cyclone DDS's IDL layer) writes them.
    #[test]
    fn aux_global_position_is_byte_for_byte_what_cyclone_writes() {
        let p = Px4GlobalPosition {
            timestamp_us: 1,
            timestamp_sample_us: 2,
            id: 3,
            lat_deg: 30.5,
            lon_deg: 114.3,
            alt_amsl_m: 40.0,
            alt_ellipsoid_m: 0.0,
            eph_m: 1.5,
            epv_m: 2.5,
            lat_lon_reset_counter: 4,
        };
        let hex = |b: Vec<u8>| {
            b.iter()
                .map(|x| format!("{x:02x}"))
                .collect::<std::string::String>()
        };
        assert_eq!(
            hex(p.to_cdr(Px4AuxMessage::AuxGlobalPosition, CdrVersion::Xcdr2)),
            "000700000100000000000000020000000000000003020000000000000080\
             3e403333333333935c40000020420000c03f0000204004"
        );
        assert_eq!(
            hex(p.to_cdr(Px4AuxMessage::AuxGlobalPosition, CdrVersion::Xcdr1)),
            "000100000100000000000000020000000000000003020000000000000000\
             000000803e403333333333935c40000020420000c03f0000204004"
        );
    }

    #[test]
    fn vehicle_global_position_is_the_same_in_both_flavours() {
        let p = position();
        let x2 = p.to_cdr(Px4AuxMessage::VehicleGlobalPosition, CdrVersion::Xcdr2);
        let x1 = p.to_cdr(Px4AuxMessage::VehicleGlobalPosition, CdrVersion::Xcdr1);
        assert_eq!(x1[4..], x2[4..]);
        assert_eq!(x1.len(), 4 + 70);
    }

    #[test]
    fn vehicle_attitude_reads_back() {
        let a = VehicleAttitude {
            timestamp_us: 123_456_789,
            timestamp_sample_us: 123_456_000,
            q: [0.5, 0.5, -0.5, 0.5],
        };
        assert_eq!(VehicleAttitude::from_cdr(&a.to_cdr()), Ok(a));
        assert!(VehicleAttitude::from_cdr(&a.to_cdr()[..20]).is_err());
    }

    #[test]
    fn nav_sat_fix_is_as_long_as_its_fields() {
        let fix = NavSatFix {
            header: Header {
                stamp: Stamp::from_unix_us(1_700_000_000_250_000),
                frame_id: "map".into(),
            },
            status: 0,
            service: 0,
            latitude: 1.0,
            longitude: 2.0,
            altitude: 3.0,
            position_covariance: [0.0; 9],
            position_covariance_type: nav_sat_status::COVARIANCE_TYPE_KNOWN,
        };
        let bytes = fix.to_cdr(CdrVersion::Xcdr1);
        // stamp 8, "map" 4+4, status 1, pad 1, service 2, pad 4, 3 + 9 doubles, type 1.
        assert_eq!(bytes.len(), 4 + 8 + 8 + 4 + 4 + 96 + 1);
        assert_eq!(&bytes[8..12], &250_000_000u32.to_le_bytes());
    }
}
