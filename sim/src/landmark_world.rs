//! A world built from surveyed towers (a landmark CSV or database), so a flight
//! over a user's own line can be tried in the simulator before it is flown.
//!
//! The plate stays flat: its datum is the south-west corner of the towers'
//! extent, 100 m out, at the lowest tower foot, so every foot is at or above
//! the ground it is drawn on. Towers that share a `line_name` (or, without
//! one, a type) form a power line, ordered along it, with conductors between
//! neighbours and cross-arms across the line.

use nalgebra::{Matrix2, Point3, SymmetricEigen, Vector2};
use towernav_geometry::Datum;
use towernav_geometry::geodesy::{GeodesyError, Geodetic};
use towernav_protocol::LandmarkRecord;

use crate::world::{SimTower, World, nominal_size};

/// How far the plate's datum lies south and west of the westmost and southmost tower, metres.
pub const PLATE_MARGIN_M: f64 = 100.0;

#[derive(Debug, thiserror::Error)]
pub enum LandmarkWorldError {
    #[error("no towers to build a world from")]
    Empty,
    #[error("building a world from {path}: {source}")]
    Load {
        path: std::path::PathBuf,
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    #[error("tower {id}: {source}")]
    Position { id: String, source: GeodesyError },
    #[error("tower {id}: height {height_m} m is not a tower's (1-200 m)")]
    Height { id: String, height_m: f64 },
}

impl World {
    /// The world a user chose: the towers `load` reads from `file`, one drawn
    /// from `random_seed`, or the paper's field. `load` is the caller's I/O.
    pub fn chosen<E: std::error::Error + Send + Sync + 'static>(
        file: Option<&std::path::Path>,
        random_seed: Option<u64>,
        load: impl FnOnce(&std::path::Path) -> Result<Vec<LandmarkRecord>, E>,
    ) -> Result<Self, LandmarkWorldError> {
        match (file, random_seed) {
            (Some(path), _) => {
                let towers = load(path).map_err(|e| LandmarkWorldError::Load {
                    path: path.to_path_buf(),
                    source: Box::new(e),
                })?;
                Self::from_landmarks(&towers).map_err(|e| LandmarkWorldError::Load {
                    path: path.to_path_buf(),
                    source: Box::new(e),
                })
            }
            (None, Some(seed)) => Ok(Self::random(seed, &crate::world::WorldParams::default())),
            (None, None) => Ok(Self::paper_field()),
        }
    }

    /// The towers of `records` on a flat plate, with no distractors.
    pub fn from_landmarks(records: &[LandmarkRecord]) -> Result<Self, LandmarkWorldError> {
        let first = records.first().ok_or(LandmarkWorldError::Empty)?;
        let geodetic = |r: &LandmarkRecord| {
            Geodetic::new(r.lat_deg, r.lon_deg, r.ground_elev_m).map_err(|source| {
                LandmarkWorldError::Position {
                    id: r.id.clone(),
                    source,
                }
            })
        };
        let rough = Datum::new(geodetic(first)?);
        let mut feet = Vec::with_capacity(records.len());
        for r in records {
            if !(1.0..=200.0).contains(&r.height_m) {
                return Err(LandmarkWorldError::Height {
                    id: r.id.clone(),
                    height_m: r.height_m,
                });
            }
            feet.push(rough.to_enu(&geodetic(r)?));
        }
        let min = |f: fn(&Point3<f64>) -> f64| feet.iter().map(f).fold(f64::INFINITY, f64::min);
        let corner = Point3::new(
            min(|p| p.x) - PLATE_MARGIN_M,
            min(|p| p.y) - PLATE_MARGIN_M,
            0.0,
        );
        let lowest = records
            .iter()
            .map(|r| r.ground_elev_m)
            .fold(f64::INFINITY, f64::min);
        let mut origin = rough.to_geodetic(&corner);
        origin.height_m = lowest;
        let datum = Datum::new(origin);
        let towers: Vec<SimTower> = records
            .iter()
            .map(|r| {
                let foot_in_world =
                    datum.to_enu(&Geodetic::new(r.lat_deg, r.lon_deg, r.ground_elev_m)?);
                let (nominal_h, nominal_w) = nominal_size(r.tower_type);
                Ok(SimTower {
                    id: r.id.clone(),
                    tower_type: r.tower_type,
                    foot_in_world,
                    height_m: r.height_m,
                    base_width_m: r
                        .base_width_m
                        .filter(|w| *w > 0.0)
                        .unwrap_or(nominal_w * r.height_m / nominal_h),
                    line_yaw: 0.0,
                })
            })
            .collect::<Result<_, GeodesyError>>()
            .map_err(|source| LandmarkWorldError::Position {
                id: first.id.clone(),
                source,
            })?;
        let mut world = Self {
            datum,
            towers,
            lines: Vec::new(),
            distractors: Vec::new(),
        };
        world.lines = lines_of(records, &world.towers);
        for line in world.lines.clone() {
            set_line_yaws(&mut world.towers, &line);
        }
        Ok(world)
    }
}

/// Towers grouped into lines by `line_name` (else by type), each ordered along
/// its principal direction.
fn lines_of(records: &[LandmarkRecord], towers: &[SimTower]) -> Vec<Vec<usize>> {
    let key = |r: &LandmarkRecord| {
        r.line_name
            .clone()
            .unwrap_or_else(|| format!("type {}", r.tower_type))
    };
    let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
    for (i, r) in records.iter().enumerate() {
        let k = key(r);
        match groups.iter_mut().find(|(g, _)| *g == k) {
            Some((_, members)) => members.push(i),
            None => groups.push((k, vec![i])),
        }
    }
    groups
        .into_iter()
        .map(|(_, mut members)| {
            let axis = principal_axis(members.iter().map(|&i| towers[i].foot_in_world.xy().coords));
            members.sort_by(|&a, &b| {
                let along = |i: usize| towers[i].foot_in_world.xy().coords.dot(&axis);
                along(a).total_cmp(&along(b))
            });
            members
        })
        .collect()
}

