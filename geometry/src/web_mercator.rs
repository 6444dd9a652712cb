//! Web Mercator map tiles (the slippy-map scheme: `zoom/x/y`), for drawing
//! local tile folders under a map in the world frame.

/// Web Mercator's latitude limit, degrees: the world's square ends here.
pub const MAX_LAT_DEG: f64 = 85.051_128_779_806_59;

/// The slippy-map tile holding a point, at `zoom`.
pub fn tile_of(lat_deg: f64, lon_deg: f64, zoom: u8) -> (u32, u32) {
    let n = f64::from(1u32 << zoom);
    let x = (lon_deg + 180.0) / 360.0 * n;
    let lat = lat_deg.clamp(-MAX_LAT_DEG, MAX_LAT_DEG).to_radians();
    let y = (1.0 - (lat.tan() + 1.0 / lat.cos()).ln() / std::f64::consts::PI) / 2.0 * n;
    let last = n - 1.0;
    (
        x.floor().clamp(0.0, last) as u32,
        y.floor().clamp(0.0, last) as u32,
    )
}

/// The north-west corner of a tile, (latitude, longitude) in degrees.
pub fn tile_corner(x: u32, y: u32, zoom: u8) -> (f64, f64) {
    let n = f64::from(1u32 << zoom);
    let lon = f64::from(x) / n * 360.0 - 180.0;
    let lat = (std::f64::consts::PI * (1.0 - 2.0 * f64::from(y) / n))
        .sinh()
        .atan()
        .to_degrees();
    (lat, lon)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Every point lies inside the tile that holds it, at every zoom.
        #[test]
        fn a_point_lies_inside_its_tile(
            lat in -85.0f64..85.0, lon in -180.0f64..179.999, zoom in 0u8..=19,
        ) {
            let (x, y) = tile_of(lat, lon, zoom);
            let (north, west) = tile_corner(x, y, zoom);
            let (south, east) = tile_corner(x + 1, y + 1, zoom);
            prop_assert!(west <= lon + 1e-9 && lon < east + 1e-9, "{west} {lon} {east}");
            prop_assert!(south - 1e-9 < lat && lat <= north + 1e-9, "{south} {lat} {north}");
        }
    }

    #[test]
    fn zoom_zero_is_one_tile_and_the_poles_clamp_to_the_edge_rows() {
        assert_eq!(tile_of(45.0, 100.0, 0), (0, 0));
        assert_eq!(tile_of(89.9, 0.0, 4), (8, 0));
        assert_eq!(tile_of(-89.9, 0.0, 4), (8, 15));
        // Zoom 16 over central Wuhan, as the OSM wiki formula gives it.
        assert_eq!(tile_of(30.5205, 114.3601, 16), (53586, 26928));
    }
}
