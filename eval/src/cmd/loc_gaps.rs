//! Why a frame with a tower in view has no fix: each such frame of
//! `bench-localization` put in the first place along the chain where it was
//! lost (detector, tracker, identity, localizer, filter), level and banked
//! apart, so that a change can be aimed at the cause and its effect read.

use comfy_table::Table;
use serde::Serialize;

use super::loc_bench::{BenchRow, FrameRow};

const OUTCOMES: usize = 11;

/// Where along the chain a frame with a tower in view ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// A fix was fused and published.
    Published,
    /// A fix was fused, but the filter's 1-sigma was past the report bound.
    HeldBack,
    /// The filter was not running and the fix could not restart it (too
    /// few towers, or too far from the last estimate).
    NotRestarted,
    /// The filter was running and gated the fix out.
    Gated,
    /// Boxes were bound, but the frame cut each so that too little of the
    /// tower was left for a fix.
    CutByTheBorder,
    /// Boxes were bound, but the localizer made no fix of them (too
    /// uncertain, or gated out).
    NoFixFromBoxes,
    /// A track's binding stands, but its box fit a neighbour about as well
    /// and was left out of the frame.
    LeftOut,
    /// Tracks, none bound to a tower (identity waits on an ambiguity),
    /// while the filter runs.
    NotBound,
    /// Tracks, none bound, the filter lost (20 s or more without a fix):
    /// the guess they are judged by is where the UAV was last known.
    NotBoundLost,
    /// A tower was detected, but no track was confirmed yet.
    NotTracked,
    /// No box on any tower in view.
    NotDetected,
}

impl Outcome {
    pub const ALL: [Outcome; OUTCOMES] = [
        Outcome::Published,
        Outcome::HeldBack,
        Outcome::NotRestarted,
        Outcome::Gated,
        Outcome::CutByTheBorder,
        Outcome::NoFixFromBoxes,
        Outcome::LeftOut,
        Outcome::NotBound,
        Outcome::NotBoundLost,
        Outcome::NotTracked,
        Outcome::NotDetected,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Outcome::Published => "fix published",
            Outcome::HeldBack => "fix fused, held back (sigma past the bound)",
            Outcome::NotRestarted => "fix refused: filter not running, restart rule",
            Outcome::Gated => "fix refused: gated by the running filter",
            Outcome::CutByTheBorder => "bound, cut by the border: too little left",
            Outcome::NoFixFromBoxes => "bound, no fix from the boxes",
            Outcome::LeftOut => "bound, box left out (fits a neighbour)",
            Outcome::NotBound => "tracked, none bound yet",
            Outcome::NotBoundLost => "tracked, none bound, filter lost",
            Outcome::NotTracked => "detected, no confirmed track",
            Outcome::NotDetected => "no box on a tower in view",
        }
    }

    /// A frame's outcome; `None` when no tower was in view.
    pub fn of(f: &FrameRow) -> Option<Outcome> {
        if f.in_view == 0 {
            return None;
        }
        Some(if f.fix {
            match f.verdict.as_str() {
                "Accepted" | "Restarted" if f.error_m.is_some() => Outcome::Published,
                "Accepted" | "Restarted" => Outcome::HeldBack,
                _ if f.filter_running => Outcome::Gated,
                _ => Outcome::NotRestarted,
            }
        } else if f.bound > 0 && f.bound_cut == f.bound {
            Outcome::CutByTheBorder
        } else if f.bound > 0 {
            Outcome::NoFixFromBoxes
        } else if f.held > 0 {
            Outcome::LeftOut
        } else if f.tracks > 0 && f.filter_running {
            Outcome::NotBound
        } else if f.tracks > 0 {
            Outcome::NotBoundLost
        } else if f.detected > 0 {
            Outcome::NotTracked
        } else {
            Outcome::NotDetected
        })
    }
}

