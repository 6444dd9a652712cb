//! Tracking metrics against truth (pure), matched as MOTChallenge's tools
//! (TrackEval, py-motmetrics) match: plain IoU at 0.5, and hypotheses that a
//! one-to-one matching puts on "don't care" boxes removed before scoring.
//! CLEAR MOT (MOTA, ID switches, fragmentation), IDF1, HOTA with DetA and
//! AssA, the paper's identity counts (distinct IDs, repetitive labeling: one
//! ID on several towers; hop labeling: one tower under several IDs), and
//! binding accuracy for tower identities.

use std::collections::{BTreeSet, HashMap, HashSet};

use towernav_geometry::PixelBox;

use towernav_core::assignment::max_score_matching;

use crate::hota::{Hota, HotaFrame, hota};

/// Least IoU for a hypothesis to cover a true box (MOTChallenge's 0.5).
pub const MATCH_IOU: f64 = 0.5;

/// TrackEval compares IoU with the threshold less a float epsilon.
const MATCH_MIN: f64 = MATCH_IOU - 1e-9;

/// A previous frame's pairing outweighs any IoU in CLEAR MOT's matching.
const CONTINUITY_BONUS: f64 = 1000.0;

/// One reported box: its identity as the method states it, and the tower it is bound to.
#[derive(Debug, Clone, PartialEq)]
pub struct Hypothesis {
    pub id: String,
    pub bbox: PixelBox,
    pub tower: Option<String>,
}

/// Identities as dense indices, in order of appearance.
#[derive(Debug, Clone, Default)]
struct Ids(HashMap<String, usize>);

impl Ids {
    fn of(&mut self, id: &str) -> usize {
        let next = self.0.len();
        *self.0.entry(id.to_string()).or_insert(next)
    }
}

#[derive(Debug, Clone, Default)]
pub struct MotAccumulator {
    gt_total: usize,
    hyp_total: usize,
    false_positives: usize,
    misses: usize,
    id_switches: usize,
    /// gt id -> the hypothesis it was last matched to, ever (for switches).
    prev_hyp: HashMap<String, String>,
    /// gt id -> its hypothesis in the previous frame (for continuity).
    prev_frame_hyp: HashMap<String, String>,
    /// gt id -> times its tracking started again (for fragmentation).
    starts: HashMap<String, usize>,
    gt_seen: BTreeSet<String>,
    /// (gt, hyp) -> frames where they overlap enough: for IDF1.
    pair_frames: HashMap<(String, String), usize>,
    hyp_to_gt: HashMap<String, HashSet<String>>,
    gt_to_hyp: HashMap<String, HashSet<String>>,
    bound_frames: usize,
    bound_right: usize,
    matched_frames: usize,
    matched_bound: usize,
    hota_frames: Vec<HotaFrame>,
    gt_ids: Ids,
    hyp_ids: Ids,
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
    pub hota: Hota,
    /// Hypothesis IDs that covered a true tower at least once, and true towers seen.
    pub distinct_ids: usize,
    pub true_towers: usize,
    pub repetitive_errors: usize,
    pub hop_errors: usize,
    /// Of track-frames bound to a tower, the share bound to the tower their
    /// box lies on (`tower_under`; a box on no tower is wrong whatever its binding).
    pub binding_accuracy: f64,
    /// Of track-frames covering a true tower, the share that carry a binding.
    pub binding_coverage: f64,
}

/// A bound box is judged by identity alone, not by how well it is drawn:
/// a loose box on its tower is right, as the localizer reads it so.
pub const ON_TOWER_IOU: f64 = 0.3;

/// The true tower a box lies on: the one it overlaps most, if by
/// `ON_TOWER_IOU` or more.
pub fn tower_under<'a>(truth: &'a [(String, PixelBox)], bbox: &PixelBox) -> Option<&'a String> {
    truth
        .iter()
        .map(|(id, b)| (id, b.iou(bbox)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|&(_, iou)| iou >= ON_TOWER_IOU)
        .map(|(id, _)| id)
}

/// Hypotheses left once those a one-to-one IoU matching over every true
/// box puts on a "don't care" box are removed, as MOTChallenge removes
/// hypotheses on its distractors.
fn without_dont_care<'a>(
    truth: &[(String, PixelBox)],
    dont_care: &[PixelBox],
    hyps: &'a [Hypothesis],
) -> Vec<&'a Hypothesis> {
    if dont_care.is_empty() || hyps.is_empty() {
        return hyps.iter().collect();
    }
    let all: Vec<&PixelBox> = truth.iter().map(|(_, b)| b).chain(dont_care).collect();
    let removed: HashSet<usize> = max_score_matching(
        all.len(),
        hyps.len(),
        |r, c| all[r].iou(&hyps[c].bbox),
        MATCH_MIN,
    )
    .into_iter()
    .filter(|(r, _)| *r >= truth.len())
    .map(|(_, c)| c)
    .collect();
    hyps.iter()
        .enumerate()
        .filter(|(i, _)| !removed.contains(i))
        .map(|(_, h)| h)
        .collect()
}

