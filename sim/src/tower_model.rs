//! Steel-lattice tower models, one design per type, as 3-D line members.
//!
//! Coordinates are tower-local: origin at the foot on the axis (where the base
//! diagonals cross), x along the power line, y across it (the cross-arms), z up.
//! Every design's highest point is the apex on the axis at exactly the tower
//! height, so the labeling convention's top edge is the model's top.

use nalgebra::{Point3, Vector3};
use towernav_protocol::TowerType;

/// What a member is; the renderer gives each kind its width and colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MemberKind {
    /// Corner legs: the heaviest angle sections.
    Leg,
    /// Face bracing and horizontal struts.
    Brace,
    /// Cross-arm chords and ties, and earth-wire peaks.
    Arm,
    /// Insulator strings hanging from the arm tips.
    Insulator,
}

impl MemberKind {
    pub const ALL: [MemberKind; 4] = [Self::Leg, Self::Brace, Self::Arm, Self::Insulator];

    /// Physical width of the member, metres.
    pub fn width_m(self) -> f64 {
        match self {
            Self::Leg => 0.28,
            Self::Brace => 0.10,
            Self::Arm => 0.16,
            Self::Insulator => 0.26,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Member {
    pub kind: MemberKind,
    pub a: Point3<f64>,
    pub b: Point3<f64>,
}

/// One tower's members plus where its conductors attach.
#[derive(Debug, Clone, PartialEq)]
pub struct TowerModel {
    pub members: Vec<Member>,
    /// Bottom ends of the insulator strings: where conductors hang.
    pub attachments: Vec<Point3<f64>>,
}

/// Cross-arm level: height as a fraction of H, span either side in base widths.
struct ArmLevel {
    z: f64,
    span: f64,
}

/// A design in fractions of the tower height H and base width W, so one type
/// keeps its look at any surveyed height.
struct Design {
    /// Body half-width at the waist (fraction of W) and the waist height (fraction of H).
    waist: (f64, f64),
    /// Half-width at the top of the body, fraction of W.
    head_half: f64,
    /// Top of the lattice body, fraction of H; above it only the peak.
    body_top: f64,
    arms: &'static [ArmLevel],
    /// Earth-wire horns either side of the peak: (z, span) like an arm, or none.
    horns: Option<(f64, f64)>,
    /// Bracing panels between the foot and the waist, and above it.
    panels: (usize, usize),
}

fn design(tower_type: TowerType) -> Design {
    match tower_type {
        // Single circuit "cat head": narrow waist, one wide arm.
        TowerType::A => Design {
            waist: (0.14, 0.62),
            head_half: 0.30,
            body_top: 0.90,
            arms: &[ArmLevel {
                z: 0.80,
                span: 1.25,
            }],
            horns: None,
            panels: (5, 2),
        },
        // Double circuit: three arm levels, straight taper.
        TowerType::B => Design {
            waist: (0.18, 0.55),
            head_half: 0.14,
            body_top: 0.93,
            arms: &[
                ArmLevel {
                    z: 0.58,
                    span: 0.75,
                },
                ArmLevel {
                    z: 0.71,
                    span: 0.90,
                },
                ArmLevel {
                    z: 0.84,
                    span: 0.70,
                },
            ],
            horns: None,
            panels: (5, 4),
        },
        // Two arm levels, wide below, with earth-wire horns.
        TowerType::C => Design {
            waist: (0.20, 0.50),
            head_half: 0.12,
            body_top: 0.92,
            arms: &[
                ArmLevel {
                    z: 0.62,
                    span: 1.05,
                },
                ArmLevel {
                    z: 0.78,
                    span: 0.70,
                },
            ],
            horns: Some((0.92, 0.45)),
            panels: (6, 4),
        },
        // Tall, single wide arm high up, earth-wire horns, slim head.
        // D, and any type a surveyed world names that is not one of the four.
        _ => Design {
            waist: (0.16, 0.70),
            head_half: 0.10,
            body_top: 0.90,
            arms: &[ArmLevel {
                z: 0.80,
                span: 1.10,
            }],
            horns: Some((0.90, 0.35)),
            panels: (7, 2),
        },
    }
}

const CORNERS: [(f64, f64); 4] = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
/// Insulator string length, metres.
const INSULATOR_M: f64 = 2.5;

impl TowerModel {
    pub fn new(tower_type: TowerType, height_m: f64, base_width_m: f64) -> Self {
        let d = design(tower_type);
        let (h, w) = (height_m, base_width_m);
        let (head_half, top_z) = (d.head_half * w, d.body_top * h);
        let levels = body_levels(&d, h, w);
        let mut members = body_members(&levels);
        // Peak: from the body top's corners to the apex on the axis at exactly H.
        let apex = Point3::new(0.0, 0.0, h);
        for c in 0..4 {
            members.push(Member {
                kind: MemberKind::Arm,
                a: corner(top_z, head_half, c),
                b: apex,
            });
        }
        let half_at = |z: f64| {
            levels
                .windows(2)
                .find(|p| z <= p[1].0)
                .map(|p| lerp(p[0].1, p[1].1, (z - p[0].0) / (p[1].0 - p[0].0)))
                .unwrap_or(head_half)
        };
        let mut attachments = Vec::new();
        let mut arm = |z: f64, span: f64, insulators: bool| {
            let half = half_at(z);
            let depth = (0.06 * h).min(2.5);
            let upper = z + depth;
            let upper_half = half_at(upper.min(top_z));
            for side in [-1.0, 1.0] {
                let tip = Point3::new(0.0, side * (half + span * w), z);
                for sx in [-1.0, 1.0] {
                    members.push(Member {
                        kind: MemberKind::Arm,
                        a: Point3::new(sx * half, side * half, z),
                        b: tip,
                    });
                    members.push(Member {
                        kind: MemberKind::Arm,
                        a: Point3::new(sx * upper_half, side * upper_half, upper),
                        b: tip,
                    });
                }
                if insulators {
                    let bottom = tip - Vector3::new(0.0, 0.0, INSULATOR_M);
                    members.push(Member {
                        kind: MemberKind::Insulator,
                        a: tip,
                        b: bottom,
                    });
                    attachments.push(bottom);
                }
            }
        };
        for level in d.arms {
            arm(level.z * h, level.span, true);
        }
        if let Some((z, span)) = d.horns {
            arm(z * h, span, false);
        }
        Self {
            members,
            attachments,
        }
    }

    /// Every member end point: what a projected box must enclose.
    pub fn vertices(&self) -> impl Iterator<Item = Point3<f64>> + '_ {
        self.members.iter().flat_map(|m| [m.a, m.b])
    }
}

/// Body levels (z, half-width) from the foot up: waist panels, then head panels to the body top.
fn body_levels(d: &Design, h: f64, w: f64) -> Vec<(f64, f64)> {
    let base_half = w / 2.0;
    let (waist_half, waist_z) = (d.waist.0 * w, d.waist.1 * h);
    let (head_half, top_z) = (d.head_half * w, d.body_top * h);
    let mut levels = Vec::new();
    for i in 0..=d.panels.0 {
        let s = i as f64 / d.panels.0 as f64;
        levels.push((s * waist_z, lerp(base_half, waist_half, s)));
    }
    for i in 1..=d.panels.1 {
        let s = i as f64 / d.panels.1 as f64;
        levels.push((lerp(waist_z, top_z, s), lerp(waist_half, head_half, s)));
    }
    levels
}

/// Corner `c` of the square section at height `z`.
fn corner(z: f64, half: f64, c: usize) -> Point3<f64> {
    let (sx, sy) = CORNERS[c];
    Point3::new(sx * half, sy * half, z)
}

/// Legs between levels, X-bracing on each face, and a strut along each panel's upper edge.
fn body_members(levels: &[(f64, f64)]) -> Vec<Member> {
    let mut members = Vec::new();
    for pair in levels.windows(2) {
        let ((z0, h0), (z1, h1)) = (pair[0], pair[1]);
        for c in 0..4 {
            let n = (c + 1) % 4;
            members.push(Member {
                kind: MemberKind::Leg,
                a: corner(z0, h0, c),
                b: corner(z1, h1, c),
            });
            for (a, b) in [
                (corner(z0, h0, c), corner(z1, h1, n)),
                (corner(z0, h0, n), corner(z1, h1, c)),
                (corner(z1, h1, c), corner(z1, h1, n)),
            ] {
                members.push(Member {
                    kind: MemberKind::Brace,
                    a,
                    b,
                });
            }
        }
    }
    members
}

fn lerp(a: f64, b: f64, s: f64) -> f64 {
    a + (b - a) * s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_design_peaks_on_its_axis_at_exactly_its_height() {
        for t in TowerType::ALL {
            let model = TowerModel::new(t, 40.0, 7.0);
            let top = model
                .vertices()
                .max_by(|a, b| a.z.total_cmp(&b.z))
                .expect("members");
            assert_eq!(top, Point3::new(0.0, 0.0, 40.0), "{t}");
            assert!(model.vertices().all(|p| p.z >= 0.0), "{t} below ground");
            assert!(!model.attachments.is_empty(), "{t} carries conductors");
        }
    }

    #[test]
    fn designs_differ_in_arm_layout() {
        let spans: Vec<usize> = TowerType::ALL
            .iter()
            .map(|&t| TowerModel::new(t, 40.0, 7.0).attachments.len())
            .collect();
        // A and D are single circuit, B double circuit with three levels, C two levels.
        assert_eq!(spans, vec![2, 6, 4, 2]);
        let width = |t| {
            TowerModel::new(t, 40.0, 7.0)
                .vertices()
                .map(|p| p.y.abs())
                .fold(0.0, f64::max)
        };
        assert!(width(TowerType::A) > width(TowerType::B));
    }
}
