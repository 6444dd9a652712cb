//! Tracking metrics against truth (pure): CLEAR MOT (MOTA, ID switches,
//! fragmentation), IDF1, the paper's identity counts (distinct IDs, repetitive
//! labeling: one ID on several towers; hop labeling: one tower under several
//! IDs), and binding accuracy for tower identities.

use std::collections::{HashMap, HashSet};

use towernav_geometry::PixelBox;

use towernav_core::assignment::max_score_matching;

/// Least overlap for a hypothesis to count as covering a true box (MOTChallenge's 0.5),
/// measured by `overlap`.
pub const MATCH_IOU: f64 = 0.5;

/// IoU with both boxes widened to at least a third of their height about
/// their centres. A far tower is a few pixels wide and tens tall: plain IoU
/// would call a 2 px sideways error a miss; this keeps the test about where
/// the tower is, not about the width of its image.
pub fn overlap(a: &PixelBox, b: &PixelBox) -> f64 {
    let widen = |p: &PixelBox| {
        let w = p.width().max(p.height() / 3.0);
        PixelBox::new(
            p.center_x() - w / 2.0,
            p.top,
            p.center_x() + w / 2.0,
            p.bottom,
        )
    };
    widen(a).iou(&widen(b))
}

/// One reported box: its identity as the method states it, and the tower it is bound to.
#[derive(Debug, Clone, PartialEq)]
pub struct Hypothesis {
    pub id: String,
    pub bbox: PixelBox,
    pub tower: Option<String>,
}

#[derive(Debug, Clone, Default)]
pub struct MotAccumulator {
    gt_total: usize,
    hyp_total: usize,
    false_positives: usize,
    misses: usize,
    id_switches: usize,
    fragmentations: usize,
    /// gt id -> (last matched hyp, matched in the previous frame).
    last: HashMap<String, (Option<String>, bool)>,
    /// (gt, hyp) -> frames where they overlap enough: for IDF1.
    pair_frames: HashMap<(String, String), usize>,
    hyp_to_gt: HashMap<String, HashSet<String>>,
    gt_to_hyp: HashMap<String, HashSet<String>>,
    bound_frames: usize,
    bound_right: usize,
    matched_frames: usize,
    matched_bound: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotMetrics {
    pub frames_gt: usize,
    pub false_positives: usize,
    pub misses: usize,
    pub id_switches: usize,
    pub fragmentations: usize,
    pub mota: f64,
    pub idf1: f64,
    /// Hypothesis IDs that covered a true tower at least once, and true towers seen.
    pub distinct_ids: usize,
    pub true_towers: usize,
    pub repetitive_errors: usize,
    pub hop_errors: usize,
    /// Of track-frames bound to a tower, the share bound to the right one
    /// (a false positive bound to anything is wrong).
    pub binding_accuracy: f64,
    /// Of track-frames covering a true tower, the share that carry a binding.
    pub binding_coverage: f64,
}

impl MotAccumulator {
    /// Add one frame: true boxes by tower id, boxes to ignore (towers too small
    /// or hidden to demand; hypotheses on them are neither hits nor false
    /// positives, as MOTChallenge treats its "don't care" boxes), and the hypotheses.
    pub fn add_frame(
        &mut self,
        truth: &[(String, PixelBox)],
        ignore: &[PixelBox],
        hyps: &[Hypothesis],
    ) {
        let kept: Vec<Hypothesis>;
        let hyps = if ignore.is_empty() {
            hyps
        } else {
            kept = hyps
                .iter()
                .filter(|h| {
                    let on_ignored = ignore.iter().any(|i| overlap(i, &h.bbox) >= MATCH_IOU);
                    let on_truth = truth.iter().any(|(_, g)| overlap(g, &h.bbox) >= MATCH_IOU);
                    on_truth || !on_ignored
                })
                .cloned()
                .collect();
            &kept
        };
        self.gt_total += truth.len();
        self.hyp_total += hyps.len();
        for (g, gb) in truth {
            for h in hyps {
                if overlap(gb, &h.bbox) >= MATCH_IOU {
                    *self
                        .pair_frames
                        .entry((g.clone(), h.id.clone()))
                        .or_insert(0) += 1;
                }
            }
        }
        let (matched_gt, hyp_taken) = self.correspondences(truth, hyps);
        for (gi, (g, _)) in truth.iter().enumerate() {
            let entry = self.last.entry(g.clone()).or_insert((None, false));
            match matched_gt[gi] {
                Some(hi) => {
                    let h = &hyps[hi];
                    if let Some(prev) = &entry.0
                        && prev != &h.id
                    {
                        self.id_switches += 1;
                    }
                    if entry.0.is_some() && !entry.1 {
                        self.fragmentations += 1;
                    }
                    *entry = (Some(h.id.clone()), true);
                    self.count_match(g, h);
                }
                None => {
                    self.misses += 1;
                    entry.1 = false;
                }
            }
        }
        for (hi, h) in hyps.iter().enumerate() {
            if !hyp_taken[hi] {
                self.false_positives += 1;
                self.bound_frames += usize::from(h.tower.is_some());
            }
        }
    }

