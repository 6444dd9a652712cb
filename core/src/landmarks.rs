//! The database towers in the mission's ENU world, ready for projection, with the
//! landmark database's radius query to pick the ones near the UAV.

use std::sync::Arc;

use nalgebra::{Point3, Vector3};
use towernav_geometry::{Datum, GeoIndex, Geodetic};
use towernav_protocol::{LandmarkRecord, TowerType};

#[derive(Debug, Clone, PartialEq)]
pub struct MapTower {
    pub id: String,
    pub tower_type: TowerType,
    pub foot_in_world: Point3<f64>,
    pub height_m: f64,
    /// One-sigma survey accuracy of the foot's position, horizontal and vertical (metres).
    pub sigma_horizontal_m: f64,
    pub sigma_vertical_m: f64,
}

/// Survey accuracy assumed when a record states none: a careful GNSS survey.
pub const DEFAULT_SURVEY_SIGMA_M: f64 = 0.5;

impl MapTower {
    pub fn top_in_world(&self) -> Point3<f64> {
        self.foot_in_world + Vector3::new(0.0, 0.0, self.height_m)
    }
}

/// How a detector's classes meet the database's tower types.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TypeMatch {
    /// Every database type is one of the detector's classes: identity
    /// binds a box only to towers of its type.
    Typed,
    /// A one-class detector (`tower`): every tower is taken as that class,
    /// and identity binds by geometry alone.
    Untyped(TowerType),
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "the landmark database's tower types {missing:?} are not classes of the detector, whose classes are {classes:?}; \
     train it on those types, or use a one-class model to bind by geometry alone"
)]
pub struct TypeMismatch {
    pub missing: Vec<String>,
    pub classes: Vec<String>,
}

/// Check `records`' types against a detector's `classes`: a one-class
/// detector matches any database; else every stored type must be a class.
pub fn match_types(
    classes: &[TowerType],
    records: &[LandmarkRecord],
) -> Result<TypeMatch, TypeMismatch> {
    if let [only] = classes {
        return Ok(TypeMatch::Untyped(*only));
    }
    let mut missing: Vec<String> = records
        .iter()
        .filter(|r| !classes.contains(&r.tower_type))
        .map(|r| r.tower_type.to_string())
        .collect();
    missing.sort();
    missing.dedup();
    if missing.is_empty() {
        Ok(TypeMatch::Typed)
    } else {
        Err(TypeMismatch {
            missing,
            classes: classes.iter().map(|c| c.to_string()).collect(),
        })
    }
}

#[derive(Clone)]
pub struct LandmarkMap {
    pub towers: Vec<MapTower>,
    datum: Datum,
    /// Shared so that cloning a map (replays, benches) does not rebuild the tree.
    index: Arc<GeoIndex>,
}

impl std::fmt::Debug for LandmarkMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LandmarkMap")
            .field("towers", &self.towers)
            .field("datum", &self.datum)
            .finish()
    }
}

impl PartialEq for LandmarkMap {
    fn eq(&self, other: &Self) -> bool {
        self.towers == other.towers && self.datum == other.datum
    }
}

impl LandmarkMap {
    pub fn new(towers: Vec<MapTower>, datum: Datum) -> Self {
        let feet: Vec<Geodetic> = towers
            .iter()
            .map(|t| datum.to_geodetic(&t.foot_in_world))
            .collect();
        Self {
            index: Arc::new(GeoIndex::from_points(&feet)),
            towers,
            datum,
        }
    }

    /// The map as a detector of `types` sees it: with a one-class detector,
    /// every tower is of its one class.
    pub fn matched(mut self, types: TypeMatch) -> Self {
        if let TypeMatch::Untyped(class) = types {
            for t in &mut self.towers {
                t.tower_type = class;
            }
        }
        self
    }

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
                sigma_horizontal_m: r.sigma_horizontal_m.unwrap_or(DEFAULT_SURVEY_SIGMA_M),
                sigma_vertical_m: r.sigma_vertical_m.unwrap_or(DEFAULT_SURVEY_SIGMA_M),
            })
            .collect();
        Self::new(towers, *datum)
    }

    /// The geodetic origin of the map's world frame.
    pub fn datum(&self) -> &Datum {
        &self.datum
    }

    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.towers.iter().position(|t| t.id == id)
    }

    /// Towers whose foot lies within `radius_m` of a point, nearest first.
    pub fn nearby(&self, point_in_world: &Point3<f64>, radius_m: f64) -> Vec<usize> {
        let here = self.datum.to_geodetic(point_in_world);
        self.index
            .within(&here, radius_m)
            .into_iter()
            .map(|(i, _)| i)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearby_finds_the_towers_within_range_nearest_first() {
        let datum = Datum::new(Geodetic {
            lat_deg: 30.5,
            lon_deg: 114.3,
            height_m: 20.0,
        });
        let tower = |id: &str, x: f64| MapTower {
            id: id.into(),
            tower_type: TowerType::A,
            foot_in_world: Point3::new(x, 0.0, 0.0),
            height_m: 30.0,
            sigma_horizontal_m: 0.0,
            sigma_vertical_m: 0.0,
        };
        let map = LandmarkMap::new(
            vec![
                tower("far", 3000.0),
                tower("near", 100.0),
                tower("mid", 900.0),
            ],
            datum,
        );
        assert_eq!(map.nearby(&Point3::new(0.0, 0.0, 30.0), 1000.0), [1, 2]);
    }

    #[test]
    fn a_one_class_detector_matches_any_database_and_others_need_every_type() {
        let lattice = TowerType::new("lattice").expect("name");
        let portal = TowerType::new("portal").expect("name");
        let records = [
            LandmarkRecord::new("T1", lattice, 30.5, 114.3, 20.0, 40.0),
            LandmarkRecord::new("T2", portal, 30.51, 114.3, 20.0, 25.0),
            LandmarkRecord::new("T3", portal, 30.52, 114.3, 20.0, 25.0),
        ];
        let tower = TowerType::new("tower").expect("name");
        assert_eq!(
            match_types(&[tower], &records),
            Ok(TypeMatch::Untyped(tower))
        );
        assert_eq!(
            match_types(&[portal, lattice], &records),
            Ok(TypeMatch::Typed)
        );
        let err = match_types(&TowerType::ALL, &records).expect_err("A-D only");
        assert_eq!(err.missing, ["lattice", "portal"]);
        let text = err.to_string();
        assert!(
            text.contains("\"portal\"") && text.contains("\"D\""),
            "{text}"
        );

        let datum = Datum::new(Geodetic {
            lat_deg: 30.5,
            lon_deg: 114.3,
            height_m: 20.0,
        });
        let map = LandmarkMap::from_records(&records, &datum).matched(TypeMatch::Untyped(tower));
        assert!(map.towers.iter().all(|t| t.tower_type == tower));
        let typed = LandmarkMap::from_records(&records, &datum).matched(TypeMatch::Typed);
        assert_eq!(typed.towers[1].tower_type, portal);
    }
}
