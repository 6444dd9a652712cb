//! A deterministic, seeded tower field and flight with exact truth, a renderer
//! that draws what the camera sees, and an oracle detector that perturbs the
//! truth like a real one would.
//!
//! Pure: no I/O, no clocks, no global state. Same seed, same frames.

pub mod barometer;
pub mod flight;
pub mod gnss;
pub mod landmark_world;
pub mod mot;
pub mod oracle;
pub mod quadrotor;
pub mod render;
pub mod replay;
pub mod scenario;
pub mod tower_model;
pub mod truth;
pub mod viewpoint;
pub mod waypoints;
pub mod world;

pub use barometer::{Barometer, BarometerParams};
pub use flight::{Flight, StraightFlight};
pub use oracle::{OracleDetector, OracleParams};
pub use render::lens::LensEffects;
pub use render::{Backdrop, Conditions, FrameBuffers, Renderer, TowerPaint};
pub use scenario::Scenario;
pub use truth::{FrameTruth, TruthBox};
pub use world::{SimTower, World};