    /// Which hypothesis covers each true tower this frame, and which
    /// hypotheses are taken.
    fn correspondences(
        &self,
        truth: &[(String, PixelBox)],
        hyps: &[Hypothesis],
    ) -> (Vec<Option<usize>>, Vec<bool>) {
        // CLEAR MOT: keep last frame's correspondences that still overlap, then Hungarian.
        let mut matched_gt = vec![None; truth.len()];
        let mut hyp_taken = vec![false; hyps.len()];
        for (gi, (g, gb)) in truth.iter().enumerate() {
            let Some((Some(prev), _)) = self.last.get(g) else {
                continue;
            };
            if let Some(hi) = hyps
                .iter()
                .position(|h| &h.id == prev && overlap(&h.bbox, gb) >= MATCH_IOU)
                && !hyp_taken[hi]
            {
                matched_gt[gi] = Some(hi);
                hyp_taken[hi] = true;
            }
        }
        let free_gt: Vec<usize> = (0..truth.len())
            .filter(|&i| matched_gt[i].is_none())
            .collect();
        let free_hyp: Vec<usize> = (0..hyps.len()).filter(|&i| !hyp_taken[i]).collect();
        for (r, c) in max_score_matching(
            free_gt.len(),
            free_hyp.len(),
            |r, c| overlap(&truth[free_gt[r]].1, &hyps[free_hyp[c]].bbox),
            MATCH_IOU,
        ) {
            matched_gt[free_gt[r]] = Some(free_hyp[c]);
            hyp_taken[free_hyp[c]] = true;
        }
        (matched_gt, hyp_taken)
    }

    /// A true tower `g` covered by `h`: the identity maps and the binding counts.
    fn count_match(&mut self, g: &str, h: &Hypothesis) {
        self.hyp_to_gt
            .entry(h.id.clone())
            .or_default()
            .insert(g.to_string());
        self.gt_to_hyp
            .entry(g.to_string())
            .or_default()
            .insert(h.id.clone());
        self.matched_frames += 1;
        if let Some(t) = &h.tower {
            self.matched_bound += 1;
            self.bound_frames += 1;
            self.bound_right += usize::from(t == g);
        }
    }

    pub fn finish(&self) -> MotMetrics {
        // IDF1: the one-to-one gt/hyp pairing that maximises frames in common.
        let gts: Vec<&String> = self.gt_to_hyp_all_gts();
        let hyps: Vec<&String> = self.hyp_ids();
        let idtp: usize = max_score_matching(
            gts.len(),
            hyps.len(),
            |r, c| {
                self.pair_frames
                    .get(&(gts[r].clone(), hyps[c].clone()))
                    .copied()
                    .unwrap_or(0) as f64
            },
            0.5,
        )
        .into_iter()
        .map(|(r, c)| {
            self.pair_frames
                .get(&(gts[r].clone(), hyps[c].clone()))
                .copied()
                .unwrap_or(0)
        })
        .sum();
        let ratio = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
        MotMetrics {
            frames_gt: self.gt_total,
            false_positives: self.false_positives,
            misses: self.misses,
            id_switches: self.id_switches,
            fragmentations: self.fragmentations,
            mota: 1.0
                - ratio(
                    self.misses + self.false_positives + self.id_switches,
                    self.gt_total,
                ),
            idf1: ratio(2 * idtp, self.gt_total + self.hyp_total),
            distinct_ids: self.hyp_to_gt.len(),
            true_towers: self.gt_to_hyp.len(),
            repetitive_errors: self
                .hyp_to_gt
                .values()
                .map(|g| g.len().saturating_sub(1))
                .sum(),
            hop_errors: self
                .gt_to_hyp
                .values()
                .map(|h| h.len().saturating_sub(1))
                .sum(),
            binding_accuracy: ratio(self.bound_right, self.bound_frames),
            binding_coverage: ratio(self.matched_bound, self.matched_frames),
        }
    }

