//! Flight plans: waypoint files in TOML, and the named presets shipped in `sim/flights/`.

use serde::{Deserialize, Serialize};

/// One waypoint in the world's local ENU frame; `speed_mps` is for the leg that starts here.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    pub east_m: f64,
    pub north_m: f64,
    /// Height above the plate.
    pub height_m: f64,
    pub speed_mps: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlightPlan {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(rename = "waypoint")]
    pub waypoints: Vec<Waypoint>,
}

#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("flight plan {origin}: {source}")]
    Toml {
        origin: String,
        source: Box<toml::de::Error>,
    },
    #[error("flight plan {origin}: waypoint {index}: {reason}")]
    Waypoint {
        origin: String,
        index: usize,
        reason: String,
    },
    #[error("flight plan {origin}: needs at least two waypoints, has {count}")]
    TooShort { origin: String, count: usize },
    #[error("no flight preset named {name:?}; presets: {known}")]
    UnknownPreset { name: String, known: String },
}

/// Presets by name: the paper's two simulated paths, a straight pass, an out-and-back and a lawnmower.
pub const PRESETS: [(&str, &str); 5] = [
    ("paper-path-1", include_str!("../flights/paper-path-1.toml")),
    ("paper-path-2", include_str!("../flights/paper-path-2.toml")),
    ("straight", include_str!("../flights/straight.toml")),
    ("out-and-back", include_str!("../flights/out-and-back.toml")),
    ("lawnmower", include_str!("../flights/lawnmower.toml")),
];

/// Older preset names users may still type: `seed-path-N` is `paper-path-N`.
pub const PRESET_ALIASES: [(&str, &str); 2] = [
    ("seed-path-1", "paper-path-1"),
    ("seed-path-2", "paper-path-2"),
];

/// The preset a name means, through its alias if it has one.
pub fn preset_name(name: &str) -> &str {
    PRESET_ALIASES
        .iter()
        .find(|(alias, _)| *alias == name)
        .map_or(name, |(_, preset)| preset)
}

impl FlightPlan {
    /// Parse and check a plan; `origin` names the file in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, PlanError> {
        let plan: FlightPlan = toml::from_str(text).map_err(|e| PlanError::Toml {
            origin: origin.into(),
            source: Box::new(e),
        })?;
        if plan.waypoints.len() < 2 {
            return Err(PlanError::TooShort {
                origin: origin.into(),
                count: plan.waypoints.len(),
            });
        }
        for (index, w) in plan.waypoints.iter().enumerate() {
            let bad = |reason: String| PlanError::Waypoint {
                origin: origin.into(),
                index: index + 1,
                reason,
            };
            if ![w.east_m, w.north_m, w.height_m, w.speed_mps]
                .iter()
                .all(|v| v.is_finite())
            {
                return Err(bad("values must be finite numbers".into()));
            }
            if !(2.0..=500.0).contains(&w.height_m) {
                return Err(bad(format!(
                    "height_m {} is not between 2 and 500 m above the plate",
                    w.height_m
                )));
            }
            if !(0.5..=30.0).contains(&w.speed_mps) {
                return Err(bad(format!(
                    "speed_mps {} is not between 0.5 and 30 m/s for a small quadrotor",
                    w.speed_mps
                )));
            }
        }
        Ok(plan)
    }

    pub fn preset(name: &str) -> Result<Self, PlanError> {
        let wanted = preset_name(name);
        let (_, text) =
            PRESETS
                .iter()
                .find(|(n, _)| *n == wanted)
                .ok_or_else(|| PlanError::UnknownPreset {
                    name: name.into(),
                    known: PRESETS.map(|(n, _)| n).join(", "),
                })?;
        Self::parse(text, &format!("preset {name}"))
    }
}

