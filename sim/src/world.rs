//! Worlds: towers standing in power lines, and distractors, on a flat plate.
//! The paper's field (18 towers of four types on 1000 m x 500 m) and seeded random fields.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use towernav_geometry::{Datum, Geodetic};
use towernav_protocol::{LandmarkRecord, TowerType};

use crate::tower_model::TowerModel;

#[derive(Debug, Clone, PartialEq)]
pub struct SimTower {
    pub id: String,
    pub tower_type: TowerType,
    /// Foot of the tower axis, where the base diagonals cross.
    pub foot_in_world: Point3<f64>,
    pub height_m: f64,
    pub base_width_m: f64,
    /// ENU yaw of the power line through the tower; the cross-arms stand across it.
    pub line_yaw: f64,
}

impl SimTower {
    pub fn model(&self) -> TowerModel {
        TowerModel::new(self.tower_type, self.height_m, self.base_width_m)
    }

    /// Tower-local model coordinates into the world.
    pub fn world_from_tower(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.foot_in_world.coords),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.line_yaw),
        )
    }
}

/// Things that are not towers but could be mistaken for one, or hide one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distractor {
    Tree {
        foot_in_world: Point3<f64>,
        height_m: f64,
        crown_radius_m: f64,
    },
    Building {
        /// Centre of the footprint on the ground.
        foot_in_world: Point3<f64>,
        /// East-west, north-south and vertical size.
        size_m: Vector3<f64>,
    },
    /// A wooden or concrete distribution pole: thin, tall, tower-like from afar.
    Pole {
        foot_in_world: Point3<f64>,
        height_m: f64,
    },
    /// A cell mast: a slim three-legged lattice with antenna panels on top,
    /// the hardest look-alike of a transmission tower.
    Mast {
        foot_in_world: Point3<f64>,
        height_m: f64,
    },
    /// A street lamp: a pole with an arm reaching out over the road.
    Lamp {
        foot_in_world: Point3<f64>,
        height_m: f64,
        yaw: f64,
    },
    /// A wind turbine: a tapered tube, a nacelle and three blades.
    Turbine {
        foot_in_world: Point3<f64>,
        hub_m: f64,
        blade_m: f64,
        /// Rotor angle of the first blade, radians.
        phase: f64,
        yaw: f64,
    },
    /// A tower crane: a lattice mast with a jib and a counter-jib.
    Crane {
        foot_in_world: Point3<f64>,
        height_m: f64,
        jib_m: f64,
        yaw: f64,
    },
    /// A post-and-rail fence starting at `foot_in_world`.
    Fence {
        foot_in_world: Point3<f64>,
        length_m: f64,
        yaw: f64,
    },
}

impl Distractor {
    pub fn foot_in_world(&self) -> Point3<f64> {
        match *self {
            Self::Tree { foot_in_world, .. }
            | Self::Building { foot_in_world, .. }
            | Self::Pole { foot_in_world, .. }
            | Self::Mast { foot_in_world, .. }
            | Self::Lamp { foot_in_world, .. }
            | Self::Turbine { foot_in_world, .. }
            | Self::Crane { foot_in_world, .. }
            | Self::Fence { foot_in_world, .. } => foot_in_world,
        }
    }

