//! The edge's fix as ROS 2 and PX4 see it over Zenoh: rmw_zenoh's keys,
//! liveliness tokens and attachments, ROS 2 type hashes, CDR payloads of
//! `sensor_msgs/NavSatFix`, `geometry_msgs/PoseWithCovarianceStamped`,
//! `nav_msgs/Odometry` and PX4's auxiliary global position, and PX4's
//! `vehicle_attitude` read back.

pub mod cdr;
pub mod msgs;
pub mod rmw_zenoh;
pub mod type_hash;
