//! WGS84 geodetic <-> local east-north-up about a datum.
//!
//! The arithmetic is `map_3d`'s; this module fixes the ellipsoid, the units
//! (degrees at the edges, metres) and the one datum type the project passes around.

use map_3d::Ellipsoid;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};

/// A WGS84 position: latitude and longitude in degrees, height in metres above the ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Geodetic {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub height_m: f64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeodesyError {
    #[error("latitude {0} deg is not between -90 and 90")]
    Latitude(f64),
    #[error("longitude {0} deg is not between -180 and 180")]
    Longitude(f64),
    #[error("height {0} m is not a finite number")]
    Height(f64),
}

impl Geodetic {
    pub fn new(lat_deg: f64, lon_deg: f64, height_m: f64) -> Result<Self, GeodesyError> {
        if !(-90.0..=90.0).contains(&lat_deg) {
            return Err(GeodesyError::Latitude(lat_deg));
        }
        if !(-180.0..=180.0).contains(&lon_deg) {
            return Err(GeodesyError::Longitude(lon_deg));
        }
        if !height_m.is_finite() {
            return Err(GeodesyError::Height(height_m));
        }
        Ok(Self {
            lat_deg,
            lon_deg,
            height_m,
        })
    }
}

impl Geodetic {
    /// Earth-centred, Earth-fixed position, metres: one frame valid anywhere, for spatial indexing.
    pub fn to_ecef(&self) -> [f64; 3] {
        let (x, y, z) = map_3d::geodetic2ecef(
            self.lat_deg.to_radians(),
            self.lon_deg.to_radians(),
            self.height_m,
            Ellipsoid::WGS84,
        );
        [x, y, z]
    }
}

/// The origin of a local ENU world frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Datum {
    pub origin: Geodetic,
}

impl Datum {
    pub fn new(origin: Geodetic) -> Self {
        Self { origin }
    }

    pub fn to_enu(&self, g: &Geodetic) -> Point3<f64> {
        let o = &self.origin;
        let (e, n, u) = map_3d::geodetic2enu(
            g.lat_deg.to_radians(),
            g.lon_deg.to_radians(),
            g.height_m,
            o.lat_deg.to_radians(),
            o.lon_deg.to_radians(),
            o.height_m,
            Ellipsoid::WGS84,
        );
        Point3::new(e, n, u)
    }

    pub fn to_geodetic(&self, point_in_world: &Point3<f64>) -> Geodetic {
        let o = &self.origin;
        let (lat, lon, h) = map_3d::enu2geodetic(
            point_in_world.x,
            point_in_world.y,
            point_in_world.z,
            o.lat_deg.to_radians(),
            o.lon_deg.to_radians(),
            o.height_m,
            Ellipsoid::WGS84,
        );
        Geodetic {
            lat_deg: lat.to_degrees(),
            lon_deg: lon.to_degrees(),
            height_m: h,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// MathWorks' geodetic2enu reference: the Matterhorn seen from Zermatt (WGS84),
    /// published as xEast = -7134.8, yNorth = -4556.3, zUp = 2852.4 m.
    #[test]
    fn matterhorn_from_zermatt_matches_published_enu() {
        let zermatt = Datum::new(Geodetic::new(46.017, 7.750, 1673.0).expect("valid"));
        let matterhorn = Geodetic::new(45.976, 7.658, 4531.0).expect("valid");
        let enu = zermatt.to_enu(&matterhorn);
        assert!((enu.x - -7134.8).abs() < 0.5, "east {}", enu.x);
        assert!((enu.y - -4556.3).abs() < 0.5, "north {}", enu.y);
        assert!((enu.z - 2852.4).abs() < 0.5, "up {}", enu.z);
    }

    /// On the equator one degree of longitude is a*pi/180 = 111319.49 m (WGS84 a = 6378137 m).
    #[test]
    fn one_degree_of_longitude_on_the_equator() {
        let datum = Datum::new(Geodetic::new(0.0, 0.0, 0.0).expect("valid"));
        let enu = datum.to_enu(&Geodetic::new(0.0, 0.001, 0.0).expect("valid"));
        assert!((enu.x - 111.31949).abs() < 1e-3, "east {}", enu.x);
        assert!(enu.y.abs() < 1e-6);
    }

    /// WGS84: a = 6378137 m on the equator, b = 6356752.3142 m at the pole.
    #[test]
    fn ecef_of_the_equator_and_the_pole() {
        let e = Geodetic::new(0.0, 90.0, 0.0).expect("valid").to_ecef();
        assert!(e[0].abs() < 1e-6 && (e[1] - 6_378_137.0).abs() < 1e-6 && e[2].abs() < 1e-6);
        let p = Geodetic::new(90.0, 0.0, 0.0).expect("valid").to_ecef();
        assert!((p[2] - 6_356_752.314_2).abs() < 1e-3, "{p:?}");
    }

    #[test]
    fn out_of_range_coordinates_are_refused() {
        assert_eq!(
            Geodetic::new(91.0, 0.0, 0.0),
            Err(GeodesyError::Latitude(91.0))
        );
        assert_eq!(
            Geodetic::new(0.0, 181.0, 0.0),
            Err(GeodesyError::Longitude(181.0))
        );
        assert!(Geodetic::new(0.0, 0.0, f64::NAN).is_err());
    }

    proptest! {
        #[test]
        fn enu_round_trip_is_millimetre_exact(lat0 in -80.0f64..80.0, lon0 in -179.0f64..179.0,
                                              e in -5000.0f64..5000.0, n in -5000.0f64..5000.0, u in -100.0f64..500.0) {
            let datum = Datum::new(Geodetic::new(lat0, lon0, 100.0).expect("valid"));
            let p = Point3::new(e, n, u);
            let back = datum.to_enu(&datum.to_geodetic(&p));
            prop_assert!((back - p).norm() < 1e-3, "{p} -> {back}");
        }
    }
}