    /// Corners of the box that holds it, world frame: for projection and occlusion.
    pub fn bounding_corners(&self) -> [Point3<f64>; 8] {
        let (foot, half, height) = match *self {
            Self::Tree {
                foot_in_world,
                height_m,
                crown_radius_m,
            } => (
                foot_in_world,
                Vector3::new(crown_radius_m, crown_radius_m, 0.0),
                height_m,
            ),
            Self::Building {
                foot_in_world,
                size_m,
            } => (
                foot_in_world,
                Vector3::new(size_m.x / 2.0, size_m.y / 2.0, 0.0),
                size_m.z,
            ),
            Self::Pole {
                foot_in_world,
                height_m,
            } => (foot_in_world, Vector3::new(0.15, 0.15, 0.0), height_m),
            Self::Mast {
                foot_in_world,
                height_m,
            } => (foot_in_world, Vector3::new(1.5, 1.5, 0.0), height_m),
            Self::Lamp {
                foot_in_world,
                height_m,
                ..
            } => (
                foot_in_world,
                Vector3::new(0.3 * height_m, 0.3 * height_m, 0.0),
                height_m,
            ),
            Self::Turbine {
                foot_in_world,
                hub_m,
                blade_m,
                ..
            } => (
                foot_in_world,
                Vector3::new(blade_m, blade_m, 0.0),
                hub_m + blade_m,
            ),
            Self::Crane {
                foot_in_world,
                height_m,
                jib_m,
                ..
            } => (
                foot_in_world,
                Vector3::new(jib_m, jib_m, 0.0),
                height_m + 6.0,
            ),
            Self::Fence {
                foot_in_world,
                length_m,
                ..
            } => (foot_in_world, Vector3::new(length_m, length_m, 0.0), 1.3),
        };
        let mut out = [foot; 8];
        for (i, corner) in out.iter_mut().enumerate() {
            let sx = if i & 1 == 0 { -1.0 } else { 1.0 };
            let sy = if i & 2 == 0 { -1.0 } else { 1.0 };
            let z = if i & 4 == 0 { 0.0 } else { height };
            *corner = foot + Vector3::new(sx * half.x, sy * half.y, z);
        }
        out
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct World {
    pub datum: Datum,
    pub towers: Vec<SimTower>,
    /// Each power line as indices into `towers`, in order along the line.
    pub lines: Vec<Vec<usize>>,
    pub distractors: Vec<Distractor>,
}

/// What a random world may hold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldParams {
    /// Plate size east and north, metres.
    pub extent_m: (f64, f64),
    /// Number of power lines, inclusive range.
    pub lines: (usize, usize),
    /// Tower spacing along a line, metres.
    pub spacing_m: (f64, f64),
    pub trees: usize,
    pub buildings: usize,
    pub poles: usize,
    /// How many of each look-alike that worlds for training add: cell masts,
    /// street lamps, wind turbines, cranes and fences (none by default, so
    /// the held-out evaluation worlds stay as they were).
    pub clutter: usize,
}

impl WorldParams {
    /// A world crowded with things a detector must not call a tower.
    pub fn cluttered() -> Self {
        Self {
            trees: 90,
            buildings: 14,
            poles: 24,
            clutter: 4,
            ..Self::default()
        }
    }
}

impl Default for WorldParams {
    fn default() -> Self {
        Self {
            extent_m: (1200.0, 600.0),
            lines: (2, 4),
            spacing_m: (170.0, 300.0),
            trees: 60,
            buildings: 8,
            poles: 12,
            clutter: 0,
        }
    }
}

/// One of each look-alike, at random spots with random sizes.
fn push_clutter(
    distractors: &mut Vec<Distractor>,
    rng: &mut ChaCha8Rng,
    spot: impl Fn(&mut ChaCha8Rng) -> Point3<f64>,
) {
    let yaw = |rng: &mut ChaCha8Rng| rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let foot_in_world = spot(rng);
    distractors.push(Distractor::Mast {
        foot_in_world,
        height_m: rng.random_range(20.0..45.0),
    });
    let foot_in_world = spot(rng);
    distractors.push(Distractor::Lamp {
        foot_in_world,
        height_m: rng.random_range(6.0..12.0),
        yaw: yaw(rng),
    });
    let foot_in_world = spot(rng);
    let hub_m = rng.random_range(60.0..110.0);
    distractors.push(Distractor::Turbine {
        foot_in_world,
        hub_m,
        blade_m: hub_m * rng.random_range(0.4..0.6),
        phase: yaw(rng),
        yaw: yaw(rng),
    });
    let foot_in_world = spot(rng);
    distractors.push(Distractor::Crane {
        foot_in_world,
        height_m: rng.random_range(25.0..55.0),
        jib_m: rng.random_range(25.0..50.0),
        yaw: yaw(rng),
    });
    let foot_in_world = spot(rng);
    distractors.push(Distractor::Fence {
        foot_in_world,
        length_m: rng.random_range(20.0..120.0),
        yaw: yaw(rng),
    });
}

/// Nominal height and base width per type; random worlds vary heights around them.
pub fn nominal_size(tower_type: TowerType) -> (f64, f64) {
    match tower_type {
        TowerType::A => (32.0, 6.0),
        TowerType::B => (38.0, 7.0),
        TowerType::C => (45.0, 8.0),
        TowerType::D => (52.0, 9.0),
        _ => (40.0, 7.5),
    }
}

/// Per type: line north coordinate and east positions.
const SEED_LINES: [(TowerType, f64, &[f64]); 4] = [
    (TowerType::A, 300.0, &[120.0, 320.0, 520.0, 720.0, 920.0]),
    (TowerType::B, 200.0, &[80.0, 280.0, 480.0, 680.0, 880.0]),
    (TowerType::C, 400.0, &[150.0, 400.0, 650.0, 900.0]),
    (TowerType::D, 100.0, &[100.0, 350.0, 600.0, 850.0]),
];

fn paper_datum() -> Datum {
    Datum::new(Geodetic {
        lat_deg: 30.52,
        lon_deg: 114.36,
        height_m: 25.0,
    })
}

impl World {
    /// The plate's south-west corner is the datum; east is +x, north is +y.
    /// A and B stand 50 m either side of the centre line, C and D 150 m out.
    /// A few trees and sheds stand off the path; none hides the A and B lines.
    pub fn paper_field() -> Self {
        let mut towers = Vec::new();
        let mut lines = Vec::new();
        for &(tower_type, north, easts) in &SEED_LINES {
            let (height_m, base_width_m) = nominal_size(tower_type);
            let first = towers.len();
            towers.extend(easts.iter().enumerate().map(|(i, &east)| SimTower {
                id: format!("{tower_type}{}", i + 1),
                tower_type,
                foot_in_world: Point3::new(east, north, 0.0),
                height_m,
                base_width_m,
                line_yaw: 0.0,
            }));
            lines.push((first..towers.len()).collect());
        }
        let tree = |east: f64, north: f64, height_m: f64| Distractor::Tree {
            foot_in_world: Point3::new(east, north, 0.0),
            height_m,
            crown_radius_m: height_m * 0.3,
        };
        let distractors = vec![
            tree(230.0, 150.0, 12.0),
            tree(245.0, 160.0, 9.0),
            tree(610.0, 350.0, 14.0),
            tree(790.0, 140.0, 11.0),
            Distractor::Building {
                foot_in_world: Point3::new(420.0, 150.0, 0.0),
                size_m: Vector3::new(14.0, 9.0, 6.0),
            },
            Distractor::Pole {
                foot_in_world: Point3::new(560.0, 330.0, 0.0),
                height_m: 11.0,
            },
        ];
        Self {
            datum: paper_datum(),
            towers,
            lines,
            distractors,
        }
    }

