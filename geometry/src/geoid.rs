//! Heights above mean sea level: the EGM96 geoid's height above the WGS84
//! ellipsoid (its spherical-harmonic model to degree 360, from the `egm96`
//! crate's NGA coefficients; no grid file, nothing read at run time).
//!
//! Autopilots take GNSS altitude as MSL (GPS_INPUT's `alt`), while towernav's
//! geodesy is ellipsoidal: MSL = ellipsoidal height - geoid height. The two
//! differ by up to about 100 m on Earth.

/// The geoid's height above the WGS84 ellipsoid at a place, metres (EGM96).
pub fn geoid_height_m(lat_deg: f64, lon_deg: f64) -> f64 {
    egm96::egm96_compute_altitude_offset(lat_deg, lon_deg)
}

/// Height above mean sea level from a height above the ellipsoid.
pub fn msl_from_ellipsoid_m(lat_deg: f64, lon_deg: f64, ellipsoid_m: f64) -> f64 {
    ellipsoid_m - geoid_height_m(lat_deg, lon_deg)
}

/// The geoid height of the last place asked, reused while the next is within
/// `reuse_m` of it: the model's sum takes about a millisecond, while the geoid
/// moves by centimetres over hundreds of metres.
#[derive(Debug, Clone)]
pub struct GeoidCache {
    reuse_m: f64,
    last: Option<(f64, f64, f64)>,
}

impl GeoidCache {
    pub fn new(reuse_m: f64) -> Self {
        Self {
            reuse_m,
            last: None,
        }
    }

    /// The geoid height at (lat, lon), metres.
    pub fn height_m(&mut self, lat_deg: f64, lon_deg: f64) -> f64 {
        if let Some((lat, lon, n)) = self.last {
            // Small-angle distance: exact enough for a reuse radius.
            let north = (lat_deg - lat).to_radians() * 6_371_000.0;
            let east = (lon_deg - lon).to_radians() * 6_371_000.0 * lat.to_radians().cos();
            if north.hypot(east) <= self.reuse_m {
                return n;
            }
        }
        let n = geoid_height_m(lat_deg, lon_deg);
        self.last = Some((lat_deg, lon_deg, n));
        n
    }
}

impl Default for GeoidCache {
    /// Reuse within 200 m.
    fn default() -> Self {
        Self::new(200.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The test points and undulations that NGA distributes with its EGM96
    /// geoid program F477 (`INPUT.DAT` / `OUTINTPT.DAT`, longitudes east
    /// 0-360), computed by NGA's Fortran, not by the crate used here.
    const NGA_F477: [(f64, f64, f64); 6] = [
        (38.628155, 269.779155, -31.628),
        (-14.621217, 305.021114, -2.969),
        (46.874319, 102.448729, -43.575),
        (-23.617446, 133.874712, 15.871),
        (38.625473, 359.999500, 50.066),
        (-0.466744, 0.002300, 17.329),
    ];

    #[test]
    fn geoid_heights_match_nga_s_own_program() {
        for (lat, lon, expected) in NGA_F477 {
            let n = geoid_height_m(lat, lon);
            assert!(
                (n - expected).abs() < 0.01,
                "({lat}, {lon}): {n:.3} m, NGA {expected} m"
            );
        }
    }

    #[test]
    fn msl_is_the_ellipsoidal_height_less_the_geoid() {
        // Near Wuhan, where the paper flew, the geoid lies below the ellipsoid.
        let (lat, lon) = (30.52, 114.36);
        let n = geoid_height_m(lat, lon);
        assert!(n < -5.0, "{n}");
        assert!((msl_from_ellipsoid_m(lat, lon, 100.0) - (100.0 - n)).abs() < 1e-9);
    }

    #[test]
    fn the_cache_reuses_nearby_and_recomputes_far() {
        let mut cache = GeoidCache::new(200.0);
        let a = cache.height_m(46.0, 102.0);
        // 100 m north: the cached value.
        assert_eq!(cache.height_m(46.0009, 102.0), a);
        // 50 km away: a new value, equal to the direct sum.
        let far = cache.height_m(46.5, 102.0);
        assert_eq!(far, geoid_height_m(46.5, 102.0));
        assert_ne!(far, a);
    }
}
