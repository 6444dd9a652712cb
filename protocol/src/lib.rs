//! Everything that crosses the wire between towernav nodes: message types,
//! their JSON codec with a schema version, and the Zenoh key expressions.
//!
//! No other crate defines a wire type or formats a key; see README.md for the
//! format as a Python or C++ client sees it.

pub mod codec;
pub mod ids;
pub mod keys;
pub mod messages;
pub mod on_key;
pub mod ros2;
#[cfg(feature = "zenoh")]
pub mod security;
#[cfg(feature = "zenoh")]
pub mod session;
pub mod tower_type;

pub use codec::{DecodeError, EncodeError, Message, SCHEMA_VERSION, decode, encode};
pub use ids::{IdError, NodeId};
pub use keys::{KeyError, Keys, Topic, UavKey, UavMessage};
pub use messages::*;
pub use on_key::{OnKeyError, decode_on_key};