    /// A seeded random field: straight power lines at random headings and types
    /// across the plate, with trees, buildings and poles scattered between them.
    pub fn random(seed: u64, params: &WorldParams) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (ex, ey) = params.extent_m;
        let mut towers: Vec<SimTower> = Vec::new();
        let mut lines = Vec::new();
        let line_count = rng.random_range(params.lines.0..=params.lines.1.max(params.lines.0));
        for line in 0..line_count {
            let tower_type = TowerType::ALL[rng.random_range(0..4)];
            let (nominal_h, base_w) = nominal_size(tower_type);
            let yaw: f64 = rng.random_range(-0.35..0.35);
            // Lines spread across the plate's width and cross it west to east;
            // `north0` is where a line crosses the plate's middle.
            let north0 = ey * (line as f64 + rng.random_range(0.2..0.8)) / line_count as f64;
            let (dir_e, dir_n) = (yaw.cos(), yaw.sin());
            let mut along = rng.random_range(0.0..params.spacing_m.0);
            let first = towers.len();
            loop {
                let e = along * dir_e;
                let n = north0 + (along - ex / 2.0 / dir_e) * dir_n;
                if e > ex {
                    break;
                }
                let height_m = nominal_h * rng.random_range(0.88..1.12);
                towers.push(SimTower {
                    id: format!("L{}-{}{}", line + 1, tower_type, towers.len() - first + 1),
                    tower_type,
                    foot_in_world: Point3::new(e, n, 0.0),
                    height_m,
                    base_width_m: base_w * height_m / nominal_h,
                    line_yaw: yaw,
                });
                along += rng.random_range(
                    params.spacing_m.0..params.spacing_m.1.max(params.spacing_m.0 + 1.0),
                );
            }
            if towers.len() > first {
                lines.push((first..towers.len()).collect());
            }
        }
        let mut distractors = Vec::new();
        let spot = |rng: &mut ChaCha8Rng| {
            Point3::new(rng.random_range(0.0..ex), rng.random_range(0.0..ey), 0.0)
        };
        for _ in 0..params.trees {
            let h = rng.random_range(6.0..18.0);
            let foot_in_world = spot(&mut rng);
            distractors.push(Distractor::Tree {
                foot_in_world,
                height_m: h,
                crown_radius_m: h * rng.random_range(0.2..0.4),
            });
        }
        for _ in 0..params.buildings {
            let foot_in_world = spot(&mut rng);
            distractors.push(Distractor::Building {
                foot_in_world,
                size_m: Vector3::new(
                    rng.random_range(6.0..25.0),
                    rng.random_range(6.0..20.0),
                    rng.random_range(3.0..12.0),
                ),
            });
        }
        for _ in 0..params.poles {
            let foot_in_world = spot(&mut rng);
            distractors.push(Distractor::Pole {
                foot_in_world,
                height_m: rng.random_range(8.0..13.0),
            });
        }
        for _ in 0..params.clutter {
            push_clutter(&mut distractors, &mut rng, spot);
        }
        // Nothing stands inside a tower's base.
        distractors.retain(|d| {
            towers
                .iter()
                .all(|t| (t.foot_in_world - d.foot_in_world()).xy().norm() > 25.0)
        });
        Self {
            datum: paper_datum(),
            towers,
            lines,
            distractors,
        }
    }

