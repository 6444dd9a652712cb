//! The look-alikes as stick figures in world coordinates: each is a few
//! groups of members sharing a width and a colour, which the scene strokes
//! like a tower's.

use nalgebra::{Point3, Vector3};

use crate::world::Distractor;

/// Members of one width and colour.
pub struct Group {
    pub width_m: f64,
    pub rgb: [f32; 3],
    pub members: Vec<(Point3<f64>, Point3<f64>)>,
}

const STEEL: [f32; 3] = [0.60, 0.61, 0.63];
const WHITE: [f32; 3] = [0.88, 0.89, 0.90];
const YELLOW: [f32; 3] = [0.85, 0.65, 0.10];
const TIMBER: [f32; 3] = [0.45, 0.37, 0.28];

/// Groups for the line-drawn look-alikes; `None` for the kinds the scene
/// draws itself (trees, buildings, poles).
pub fn groups(d: &Distractor) -> Option<Vec<Group>> {
    Some(match *d {
        Distractor::Mast {
            foot_in_world,
            height_m,
        } => mast(foot_in_world, height_m),
        Distractor::Lamp {
            foot_in_world,
            height_m,
            yaw,
        } => {
            let top = foot_in_world + Vector3::new(0.0, 0.0, height_m);
            let reach = heading(yaw) * (0.25 * height_m);
            let head = top + reach - Vector3::new(0.0, 0.0, 0.3);
            vec![
                group(0.18, STEEL, vec![(foot_in_world, top), (top, head)]),
                group(0.35, WHITE, vec![(head, head + reach * 0.25)]),
            ]
        }
        Distractor::Turbine {
            foot_in_world,
            hub_m,
            blade_m,
            phase,
            yaw,
        } => {
            let hub = foot_in_world + Vector3::new(0.0, 0.0, hub_m);
            let along = heading(yaw);
            let side = Vector3::new(-along.y, along.x, 0.0);
            let blades = (0..3)
                .map(|i| {
                    let a = phase + f64::from(i) * std::f64::consts::TAU / 3.0;
                    let tip = hub + (side * a.cos() + Vector3::z() * a.sin()) * blade_m;
                    (hub + along * 2.0, tip + along * 2.0)
                })
                .collect();
            vec![
                group(4.0, WHITE, vec![(foot_in_world, hub - Vector3::z() * 1.5)]),
                group(3.5, WHITE, vec![(hub - along * 4.0, hub + along * 2.5)]),
                group(2.0, WHITE, blades),
            ]
        }
        Distractor::Crane {
            foot_in_world,
            height_m,
            jib_m,
            yaw,
        } => crane(foot_in_world, height_m, jib_m, yaw),
        Distractor::Fence {
            foot_in_world,
            length_m,
            yaw,
        } => {
            let along = heading(yaw);
            let posts = (length_m / 3.0).ceil().max(1.0) as usize;
            let end = foot_in_world + along * length_m;
            let up = |h: f64| Vector3::new(0.0, 0.0, h);
            vec![
                group(
                    0.12,
                    TIMBER,
                    (0..=posts)
                        .map(|i| {
                            let p = foot_in_world + along * (length_m * i as f64 / posts as f64);
                            (p, p + up(1.3))
                        })
                        .collect(),
                ),
                group(
                    0.06,
                    TIMBER,
                    vec![
                        (foot_in_world + up(0.5), end + up(0.5)),
                        (foot_in_world + up(1.1), end + up(1.1)),
                    ],
                ),
            ]
        }
        Distractor::Tree { .. } | Distractor::Building { .. } | Distractor::Pole { .. } => {
            return None;
        }
    })
}

fn group(width_m: f64, rgb: [f32; 3], members: Vec<(Point3<f64>, Point3<f64>)>) -> Group {
    Group {
        width_m,
        rgb,
        members,
    }
}

fn heading(yaw: f64) -> Vector3<f64> {
    Vector3::new(yaw.cos(), yaw.sin(), 0.0)
}

