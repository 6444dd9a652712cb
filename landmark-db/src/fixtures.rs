//! Towers shared by the database's unit tests.

use towernav_protocol::{LandmarkRecord, TowerType};

/// A type-B tower at `lat_deg` (longitude 114.3, ground 20 m), `height_m` tall.
pub fn tower_at(id: &str, lat_deg: f64, height_m: f64) -> LandmarkRecord {
    LandmarkRecord::new(id, TowerType::B, lat_deg, 114.3, 20.0, height_m)
}

/// A 38 m type-B tower at the fixtures' spot.
pub fn tower(id: &str) -> LandmarkRecord {
    tower_at(id, 30.5, 38.0)
}

/// A tower as a survey crew enters it: notes and a horizontal sigma.
pub fn surveyed(id: &str, height_m: f64) -> LandmarkRecord {
    LandmarkRecord {
        notes: "survey 2026".into(),
        sigma_horizontal_m: Some(0.05),
        ..tower_at(id, 30.5, height_m)
    }
}