    /// The towers as surveyed landmarks, in WGS84, for the database.
    /// Each tower's `line_name` is its line's number, so the lines come back
    /// whole when the records build a world again.
    pub fn landmarks(&self) -> Vec<LandmarkRecord> {
        let line_of = |i: usize| {
            self.lines
                .iter()
                .position(|line| line.contains(&i))
                .map(|k| format!("line {}", k + 1))
        };
        self.towers
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let g = self.datum.to_geodetic(&t.foot_in_world);
                LandmarkRecord {
                    base_width_m: Some(t.base_width_m),
                    line_name: line_of(i),
                    survey_source: Some("towernav-sim".into()),
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
    fn the_paper_field_has_18_towers_of_4_types_on_the_plate() {
        let world = World::paper_field();
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
    fn random_worlds_are_seeded_and_hold_lines_of_one_type() {
        let params = WorldParams::default();
        assert_eq!(World::random(3, &params), World::random(3, &params));
        assert_ne!(World::random(3, &params), World::random(4, &params));
        for seed in 0..20 {
            let world = World::random(seed, &params);
            assert!(
                world.towers.len() >= 4,
                "seed {seed}: {}",
                world.towers.len()
            );
            for line in &world.lines {
                let t = world.towers[line[0]].tower_type;
                assert!(line.iter().all(|&i| world.towers[i].tower_type == t));
            }
            let mut ids: Vec<_> = world.towers.iter().map(|t| &t.id).collect();
            ids.sort();
            ids.dedup();
            assert_eq!(ids.len(), world.towers.len(), "ids are unique");
        }
    }

    #[test]
    fn landmarks_map_back_onto_the_plate() {
        let world = World::paper_field();
        for (tower, record) in world.towers.iter().zip(world.landmarks()) {
            let g =
                Geodetic::new(record.lat_deg, record.lon_deg, record.ground_elev_m).expect("valid");
            let back = world.datum.to_enu(&g);
            assert!((back - tower.foot_in_world).norm() < 1e-3, "{}", tower.id);
        }
    }
}
