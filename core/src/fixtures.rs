//! Test fixtures shared by the core's unit tests.

use nalgebra::Point3;
use towernav_geometry::{Datum, Geodetic, PixelBox};
use towernav_protocol::{Detection, TowerType};

use crate::landmarks::{LandmarkMap, MapTower};

/// A surveyed type-B tower at (x, y) on the ground, `h` metres tall, exactly placed.
pub fn tower(id: &str, x: f64, y: f64, h: f64) -> MapTower {
    MapTower {
        id: id.into(),
        tower_type: TowerType::B,
        foot_in_world: Point3::new(x, y, 0.0),
        height_m: h,
        sigma_horizontal_m: 0.0,
        sigma_vertical_m: 0.0,
    }
}

/// The towers as a map about a datum near Chengdu.
pub fn map(towers: Vec<MapTower>) -> LandmarkMap {
    let datum = Datum::new(Geodetic::new(30.6, 104.0, 500.0).expect("a valid datum"));
    LandmarkMap::new(towers, datum)
}

/// A 30x200 px box from column `x`, rows 100 to 300, of type `t`, scoring `score`.
pub fn det(x: f64, t: TowerType, score: f64) -> Detection {
    Detection {
        bbox: PixelBox::new(x, 100.0, x + 30.0, 300.0),
        tower_type: t,
        score,
    }
}
