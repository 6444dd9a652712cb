//! "Towers within R metres of a point": an R-tree over Earth-centred (ECEF)
//! points. Here, not in the database, so that the edge's core uses it without SQLite.
//!
//! ECEF keeps one index valid anywhere on Earth; for the radii an edge asks
//! (a few km) the chord length differs from the ground distance by under a millimetre.

use crate::Geodetic;
use rstar::RTree;
use rstar::primitives::GeomWithData;

type Entry = GeomWithData<[f64; 3], usize>;

/// A read-only index over a set of points; rebuild it when the set changes.
pub struct GeoIndex {
    tree: RTree<Entry>,
}

impl GeoIndex {
    /// Results index into `points`.
    pub fn from_points(points: &[Geodetic]) -> Self {
        let entries = points
            .iter()
            .enumerate()
            .map(|(i, p)| GeomWithData::new(p.to_ecef(), i))
            .collect();
        Self {
            tree: RTree::bulk_load(entries),
        }
    }

    pub fn len(&self) -> usize {
        self.tree.size()
    }

    pub fn is_empty(&self) -> bool {
        self.tree.size() == 0
    }

    /// Points from the nearest outwards, lazily: the nearest few cost a
    /// logarithmic walk however many stand at one spot.
    pub fn nearest(&self, point: &Geodetic) -> impl Iterator<Item = (usize, f64)> + '_ {
        let p = point.to_ecef();
        self.tree
            .nearest_neighbor_iter(p)
            .map(move |e| (e.data, distance(e.geom(), &p)))
    }

    /// Indices (into the points the index was built from) of those within
    /// `radius_m` of `point`, nearest first, with their distances.
    pub fn within(&self, point: &Geodetic, radius_m: f64) -> Vec<(usize, f64)> {
        let p = point.to_ecef();
        let mut hits: Vec<(usize, f64)> = self
            .tree
            .locate_within_distance(p, radius_m * radius_m)
            .map(|e| (e.data, distance(e.geom(), &p)))
            .collect();
        hits.sort_by(|a, b| a.1.total_cmp(&b.1));
        hits
    }
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The index returns exactly what a brute-force scan over the same distance returns.
        #[test]
        fn agrees_with_brute_force(
            lat0 in -60.0f64..60.0, lon0 in -170.0f64..170.0,
            offsets in proptest::collection::vec((-0.05f64..0.05, -0.05f64..0.05), 1..200),
            radius in 100.0f64..5000.0,
        ) {
            let points: Vec<Geodetic> = offsets.iter()
                .map(|(dlat, dlon)| Geodetic { lat_deg: lat0 + dlat, lon_deg: lon0 + dlon, height_m: 10.0 })
                .collect();
            let index = GeoIndex::from_points(&points);
            let query = Geodetic { lat_deg: lat0, lon_deg: lon0, height_m: 10.0 };
            let got: Vec<usize> = index.within(&query, radius).into_iter().map(|(i, _)| i).collect();
            let q = query.to_ecef();
            let mut want: Vec<(usize, f64)> = points.iter().enumerate()
                .map(|(i, p)| (i, distance(&p.to_ecef(), &q)))
                .filter(|(_, d)| *d <= radius)
                .collect();
            want.sort_by(|a, b| a.1.total_cmp(&b.1));
            prop_assert_eq!(got, want.into_iter().map(|(i, _)| i).collect::<Vec<_>>());
        }
    }
}
