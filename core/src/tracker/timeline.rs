//! The paper's identity correction (its Algorithm 1), run online on any
//! tracker's output: in a one-way flight a tower comes into view once and
//! stays, so
//! 1. a track unseen for more than `gap_frames` frames ends its run, and if
//!    its id comes back it is a different tower: it gets a fresh id;
//! 2. runs shorter than `min_run` frames are not reported (mostly false
//!    positives); online, a run is reported from its `min_run`-th frame on.

use std::collections::HashMap;

use super::common::TrackOutput;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimelineParams {
    pub gap_frames: u64,
    pub min_run: u32,
}

impl Default for TimelineParams {
    fn default() -> Self {
        Self {
            gap_frames: 15,
            min_run: 5,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Run {
    id: u64,
    last_seq: u64,
    length: u32,
}

#[derive(Debug, Clone, Default)]
pub struct TimelineCorrection {
    params: TimelineParams,
    runs: HashMap<u64, Run>,
    next_id: u64,
}

impl TimelineCorrection {
    pub fn new(params: TimelineParams) -> Self {
        Self {
            params,
            runs: HashMap::new(),
            next_id: 1,
        }
    }

    /// Re-label one frame's outputs (frame number `seq`); short runs are held back.
    pub fn apply(&mut self, seq: u64, outputs: Vec<TrackOutput>) -> Vec<TrackOutput> {
        let p = self.params;
        let mut kept = Vec::with_capacity(outputs.len());
        for mut o in outputs {
            let fresh = match self.runs.get(&o.track_id) {
                Some(run) => seq.saturating_sub(run.last_seq) > p.gap_frames,
                None => true,
            };
            if fresh {
                self.runs.insert(
                    o.track_id,
                    Run {
                        id: self.next_id,
                        last_seq: seq,
                        length: 0,
                    },
                );
                self.next_id += 1;
            }
            let Some(run) = self.runs.get_mut(&o.track_id) else {
                continue;
            };
            run.last_seq = seq;
            run.length += 1;
            if run.length >= p.min_run {
                o.track_id = run.id;
                kept.push(o);
            }
        }
        // Forget runs long over, so the map stays small.
        let horizon = p.gap_frames;
        self.runs
            .retain(|_, r| seq.saturating_sub(r.last_seq) <= horizon.saturating_mul(4));
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_geometry::PixelBox;
    use towernav_protocol::TowerType;

    fn out(id: u64) -> TrackOutput {
        TrackOutput {
            track_id: id,
            bbox: PixelBox::new(0.0, 0.0, 10.0, 40.0),
            tower_type: TowerType::A,
            score: 0.9,
        }
    }

    #[test]
    fn a_reappearing_id_is_a_new_tower_and_short_runs_are_dropped() {
        let mut tc = TimelineCorrection::new(TimelineParams {
            gap_frames: 5,
            min_run: 3,
        });
        let mut ids = Vec::new();
        for seq in 0..10 {
            ids.push(tc.apply(seq, vec![out(7)]).first().map(|o| o.track_id));
        }
        assert_eq!(
            ids[..2],
            [None, None],
            "held back until the run is three frames long"
        );
        let first = ids[2].expect("reported");
        assert!(ids[2..].iter().all(|i| *i == Some(first)));
        // Gone for 10 frames, then back with the same tracker id: a different tower.
        let back: Vec<_> = (20..24)
            .filter_map(|seq| tc.apply(seq, vec![out(7)]).first().map(|o| o.track_id))
            .collect();
        assert_eq!(back.len(), 2);
        assert!(back.iter().all(|&i| i != first));
        // A two-frame blip never shows.
        assert!(tc.apply(30, vec![out(9)]).is_empty() && tc.apply(31, vec![out(9)]).is_empty());
    }
}
