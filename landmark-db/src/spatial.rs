//! "Towers within R metres of a point": an R-tree over Earth-centred (ECEF) points.
//!
//! ECEF keeps one index valid anywhere on Earth; for the radii an edge asks
//! (a few km) the chord length differs from the ground distance by under a millimetre.

use rstar::RTree;
use rstar::primitives::GeomWithData;
use towernav_geometry::Geodetic;
use towernav_protocol::LandmarkRecord;

type Entry = GeomWithData<[f64; 3], usize>;

/// A read-only index over a set of towers; rebuild it when the set changes.
pub struct LandmarkIndex {
    tree: RTree<Entry>,
}

impl LandmarkIndex {
    pub fn new(records: &[LandmarkRecord]) -> Self {
        let feet: Vec<Geodetic> = records.iter().map(foot).collect();
        Self::from_points(&feet)
    }

    /// An index over bare positions; results index into `points`.
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

    /// Indices (into the records the index was built from) of towers whose foot lies
    /// within `radius_m` of `point`, nearest first, with their distances.
    /// Towers from the nearest outwards, lazily: the nearest few cost a
    /// logarithmic walk however many stand at one spot.
    pub fn nearest(&self, point: &Geodetic) -> impl Iterator<Item = (usize, f64)> + '_ {
        let p = point.to_ecef();
        self.tree
            .nearest_neighbor_iter(p)
            .map(move |e| (e.data, distance(e.geom(), &p)))
    }

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

fn foot(r: &LandmarkRecord) -> Geodetic {
    Geodetic {
        lat_deg: r.lat_deg,
        lon_deg: r.lon_deg,
        height_m: r.ground_elev_m,
    }
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use towernav_protocol::TowerType;

    proptest! {
        /// The index returns exactly what a brute-force scan over the same distance returns.
        #[test]
        fn agrees_with_brute_force(
            lat0 in -60.0f64..60.0, lon0 in -170.0f64..170.0,
            offsets in proptest::collection::vec((-0.05f64..0.05, -0.05f64..0.05), 1..200),
            radius in 100.0f64..5000.0,
        ) {
            let records: Vec<LandmarkRecord> = offsets.iter().enumerate()
                .map(|(i, (dlat, dlon))| LandmarkRecord::new(format!("T{i}"), TowerType::A, lat0 + dlat, lon0 + dlon, 10.0, 30.0))
                .collect();
            let index = LandmarkIndex::new(&records);
            let query = Geodetic { lat_deg: lat0, lon_deg: lon0, height_m: 10.0 };
            let got: Vec<usize> = index.within(&query, radius).into_iter().map(|(i, _)| i).collect();
            let q = query.to_ecef();
            let mut want: Vec<(usize, f64)> = records.iter().enumerate()
                .map(|(i, r)| (i, distance(&foot(r).to_ecef(), &q)))
                .filter(|(_, d)| *d <= radius)
                .collect();
            want.sort_by(|a, b| a.1.total_cmp(&b.1));
            prop_assert_eq!(got, want.into_iter().map(|(i, _)| i).collect::<Vec<_>>());
        }
    }
}