/// Frames with a tower in view by outcome, level (roll under 3 degrees) and
/// banked (over 10 degrees), for one detector over its flights.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Gaps {
    pub detector: String,
    pub level: [usize; OUTCOMES],
    pub banked: [usize; OUTCOMES],
}

impl Gaps {
    pub fn of(detector: &str, rows: &[&BenchRow]) -> Gaps {
        let mut gaps = Gaps {
            detector: detector.to_owned(),
            ..Gaps::default()
        };
        for f in rows.iter().flat_map(|r| &r.per_frame) {
            let Some(outcome) = Outcome::of(f) else {
                continue;
            };
            let i = Outcome::ALL
                .iter()
                .position(|o| *o == outcome)
                .unwrap_or_default();
            let roll = f.roll_deg.abs();
            if roll < 3.0 {
                gaps.level[i] += 1;
            } else if roll > 10.0 {
                gaps.banked[i] += 1;
            }
        }
        gaps
    }
}

/// One table per detector: each outcome's share of level and banked frames.
pub fn table(gaps: &Gaps) -> Table {
    let mut table = Table::new();
    table.set_header([
        format!("{}: frames with a tower in view", gaps.detector),
        "level".into(),
        "banked".into(),
    ]);
    let share = |counts: &[usize; OUTCOMES], i: usize| {
        let n: usize = counts.iter().sum();
        format!(
            "{:.1} % ({})",
            100.0 * counts[i] as f64 / n.max(1) as f64,
            counts[i]
        )
    };
    for (i, o) in Outcome::ALL.iter().enumerate() {
        table.add_row([
            o.name().to_owned(),
            share(&gaps.level, i),
            share(&gaps.banked, i),
        ]);
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(in_view: usize) -> FrameRow {
        FrameRow {
            in_view,
            verdict: "NoFix".into(),
            ..FrameRow::default()
        }
    }

    #[test]
    fn each_frame_is_put_where_the_chain_lost_it() {
        assert_eq!(Outcome::of(&frame(0)), None);
        let mut f = frame(1);
        assert_eq!(Outcome::of(&f), Some(Outcome::NotDetected));
        f.detected = 1;
        assert_eq!(Outcome::of(&f), Some(Outcome::NotTracked));
        f.tracks = 1;
        assert_eq!(Outcome::of(&f), Some(Outcome::NotBoundLost));
        f.filter_running = true;
        assert_eq!(Outcome::of(&f), Some(Outcome::NotBound));
        f.held = 1;
        assert_eq!(Outcome::of(&f), Some(Outcome::LeftOut));
        f.bound = 1;
        assert_eq!(Outcome::of(&f), Some(Outcome::NoFixFromBoxes));
        f.bound_cut = 1;
        assert_eq!(Outcome::of(&f), Some(Outcome::CutByTheBorder));
        f.fix = true;
        f.verdict = "Rejected".into();
        f.filter_running = false;
        assert_eq!(Outcome::of(&f), Some(Outcome::NotRestarted));
        f.filter_running = true;
        assert_eq!(Outcome::of(&f), Some(Outcome::Gated));
        f.verdict = "Accepted".into();
        assert_eq!(Outcome::of(&f), Some(Outcome::HeldBack));
        f.error_m = Some(1.0);
        assert_eq!(Outcome::of(&f), Some(Outcome::Published));
    }

    #[test]
    fn level_and_banked_frames_are_counted_apart() {
        let mut level = frame(1);
        level.roll_deg = 1.0;
        let mut banked = frame(2);
        banked.roll_deg = -20.0;
        banked.bound = 1;
        let mut between = frame(1);
        between.roll_deg = 5.0;
        let row = BenchRow {
            per_frame: vec![level, banked, between, frame(0)],
            ..BenchRow::default()
        };
        let gaps = Gaps::of("oracle", &[&row]);
        assert_eq!(gaps.level, [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1]);
        assert_eq!(gaps.banked, [0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0]);
        let text = table(&gaps).to_string();
        assert!(text.contains("100.0 % (1)"), "{text}");
    }
}