impl MotAccumulator {
    /// Add one frame: true boxes by tower id, boxes that are neither to be
    /// found nor false when found (towers too small or hidden to demand),
    /// and the hypotheses.
    pub fn add_frame(
        &mut self,
        truth: &[(String, PixelBox)],
        dont_care: &[PixelBox],
        hyps: &[Hypothesis],
    ) {
        let hyps = without_dont_care(truth, dont_care, hyps);
        self.gt_total += truth.len();
        self.hyp_total += hyps.len();
        for h in &hyps {
            if let Some(tower) = &h.tower {
                self.bound_frames += 1;
                self.bound_right += usize::from(tower_under(truth, &h.bbox) == Some(tower));
            }
        }
        let iou: Vec<f64> = truth
            .iter()
            .flat_map(|(_, g)| hyps.iter().map(move |h| g.iou(&h.bbox)))
            .collect();
        let sim = |gi: usize, hi: usize| iou[gi * hyps.len() + hi];
        for (gi, (g, _)) in truth.iter().enumerate() {
            self.gt_seen.insert(g.clone());
            for (hi, h) in hyps.iter().enumerate() {
                if sim(gi, hi) >= MATCH_MIN {
                    *self
                        .pair_frames
                        .entry((g.clone(), h.id.clone()))
                        .or_insert(0) += 1;
                }
            }
        }
        let frame = HotaFrame {
            gt: truth.iter().map(|(g, _)| self.gt_ids.of(g)).collect(),
            hyp: hyps.iter().map(|h| self.hyp_ids.of(&h.id)).collect(),
            iou: iou.clone(),
        };
        self.hota_frames.push(frame);
        if truth.is_empty() || hyps.is_empty() {
            // TrackEval keeps the previous frame's pairs across such a frame.
            self.false_positives += hyps.len();
            self.misses += truth.len();
            return;
        }
        let pairs = max_score_matching(
            truth.len(),
            hyps.len(),
            |gi, hi| {
                let s = sim(gi, hi);
                let continued = self.prev_frame_hyp.get(&truth[gi].0) == Some(&hyps[hi].id);
                if s < MATCH_MIN {
                    0.0
                } else {
                    s + if continued { CONTINUITY_BONUS } else { 0.0 }
                }
            },
            MATCH_MIN,
        );
        let mut taken = vec![false; hyps.len()];
        let mut now: HashMap<String, String> = HashMap::new();
        for &(gi, hi) in &pairs {
            let (g, h) = (&truth[gi].0, hyps[hi]);
            if self.prev_hyp.get(g).is_some_and(|p| p != &h.id) {
                self.id_switches += 1;
            }
            if !self.prev_frame_hyp.contains_key(g) {
                *self.starts.entry(g.clone()).or_insert(0) += 1;
            }
            self.prev_hyp.insert(g.clone(), h.id.clone());
            now.insert(g.clone(), h.id.clone());
            taken[hi] = true;
            self.count_match(g, h);
        }
        self.prev_frame_hyp = now;
        self.misses += truth.len() - pairs.len();
        self.false_positives += taken.iter().filter(|&&t| !t).count();
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
        if h.tower.is_some() {
            self.matched_bound += 1;
        }
    }

