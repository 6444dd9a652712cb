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
