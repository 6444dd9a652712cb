//! The seed's field: 18 lattice towers of four types on a flat 1000 m x 500 m plate.

use nalgebra::Point3;
use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{LandmarkRecord, TowerType};

#[derive(Debug, Clone, PartialEq)]
pub struct SimTower {
    pub id: String,
    pub tower_type: TowerType,
    /// Foot of the tower axis, where the base diagonals cross.
    pub foot_in_world: Point3<f64>,
    pub height_m: f64,
    pub base_width_m: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct World {
    pub datum: Datum,
    pub towers: Vec<SimTower>,
}

/// Per type: line north coordinate, east positions, height, base width.
const SEED_LINES: [(TowerType, f64, &[f64], f64, f64); 4] = [
    (
        TowerType::A,
        300.0,
        &[120.0, 320.0, 520.0, 720.0, 920.0],
        32.0,
        6.0,
    ),
    (
        TowerType::B,
        200.0,
        &[80.0, 280.0, 480.0, 680.0, 880.0],
        38.0,
        7.0,
    ),
    (
        TowerType::C,
        400.0,
        &[150.0, 400.0, 650.0, 900.0],
        45.0,
        8.0,
    ),
    (
        TowerType::D,
        100.0,
        &[100.0, 350.0, 600.0, 850.0],
        52.0,
        9.0,
    ),
];

impl World {
    /// The plate's south-west corner is the datum; east is +x, north is +y.
    /// A and B stand 50 m either side of the centre line, C and D 150 m out.
    pub fn seed_field() -> Self {
        let datum = Datum::new(Geodetic {
            lat_deg: 30.52,
            lon_deg: 114.36,
            height_m: 25.0,
        });
        let towers = SEED_LINES
            .iter()
            .flat_map(|&(tower_type, north, easts, height_m, base_width_m)| {
                easts.iter().enumerate().map(move |(i, &east)| SimTower {
                    id: format!("{tower_type}{}", i + 1),
                    tower_type,
                    foot_in_world: Point3::new(east, north, 0.0),
                    height_m,
                    base_width_m,
                })
            })
            .collect();
        Self { datum, towers }
    }

    /// The towers as surveyed landmarks, in WGS84, for the database.
    pub fn landmarks(&self) -> Vec<LandmarkRecord> {
        self.towers
            .iter()
            .map(|t| {
                let g = self.datum.to_geodetic(&t.foot_in_world);
                LandmarkRecord {
                    base_width_m: Some(t.base_width_m),
                    survey_source: Some("towernav-sim seed field".into()),
                    sigma_horizontal_m: Some(0.0),
                    sigma_vertical_m: Some(0.0),
                    ..LandmarkRecord::new(
                        &t.id,
                        t.tower_type,
                        g.lat_deg,
                        g.lon_deg,
                        g.height_m,
                        t.height_m,
                    )
                }
            })
            .collect()
    }

    pub fn tower(&self, id: &str) -> Option<&SimTower> {
        self.towers.iter().find(|t| t.id == id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seed_field_has_18_towers_of_4_types_on_the_plate() {
        let world = World::seed_field();
        assert_eq!(world.towers.len(), 18);
        for t in TowerType::ALL {
            assert!(world.towers.iter().any(|x| x.tower_type == t));
        }
        assert!(
            world
                .towers
                .iter()
                .all(|t| (0.0..=1000.0).contains(&t.foot_in_world.x)
                    && (0.0..=500.0).contains(&t.foot_in_world.y))
        );
    }

    #[test]
    fn landmarks_map_back_onto_the_plate() {
        let world = World::seed_field();
        for (tower, record) in world.towers.iter().zip(world.landmarks()) {
            let g =
                Geodetic::new(record.lat_deg, record.lon_deg, record.ground_elev_m).expect("valid");
            let back = world.datum.to_enu(&g);
            assert!((back - tower.foot_in_world).norm() < 1e-3, "{}", tower.id);
        }
    }
}