/// A random pass across a `extent_m` plate for datasets: west to east (or the
/// reverse), sometimes out and back, at a random height and speed; it climbs
/// over any tower it would pass within 25 m of.
pub fn random_crossing(
    extent_m: (f64, f64),
    towers: &[(f64, f64, f64)],
    rng: &mut impl rand::Rng,
) -> FlightPlan {
    let (ex, ey) = extent_m;
    let mut height_m: f64 = rng.random_range(18.0..70.0);
    let speed_mps = rng.random_range(6.0..14.0);
    let (n0, n1) = (
        ey * rng.random_range(0.1..0.9),
        ey * rng.random_range(0.1..0.9),
    );
    let (mut a, mut b) = ((0.0, n0), (ex, n1));
    if rng.random_bool(0.5) {
        std::mem::swap(&mut a, &mut b);
    }
    let tallest_near = towers
        .iter()
        .filter(|&&(e, n, _)| segment_distance((e, n), a, b) < 25.0)
        .map(|&(_, _, h)| h)
        .fold(0.0, f64::max);
    if tallest_near > 0.0 {
        height_m = height_m.max(tallest_near + 12.0);
    }
    let wp = |(east_m, north_m): (f64, f64)| Waypoint {
        east_m,
        north_m,
        height_m,
        speed_mps,
    };
    let mut waypoints = vec![wp(a), wp(b)];
    if rng.random_bool(0.3) {
        let side = if b.1 > ey / 2.0 { -30.0 } else { 30.0 };
        waypoints.push(wp((b.0, b.1 + side)));
        waypoints.push(wp((a.0, a.1 + side)));
    }
    FlightPlan {
        name: "random-crossing".into(),
        description: String::new(),
        waypoints,
    }
}

/// A turning flight for localization benchmarks: 30 m beside a random line
/// for up to 350 m, a turn across to another line (or round to the same
/// line's other side), and up to 300 m beside that one the other way, at one
/// height of 25 to 40 m (raised 12 m over any tower the crossing passes
/// within 25 m of) and 6 to 12 m/s. `None` for a world without a line of two
/// towers.
pub fn random_turning(world: &crate::World, rng: &mut impl rand::Rng) -> Option<FlightPlan> {
    let lines: Vec<&Vec<usize>> = world.lines.iter().filter(|l| l.len() >= 2).collect();
    if lines.is_empty() {
        return None;
    }
    let foot = |i: usize| {
        let p = world.towers[i].foot_in_world;
        (p.x, p.y)
    };
    let unit = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let n = dx.hypot(dy).max(1e-9);
        (dx / n, dy / n)
    };
    // A stretch beside `line` (from its first tower, or its last when
    // `backwards`; or from abreast of `from`), `side` metres to the right of
    // travel, at most `length` metres long.
    let beside =
        |line: &[usize], backwards: bool, side: f64, length: f64, from: Option<(f64, f64)>| {
            let mut feet: Vec<(f64, f64)> = line.iter().map(|&i| foot(i)).collect();
            if backwards {
                feet.reverse();
            }
            let (a, b) = (feet[0], feet[feet.len() - 1]);
            let d = unit(a, b);
            let right = (d.1, -d.0);
            let span = (b.0 - a.0).hypot(b.1 - a.1);
            let along = from.map_or(-60.0, |p| {
                ((p.0 - a.0) * d.0 + (p.1 - a.1) * d.1).clamp(-60.0, span)
            });
            let start = (a.0 + along * d.0, a.1 + along * d.1);
            let run = length.min(span + 60.0 - along).max(80.0);
            let end = (start.0 + run * d.0, start.1 + run * d.1);
            (
                [start, end].map(|p| (p.0 + side * right.0, p.1 + side * right.1)),
                d,
            )
        };
    let first = lines[rng.random_range(0..lines.len())];
    let (leg1, d1) = beside(
        first,
        rng.random_bool(0.5),
        30.0,
        rng.random_range(250.0..350.0),
        None,
    );
    let (second, side) = if lines.len() > 1 && rng.random_bool(0.7) {
        let others: Vec<&&Vec<usize>> = lines.iter().filter(|l| ***l != *first).collect();
        (*others[rng.random_range(0..others.len())], 30.0)
    } else {
        (first, -30.0)
    };
    // The second stretch heads back against the first, from abreast of the turn.
    let (a, b) = (foot(second[0]), foot(second[second.len() - 1]));
    let forward = unit(a, b);
    let backwards = forward.0 * d1.0 + forward.1 * d1.1 > 0.0;
    let (leg2, _) = beside(
        second,
        backwards,
        side,
        rng.random_range(200.0..300.0),
        Some(leg1[1]),
    );
    let mut height_m: f64 = rng.random_range(25.0..40.0);
    let speed_mps = rng.random_range(6.0..12.0);
    let tallest_near_crossing = world
        .towers
        .iter()
        .filter(|t| {
            segment_distance((t.foot_in_world.x, t.foot_in_world.y), leg1[1], leg2[0]) < 25.0
        })
        .map(|t| t.height_m)
        .fold(0.0, f64::max);
    if tallest_near_crossing > 0.0 {
        height_m = height_m.max(tallest_near_crossing + 12.0);
    }
    let waypoints = [leg1[0], leg1[1], leg2[0], leg2[1]]
        .map(|(east_m, north_m)| Waypoint {
            east_m,
            north_m,
            height_m,
            speed_mps,
        })
        .to_vec();
    Some(FlightPlan {
        name: "random-turning".into(),
        description: "beside a line, a turn, beside a line the other way".into(),
        waypoints,
    })
}