/// Three legs tapering from 2.5 m apart to 0.8 m, braced every 3 m, with
/// three antenna panels near the top.
fn mast(foot: Point3<f64>, height_m: f64) -> Vec<Group> {
    let leg_at = |k: usize, z: f64| {
        let r = 1.45 - 1.0 * (z / height_m);
        let a = k as f64 * std::f64::consts::TAU / 3.0;
        foot + Vector3::new(r * a.cos(), r * a.sin(), z)
    };
    let legs = (0..3)
        .map(|k| (leg_at(k, 0.0), leg_at(k, height_m)))
        .collect();
    let panels = (height_m / 3.0).floor() as usize;
    let mut braces = Vec::new();
    for p in 0..panels {
        let (z0, z1) = (p as f64 * 3.0, (p as f64 + 1.0) * 3.0);
        for k in 0..3 {
            braces.push((leg_at(k, z0), leg_at((k + 1) % 3, z1)));
            braces.push((leg_at(k, z1), leg_at((k + 1) % 3, z1)));
        }
    }
    let antennas = (0..3)
        .map(|k| {
            let base = leg_at(k, height_m - 3.0);
            (base, base + Vector3::new(0.0, 0.0, 2.6))
        })
        .collect();
    vec![
        group(0.12, STEEL, legs),
        group(0.05, STEEL, braces),
        group(0.45, WHITE, antennas),
    ]
}

/// A square lattice mast 1.6 m wide, a jib out front and a counter-jib with
/// its weight behind, both braced to a peak above the slewing ring.
fn crane(foot: Point3<f64>, height_m: f64, jib_m: f64, yaw: f64) -> Vec<Group> {
    let along = heading(yaw);
    let corner = |k: usize, z: f64| {
        let (sx, sy) = ([-0.8, 0.8, 0.8, -0.8][k], [-0.8, -0.8, 0.8, 0.8][k]);
        foot + Vector3::new(sx, sy, z)
    };
    let mut mast: Vec<_> = (0..4)
        .map(|k| (corner(k, 0.0), corner(k, height_m)))
        .collect();
    let mut z = 0.0;
    while z + 2.0 <= height_m {
        for k in 0..4 {
            mast.push((corner(k, z), corner((k + 1) % 4, z + 2.0)));
        }
        z += 2.0;
    }
    let ring = foot + Vector3::new(0.0, 0.0, height_m);
    let peak = ring + Vector3::new(0.0, 0.0, 6.0);
    let tip = ring + along * jib_m;
    let tail = ring - along * (0.3 * jib_m);
    let jib = vec![(tail, tip), (peak, tip), (peak, tail), (ring, peak)];
    let weight = vec![(tail + along * 1.5, tail + along * 1.5 - Vector3::z() * 2.0)];
    vec![
        group(0.15, YELLOW, mast),
        group(0.5, YELLOW, jib),
        group(2.0, [0.45, 0.45, 0.45], weight),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_look_alike_stands_inside_its_bounding_box() {
        let foot = Point3::new(10.0, 20.0, 0.0);
        let kinds = [
            Distractor::Mast {
                foot_in_world: foot,
                height_m: 30.0,
            },
            Distractor::Lamp {
                foot_in_world: foot,
                height_m: 9.0,
                yaw: 0.4,
            },
            Distractor::Turbine {
                foot_in_world: foot,
                hub_m: 80.0,
                blade_m: 40.0,
                phase: 1.0,
                yaw: -2.0,
            },
            Distractor::Crane {
                foot_in_world: foot,
                height_m: 40.0,
                jib_m: 30.0,
                yaw: 2.5,
            },
            Distractor::Fence {
                foot_in_world: foot,
                length_m: 50.0,
                yaw: 1.0,
            },
        ];
        for d in kinds {
            let corners = d.bounding_corners();
            let lo = corners
                .iter()
                .fold(Vector3::repeat(f64::MAX), |m, c| m.inf(&c.coords));
            let hi = corners
                .iter()
                .fold(Vector3::repeat(f64::MIN), |m, c| m.sup(&c.coords));
            let groups = groups(&d).expect("line-drawn");
            assert!(groups.iter().all(|g| !g.members.is_empty()), "{d:?}");
            for (a, b) in groups.iter().flat_map(|g| &g.members) {
                for p in [a, b] {
                    let inside = (0..3).all(|i| p[i] >= lo[i] - 1e-6 && p[i] <= hi[i] + 1e-6);
                    assert!(inside, "{d:?}: {p:?} outside {lo:?}..{hi:?}");
                }
            }
        }
    }
}