/// The direction of largest spread of `points` (east if they do not spread).
fn principal_axis(points: impl Iterator<Item = Vector2<f64>> + Clone) -> Vector2<f64> {
    let n = points.clone().count().max(1) as f64;
    let mean = points.clone().fold(Vector2::zeros(), |s, p| s + p) / n;
    let cov = points.fold(Matrix2::zeros(), |s, p| {
        let d = p - mean;
        s + d * d.transpose()
    });
    let eigen = SymmetricEigen::new(cov);
    let (i, _) = eigen.eigenvalues.argmax();
    let axis = eigen.eigenvectors.column(i).into_owned();
    if axis.norm() < 1e-9 || !axis.x.is_finite() {
        Vector2::new(1.0, 0.0)
    } else if axis.x < 0.0 || (axis.x == 0.0 && axis.y < 0.0) {
        -axis
    } else {
        axis
    }
}

/// Each tower's line heading: along the line between its neighbours.
fn set_line_yaws(towers: &mut [SimTower], line: &[usize]) {
    if line.len() < 2 {
        return;
    }
    for (k, &i) in line.iter().enumerate() {
        let before = line[k.saturating_sub(1)];
        let after = line[(k + 1).min(line.len() - 1)];
        let d = towers[after].foot_in_world - towers[before].foot_in_world;
        towers[i].line_yaw = d.y.atan2(d.x);
    }
}

/// The towers as a poor map holds them: every other one left out, the rest
/// moved 5-10 m in a direction drawn from `seed` (heights kept).
pub fn degraded(records: &[LandmarkRecord], seed: u64) -> Vec<LandmarkRecord> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    records
        .iter()
        .step_by(2)
        .map(|r| {
            let distance = rng.random_range(5.0..10.0);
            let direction: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let datum = Datum::new(r.foot());
            let moved = datum.to_geodetic(&Point3::new(
                distance * direction.sin(),
                distance * direction.cos(),
                0.0,
            ));
            LandmarkRecord {
                lat_deg: moved.lat_deg,
                lon_deg: moved.lon_deg,
                ..r.clone()
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_worlds_landmarks_build_the_same_towers_and_lines_back() {
        let seed = World::paper_field();
        let back = World::from_landmarks(&seed.landmarks()).expect("builds");
        assert_eq!(back.towers.len(), seed.towers.len());
        // The plate moved; the towers' relative layout did not.
        let offset = back.towers[0].foot_in_world - seed.towers[0].foot_in_world;
        for (a, b) in seed.towers.iter().zip(&back.towers) {
            assert_eq!(a.id, b.id);
            assert_eq!(a.tower_type, b.tower_type);
            let moved = b.foot_in_world - a.foot_in_world - offset;
            assert!(moved.norm() < 0.05, "{}: {moved}", a.id);
            assert!((a.height_m - b.height_m).abs() < 1e-9);
            assert!((a.base_width_m - b.base_width_m).abs() < 1e-9);
            assert!(
                b.foot_in_world.x >= PLATE_MARGIN_M - 0.01,
                "{}",
                b.foot_in_world.x
            );
            assert!(
                b.foot_in_world.y >= PLATE_MARGIN_M - 0.01,
                "{}",
                b.foot_in_world.y
            );
            assert!(
                b.foot_in_world.z.abs() < 0.05,
                "flat field stays on the plate"
            );
        }
        // Four lines (one type each), ordered west to east, running east.
        assert_eq!(back.lines.len(), 4);
        for line in &back.lines {
            let xs: Vec<f64> = line
                .iter()
                .map(|&i| back.towers[i].foot_in_world.x)
                .collect();
            assert!(xs.windows(2).all(|w| w[0] < w[1]), "{xs:?}");
            for &i in line {
                assert!(back.towers[i].line_yaw.abs() < 0.01);
            }
        }
    }

    #[test]
    fn line_names_group_towers_and_bad_towers_are_named() {
        let mut records = World::paper_field().landmarks();
        for r in &mut records {
            r.line_name = Some("one line".into());
        }
        let world = World::from_landmarks(&records).expect("builds");
        assert_eq!(world.lines.len(), 1);
        assert_eq!(world.lines[0].len(), records.len());
        records[3].height_m = 0.0;
        let err = World::from_landmarks(&records).expect_err("zero height");
        assert!(err.to_string().contains(&records[3].id), "{err}");
        assert!(matches!(
            World::from_landmarks(&[]),
            Err(LandmarkWorldError::Empty)
        ));
    }

    #[test]
    fn a_degraded_map_keeps_every_other_tower_moved_5_to_10_m() {
        let towers = World::paper_field().landmarks();
        let poor = degraded(&towers, 3);
        assert_eq!(poor.len(), towers.len().div_ceil(2));
        for p in &poor {
            let t = towers.iter().find(|t| t.id == p.id).expect("same ids");
            let d = Datum::new(t.foot()).to_enu(&p.foot()).coords.norm();
            assert!((5.0..10.0).contains(&d), "{} moved {d:.2} m", p.id);
            assert_eq!(p.height_m, t.height_m);
        }
        assert_eq!(degraded(&towers, 3), poor, "seeded");
    }
}