/// Where a flight plan comes from: a preset's name or a waypoint file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PlanSource {
    Preset(String),
    File(std::path::PathBuf),
}

impl PlanSource {
    /// A preset when `text` names one; otherwise a path to a plan file.
    pub fn parse(text: &str) -> Self {
        let preset = preset_name(text);
        if PRESETS.iter().any(|(name, _)| *name == preset) {
            Self::Preset(preset.into())
        } else {
            Self::File(text.into())
        }
    }
}

/// A pass along `world`'s longest line: 60 m before its first tower to 60 m
/// past its last, 30 m to the right of it, 12 m above its tallest tower (at
/// least 30 m up), at 10 m/s: towers ahead stand in the forward camera's view.
/// `None` for a world without a line of two towers.
pub fn along_longest_line(world: &crate::World) -> Option<FlightPlan> {
    let length = |line: &Vec<usize>| {
        let (a, b) = (line.first()?, line.last()?);
        Some(
            (world.towers[*b].foot_in_world - world.towers[*a].foot_in_world)
                .xy()
                .norm(),
        )
    };
    let line = world.lines.iter().filter(|l| l.len() >= 2).max_by(|a, b| {
        length(a)
            .unwrap_or(0.0)
            .total_cmp(&length(b).unwrap_or(0.0))
    })?;
    let feet: Vec<(f64, f64)> = line
        .iter()
        .map(|&i| {
            let p = world.towers[i].foot_in_world;
            (p.x, p.y)
        })
        .collect();
    let height_m = line
        .iter()
        .map(|&i| world.towers[i].foot_in_world.z + world.towers[i].height_m + 12.0)
        .fold(30.0, f64::max)
        .min(500.0);
    let unit = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let n = dx.hypot(dy).max(1e-9);
        (dx / n, dy / n)
    };
    let (first, last) = (feet[0], feet[feet.len() - 1]);
    let start_dir = unit(first, feet[1]);
    let end_dir = unit(feet[feet.len() - 2], last);
    let mut path = vec![(first.0 - 60.0 * start_dir.0, first.1 - 60.0 * start_dir.1)];
    path.extend(feet.iter().copied());
    path.push((last.0 + 60.0 * end_dir.0, last.1 + 60.0 * end_dir.1));
    // Offset each point to the right of the local direction of travel.
    let waypoints = (0..path.len())
        .map(|k| {
            let d = unit(path[k.saturating_sub(1)], path[(k + 1).min(path.len() - 1)]);
            Waypoint {
                east_m: path[k].0 + 30.0 * d.1,
                north_m: path[k].1 - 30.0 * d.0,
                height_m,
                speed_mps: 10.0,
            }
        })
        .collect();
    Some(FlightPlan {
        name: "along-the-line".into(),
        description: "30 m beside the world's longest line, end to end".into(),
        waypoints,
    })
}

fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = (dx * dx + dy * dy).max(1e-9);
    let s = (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0);
    (p.0 - a.0 - s * dx).hypot(p.1 - a.1 - s * dy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turning_plan_turns_and_stays_low_beside_its_lines() {
        use rand::SeedableRng;
        for seed in 0..20 {
            let world = crate::World::random(seed, &crate::world::WorldParams::default());
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let plan = random_turning(&world, &mut rng).expect("a plan");
            assert_eq!(plan.waypoints.len(), 4);
            let w = &plan.waypoints;
            let heading =
                |a: &Waypoint, b: &Waypoint| (b.north_m - a.north_m).atan2(b.east_m - a.east_m);
            let turn = heading(&w[2], &w[3]) - heading(&w[0], &w[1]);
            assert!(turn.cos() < 0.9, "seed {seed}: no turn: {w:?}");
            let tallest = world.towers.iter().map(|t| t.height_m).fold(0.0, f64::max);
            for p in w {
                assert!(
                    (25.0..=tallest.max(40.0) + 12.0).contains(&p.height_m),
                    "{p:?}"
                );
                assert!((6.0..12.0).contains(&p.speed_mps));
            }
        }
    }

    #[test]
    fn every_preset_parses() {
        for (name, _) in PRESETS {
            let plan = FlightPlan::preset(name).expect(name);
            assert_eq!(plan.name, name);
        }
    }

    #[test]
    fn the_older_preset_names_still_fly_the_paper_paths() {
        assert_eq!(
            PlanSource::parse("seed-path-2"),
            PlanSource::Preset("paper-path-2".into())
        );
        assert_eq!(
            FlightPlan::preset("seed-path-1").expect("alias"),
            FlightPlan::preset("paper-path-1").expect("preset")
        );
    }

    #[test]
    fn a_plan_is_a_preset_by_name_or_else_a_file() {
        assert_eq!(
            PlanSource::parse("lawnmower"),
            PlanSource::Preset("lawnmower".into())
        );
        assert_eq!(
            PlanSource::parse("plans/survey.toml"),
            PlanSource::File("plans/survey.toml".into())
        );
    }

    /// A forward camera sees a tower only on legs flown towards it, so a
    /// survey that flies one way once more than the other sees one end of
    /// the field on a single pass, along its lines.
    #[test]
    fn the_lawnmower_crosses_the_paper_field_as_often_east_as_west() {
        let plan = FlightPlan::preset("lawnmower").expect("preset");
        let world = crate::World::paper_field();
        let easts = world.towers.iter().map(|t| t.foot_in_world.x);
        let west_end = easts.clone().fold(f64::INFINITY, f64::min);
        let east_end = easts.fold(f64::NEG_INFINITY, f64::max);
        let (mut eastward, mut westward) = (0, 0);
        for leg in plan.waypoints.windows(2) {
            let (from, to) = (leg[0].east_m, leg[1].east_m);
            if from < west_end && to > east_end {
                eastward += 1;
            } else if from > east_end && to < west_end {
                westward += 1;
            }
        }
        assert_eq!((eastward, westward), (2, 2));
    }

    #[test]
    fn the_pass_along_a_line_flies_beside_every_tower() {
        let world = crate::World::random(4, &crate::world::WorldParams::default());
        let plan = along_longest_line(&world).expect("a line");
        let beside = |i: usize, w: &Waypoint| {
            let foot = world.towers[i].foot_in_world;
            (w.east_m - foot.x).hypot(w.north_m - foot.y)
        };
        let line = world
            .lines
            .iter()
            .find(|l| {
                l.len() + 2 == plan.waypoints.len() && beside(l[0], &plan.waypoints[1]) < 31.0
            })
            .expect("the longest line");
        for (k, &i) in line.iter().enumerate() {
            let foot = world.towers[i].foot_in_world;
            let w = &plan.waypoints[k + 1];
            let off = (w.east_m - foot.x).hypot(w.north_m - foot.y);
            assert!((off - 30.0).abs() < 1e-6, "{off}");
            assert!(w.height_m > world.towers[i].height_m);
        }
        let text = toml::to_string(&plan).expect("serializes");
        assert_eq!(
            FlightPlan::parse(&text, "round trip").expect("parses"),
            plan
        );
    }

    #[test]
    fn bad_plans_name_the_waypoint_and_field() {
        let text = "name = \"x\"\n[[waypoint]]\neast_m = 0\nnorth_m = 0\nheight_m = 30\nspeed_mps = 10\n\
                    [[waypoint]]\neast_m = 10\nnorth_m = 0\nheight_m = 30\nspeed_mps = 99\n";
        let err = FlightPlan::parse(text, "f.toml").unwrap_err().to_string();
        assert!(
            err.contains("f.toml") && err.contains("waypoint 2") && err.contains("speed_mps"),
            "{err}"
        );
        let err = FlightPlan::parse("name = 3", "g.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("g.toml"), "{err}");
        let err = FlightPlan::preset("nope").unwrap_err().to_string();
        assert!(err.contains("paper-path-1"), "{err}");
    }
}
