//! A deterministic, seeded tower field and flight with exact truth, and an
//! oracle detector that perturbs the truth like a real one would.
//!
//! Pure: no I/O, no clocks, no global state. Same seed, same frames.

pub mod flight;
pub mod oracle;
pub mod scenario;
pub mod truth;
pub mod world;

pub use flight::StraightFlight;
pub use oracle::{OracleDetector, OracleParams};
pub use scenario::Scenario;
pub use truth::{FrameTruth, TruthBox};
pub use world::{SimTower, World};