    fn gt_to_hyp_all_gts(&self) -> Vec<&String> {
        let mut v: Vec<&String> = self.last.keys().collect();
        v.sort();
        v
    }

    fn hyp_ids(&self) -> Vec<&String> {
        let mut v: Vec<&String> = self
            .pair_frames
            .keys()
            .map(|(_, h)| h)
            .collect::<HashSet<_>>()
            .into_iter()
            .collect();
        v.sort();
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x: f64) -> PixelBox {
        PixelBox::new(x, 100.0, x + 20.0, 200.0)
    }

    fn hyp(id: &str, x: f64, tower: Option<&str>) -> Hypothesis {
        Hypothesis {
            id: id.into(),
            bbox: b(x),
            tower: tower.map(Into::into),
        }
    }

    #[test]
    fn a_thin_far_tower_a_pixel_off_still_matches() {
        let truth = PixelBox::new(600.0, 300.0, 604.0, 330.0);
        let seen = PixelBox::new(602.0, 301.0, 606.0, 331.0);
        assert!(truth.iou(&seen) < 0.5, "plain IoU would call it a miss");
        assert!(overlap(&truth, &seen) >= MATCH_IOU);
        let elsewhere = PixelBox::new(640.0, 300.0, 644.0, 330.0);
        assert!(overlap(&truth, &elsewhere) < 0.1);
    }

    #[test]
    fn perfect_tracking_scores_one() {
        let mut acc = MotAccumulator::default();
        for _ in 0..10 {
            acc.add_frame(
                &[("A1".into(), b(0.0)), ("A2".into(), b(100.0))],
                &[b(500.0)],
                &[
                    hyp("1", 0.0, Some("A1")),
                    hyp("2", 100.0, Some("A2")),
                    hyp("7", 500.0, Some("C9")),
                ],
            );
        }
        let m = acc.finish();
        assert_eq!((m.mota, m.idf1, m.binding_accuracy), (1.0, 1.0, 1.0));
        assert_eq!(
            (m.id_switches, m.repetitive_errors, m.hop_errors),
            (0, 0, 0)
        );
        assert_eq!((m.distinct_ids, m.true_towers), (2, 2));
    }

    #[test]
    fn hops_repeats_switches_and_fragments_are_counted() {
        let mut acc = MotAccumulator::default();
        // A1 is tracked as "1", lost for a frame, then as "3" (a hop and a switch, a fragment).
        acc.add_frame(&[("A1".into(), b(0.0))], &[], &[hyp("1", 0.0, Some("A1"))]);
        acc.add_frame(&[("A1".into(), b(0.0))], &[], &[]);
        acc.add_frame(&[("A1".into(), b(0.0))], &[], &[hyp("3", 0.0, Some("A2"))]);
        // Later "1" covers A2: one ID on two towers.
        acc.add_frame(
            &[("A2".into(), b(300.0))],
            &[],
            &[hyp("1", 300.0, None), hyp("9", 600.0, Some("B1"))],
        );
        let m = acc.finish();
        assert_eq!(m.hop_errors, 1);
        assert_eq!(m.repetitive_errors, 1);
        assert_eq!(m.id_switches, 1);
        assert_eq!(m.fragmentations, 1);
        assert_eq!((m.misses, m.false_positives), (1, 1));
        // Bound track-frames: A1 right, A2-on-A1 wrong, the false positive bound to B1 wrong.
        assert!((m.binding_accuracy - 1.0 / 3.0).abs() < 1e-12);
        assert!((m.mota - (1.0 - 3.0 / 4.0)).abs() < 1e-12);
        // IDF1: best one-to-one pairing covers 1 frame of A1 ("1") and 1 of A2 ("1" taken: "3" for A1)...
        assert!(m.idf1 > 0.0 && m.idf1 < 1.0);
    }
}