    pub fn finish(&self) -> MotMetrics {
        // IDF1: the one-to-one gt/hyp pairing that maximises frames in common.
        let gts: Vec<&String> = self.gt_seen.iter().collect();
        let hyps: Vec<&String> = self.hyp_ids();
        let frames_of = |r: usize, c: usize| {
            self.pair_frames
                .get(&(gts[r].clone(), hyps[c].clone()))
                .copied()
                .unwrap_or(0)
        };
        let idtp: usize =
            max_score_matching(gts.len(), hyps.len(), |r, c| frames_of(r, c) as f64, 0.5)
                .into_iter()
                .map(|(r, c)| frames_of(r, c))
                .sum();
        let ratio = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
        MotMetrics {
            frames_gt: self.gt_total,
            false_positives: self.false_positives,
            misses: self.misses,
            id_switches: self.id_switches,
            fragmentations: self.starts.values().map(|n| n.saturating_sub(1)).sum(),
            mota: 1.0
                - ratio(
                    self.misses + self.false_positives + self.id_switches,
                    self.gt_total,
                ),
            idf1: ratio(2 * idtp, self.gt_total + self.hyp_total),
            hota: hota(&self.hota_frames, self.gt_ids.0.len(), self.hyp_ids.0.len()),
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
        // A1 is tracked as "1", lost for a frame (a box elsewhere that frame:
        // as TrackEval, a frame with no box at all keeps the previous
        // frame's pairs), then as "3" (a hop and a switch, a fragment).
        acc.add_frame(&[("A1".into(), b(0.0))], &[], &[hyp("1", 0.0, Some("A1"))]);
        acc.add_frame(&[("A1".into(), b(0.0))], &[], &[hyp("8", 900.0, None)]);
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
        assert_eq!((m.misses, m.false_positives), (1, 2));
        // Bound track-frames: A1 right, A2-on-A1 wrong, the false positive bound to B1 wrong.
        assert!((m.binding_accuracy - 1.0 / 3.0).abs() < 1e-12);
        assert!((m.mota - (1.0 - 4.0 / 4.0)).abs() < 1e-12);
        // IDF1: best one-to-one pairing covers 1 frame of A1 ("1") and 1 of A2 ("1" taken: "3" for A1)...
        assert!(m.idf1 > 0.0 && m.idf1 < 1.0);
    }

    #[test]
    fn a_loose_box_is_judged_by_the_tower_it_lies_on() {
        // Half the tower's height: IoU 0.5 would miss it, but it is on A1 alone.
        let half = PixelBox::new(0.0, 100.0, 20.0, 140.0);
        let on = |tower: &str| Hypothesis {
            id: "1".into(),
            bbox: half,
            tower: Some(tower.into()),
        };
        let truth = [("A1".to_string(), b(0.0)), ("A2".to_string(), b(300.0))];
        let mut acc = MotAccumulator::default();
        acc.add_frame(&truth, &[], &[on("A1")]);
        acc.add_frame(&truth, &[], &[on("A1")]);
        acc.add_frame(&truth, &[], &[on("A2")]);
        let m = acc.finish();
        assert_eq!(m.false_positives, 3, "no match at IoU 0.5");
        assert!((m.binding_accuracy - 2.0 / 3.0).abs() < 1e-12);
    }

    /// A sequence scored by TrackEval 1.3.0 (`trackeval.Evaluator` on
    /// `MotChallenge2DBox`, default MOT17 settings, metrics HOTA, CLEAR and
    /// Identity): three towers, one don't-care box (class 8, a distractor)
    /// that one hypothesis sits on and later leaves, an ID switch, a gap, a
    /// loose box, a false track and a duplicate.
    const FIXTURE_GT: &str = "\
1,1,105,200,20,100,1,1,1.0
1,2,400,180,30,120,1,1,1.0
1,4,900,300,10,30,0,8,0.2
2,1,110,200,20,100,1,1,1.0
2,2,400,180,30,120,1,1,1.0
2,4,900,300,10,30,0,8,0.2
3,1,115,200,20,100,1,1,1.0
3,2,400,180,30,120,1,1,1.0
3,4,900,300,10,30,0,8,0.2
4,1,120,200,20,100,1,1,1.0
4,2,400,180,30,120,1,1,1.0
4,4,900,300,10,30,0,8,0.2
5,1,125,200,20,100,1,1,1.0
5,2,400,180,30,120,1,1,1.0
5,3,685,150,15,60,1,1,1.0
5,4,900,300,10,30,0,8,0.2
6,1,130,200,20,100,1,1,1.0
6,2,400,180,30,120,1,1,1.0
6,3,682,150,15,60,1,1,1.0
6,4,900,300,10,30,0,8,0.2
7,1,135,200,20,100,1,1,1.0
7,2,400,180,30,120,1,1,1.0
7,3,679,150,15,60,1,1,1.0
7,4,900,300,10,30,0,8,0.2
8,1,140,200,20,100,1,1,1.0
8,2,400,180,30,120,1,1,1.0
8,3,676,150,15,60,1,1,1.0
8,4,900,300,10,30,0,8,0.2
9,1,145,200,20,100,1,1,1.0
9,2,400,180,30,120,1,1,1.0
9,3,673,150,15,60,1,1,1.0
9,4,900,300,10,30,0,8,0.2
10,1,150,200,20,100,1,1,1.0
10,2,400,180,30,120,1,1,1.0
10,3,670,150,15,60,1,1,1.0
10,4,900,300,10,30,0,8,0.2
";
    const FIXTURE_HYPS: &str = "\
1,1,107,202,20,100,1,-1,-1,-1
1,3,401,182,30,118,1,-1,-1,-1
1,5,901,300,10,30,1,-1,-1,-1
2,1,112,202,20,100,1,-1,-1,-1
2,3,401,182,30,118,1,-1,-1,-1
2,5,901,300,10,30,1,-1,-1,-1
3,1,117,202,20,100,1,-1,-1,-1
3,3,406,182,30,118,1,-1,-1,-1
3,5,901,300,10,30,1,-1,-1,-1
4,1,122,202,20,100,1,-1,-1,-1
4,5,907,310,10,30,1,-1,-1,-1
5,1,127,202,20,100,1,-1,-1,-1
5,3,401,182,30,118,1,-1,-1,-1
6,2,132,202,20,100,1,-1,-1,-1
6,3,406,182,30,118,1,-1,-1,-1
6,4,689,152,15,60,1,-1,-1,-1
7,2,137,202,20,100,1,-1,-1,-1
7,3,401,182,30,118,1,-1,-1,-1
7,4,680,152,15,60,1,-1,-1,-1
8,2,142,202,20,100,1,-1,-1,-1
8,3,401,182,30,118,1,-1,-1,-1
8,4,677,152,15,60,1,-1,-1,-1
8,6,1100,400,20,60,1,-1,-1,-1
9,2,147,202,20,100,1,-1,-1,-1
9,3,406,182,30,118,1,-1,-1,-1
9,4,674,152,15,60,1,-1,-1,-1
9,6,1100,400,20,60,1,-1,-1,-1
10,2,152,202,20,100,1,-1,-1,-1
10,3,401,182,30,118,1,-1,-1,-1
10,4,671,152,15,60,1,-1,-1,-1
10,7,151,201,20,100,1,-1,-1,-1
";

    fn mot_box(fields: &[f64]) -> PixelBox {
        PixelBox::new(
            fields[2],
            fields[3],
            fields[2] + fields[4],
            fields[3] + fields[5],
        )
    }

    fn rows(text: &str) -> Vec<Vec<f64>> {
        text.lines()
            .map(|l| l.split(',').map(|v| v.parse().expect("a number")).collect())
            .collect()
    }

    #[test]
    fn a_fixed_sequence_scores_as_trackeval_scores_it() {
        let (gt, hyps) = (rows(FIXTURE_GT), rows(FIXTURE_HYPS));
        let mut acc = MotAccumulator::default();
        for frame in 1..=10 {
            let in_frame = |r: &&Vec<f64>| r[0] == f64::from(frame);
            let truth: Vec<(String, PixelBox)> = gt
                .iter()
                .filter(in_frame)
                .filter(|r| r[7] == 1.0 && r[6] != 0.0)
                .map(|r| (format!("{}", r[1]), mot_box(r)))
                .collect();
            let dont_care: Vec<PixelBox> = gt
                .iter()
                .filter(in_frame)
                .filter(|r| r[7] == 8.0)
                .map(|r| mot_box(r))
                .collect();
            let h: Vec<Hypothesis> = hyps
                .iter()
                .filter(in_frame)
                .map(|r| Hypothesis {
                    id: format!("{}", r[1]),
                    bbox: mot_box(r),
                    tower: None,
                })
                .collect();
            acc.add_frame(&truth, &dont_care, &h);
        }
        let m = acc.finish();
        // TrackEval: CLR_TP 23, CLR_FN 3, CLR_FP 5, IDSW 1, Frag 1,
        // MOTA 0.6538461538461539, IDF1 0.6666666666666666 (IDTP 18),
        // HOTA 0.5994920005941505, DetA 0.6130153527686735,
        // AssA 0.6017548050728829, LocA 0.833089252768689.
        assert_eq!((m.misses, m.false_positives), (3, 5));
        assert_eq!((m.id_switches, m.fragmentations), (1, 1));
        assert!((m.mota - 0.6538461538461539).abs() < 1e-12, "{}", m.mota);
        assert!((m.idf1 - 0.6666666666666666).abs() < 1e-12, "{}", m.idf1);
        assert!(
            (m.hota.hota - 0.5994920005941505).abs() < 1e-6,
            "{:?}",
            m.hota
        );
        assert!(
            (m.hota.det_a - 0.6130153527686735).abs() < 1e-6,
            "{:?}",
            m.hota
        );
        assert!(
            (m.hota.ass_a - 0.6017548050728829).abs() < 1e-6,
            "{:?}",
            m.hota
        );
        assert!(
            (m.hota.loc_a - 0.833089252768689).abs() < 1e-6,
            "{:?}",
            m.hota
        );
    }
}
