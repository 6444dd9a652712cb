//! The database towers in the mission's ENU world, ready for projection.

use nalgebra::{Point3, Vector3};
use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{LandmarkRecord, TowerType};

#[derive(Debug, Clone, PartialEq)]
pub struct MapTower {
    pub id: String,
    pub tower_type: TowerType,
    pub foot_in_world: Point3<f64>,
    pub height_m: f64,
}

impl MapTower {
    pub fn top_in_world(&self) -> Point3<f64> {
        self.foot_in_world + Vector3::new(0.0, 0.0, self.height_m)
    }
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct LandmarkMap {
    pub towers: Vec<MapTower>,
}

impl LandmarkMap {
    /// Records are expected to be validated (the database does so on every write).
    pub fn from_records(records: &[LandmarkRecord], datum: &Datum) -> Self {
        let towers = records
            .iter()
            .map(|r| MapTower {
                id: r.id.clone(),
                tower_type: r.tower_type,
                foot_in_world: datum.to_enu(&Geodetic {
                    lat_deg: r.lat_deg,
                    lon_deg: r.lon_deg,
                    height_m: r.ground_elev_m,
                }),
                height_m: r.height_m,
            })
            .collect();
        Self { towers }
    }

    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.towers.iter().position(|t| t.id == id)
    }
}
