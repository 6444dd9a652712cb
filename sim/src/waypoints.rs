//! Flight plans: waypoint files in TOML, and the named presets shipped in `sim/flights/`.

use serde::Deserialize;

/// One waypoint in the world's local ENU frame; `speed_mps` is for the leg that starts here.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    pub east_m: f64,
    pub north_m: f64,
    /// Height above the plate.
    pub height_m: f64,
    pub speed_mps: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
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

/// Presets by name: the seed's two simulated paths and the other shapes the issue names.
pub const PRESETS: [(&str, &str); 5] = [
    ("seed-path-1", include_str!("../flights/seed-path-1.toml")),
    ("seed-path-2", include_str!("../flights/seed-path-2.toml")),
    ("straight", include_str!("../flights/straight.toml")),
    ("out-and-back", include_str!("../flights/out-and-back.toml")),
    ("lawnmower", include_str!("../flights/lawnmower.toml")),
];

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
                    "height_m {} outside 2..=500 m above the plate",
                    w.height_m
                )));
            }
            if !(0.5..=30.0).contains(&w.speed_mps) {
                return Err(bad(format!(
                    "speed_mps {} outside 0.5..=30 m/s for a small quadrotor",
                    w.speed_mps
                )));
            }
        }
        Ok(plan)
    }

    pub fn preset(name: &str) -> Result<Self, PlanError> {
        let (_, text) =
            PRESETS
                .iter()
                .find(|(n, _)| *n == name)
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
        assert!(err.contains("seed-path-1"), "{err}");
    }
}
