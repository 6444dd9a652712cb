//! HOTA (Luiten et al., IJCV 2021) with its detection and association parts,
//! DetA and AssA, as TrackEval computes them for one sequence: each frame's
//! boxes matched to maximise global alignment times IoU, then scored at IoU
//! thresholds 0.05 to 0.95 and averaged.

use towernav_core::assignment::max_score_matching;

/// The 19 IoU thresholds, 0.05 to 0.95.
fn alphas() -> impl Iterator<Item = f64> {
    (1..=19).map(|i| f64::from(i) * 0.05)
}

/// Scores below this are not in a frame's matching (TrackEval's float epsilon).
const EPS: f64 = f64::EPSILON;

/// The Hungarian solver works in fixed point: scale the small products of
/// alignment and IoU so that six decimals of the solver's are nine of ours.
const FINE: f64 = 1e3;

/// One frame: the true and hypothesised identities present (as indices) and
/// their IoU, row-major (truth by hypothesis).
#[derive(Debug, Clone, Default)]
pub struct HotaFrame {
    pub gt: Vec<usize>,
    pub hyp: Vec<usize>,
    pub iou: Vec<f64>,
}

impl HotaFrame {
    fn sim(&self, r: usize, c: usize) -> f64 {
        self.iou[r * self.hyp.len() + c]
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Hota {
    pub hota: f64,
    pub det_a: f64,
    pub ass_a: f64,
    pub loc_a: f64,
}

/// HOTA of one sequence of `frames`, with `gt_ids` and `hyp_ids` distinct identities.
pub fn hota(frames: &[HotaFrame], gt_ids: usize, hyp_ids: usize) -> Hota {
    let gt_dets: usize = frames.iter().map(|f| f.gt.len()).sum();
    let hyp_dets: usize = frames.iter().map(|f| f.hyp.len()).sum();
    if gt_dets == 0 || hyp_dets == 0 {
        return Hota {
            loc_a: 1.0,
            ..Hota::default()
        };
    }
    // Global alignment between identities, from IoU normalised per frame.
    let mut potential = vec![0.0; gt_ids * hyp_ids];
    let mut gt_count = vec![0.0; gt_ids];
    let mut hyp_count = vec![0.0; hyp_ids];
    for f in frames {
        let (n, m) = (f.gt.len(), f.hyp.len());
        let row_sum: Vec<f64> = (0..n).map(|r| (0..m).map(|c| f.sim(r, c)).sum()).collect();
        let col_sum: Vec<f64> = (0..m).map(|c| (0..n).map(|r| f.sim(r, c)).sum()).collect();
        for r in 0..n {
            for c in 0..m {
                let denom = row_sum[r] + col_sum[c] - f.sim(r, c);
                if denom > EPS {
                    potential[f.gt[r] * hyp_ids + f.hyp[c]] += f.sim(r, c) / denom;
                }
            }
        }
        for &g in &f.gt {
            gt_count[g] += 1.0;
        }
        for &h in &f.hyp {
            hyp_count[h] += 1.0;
        }
    }
    let alignment = |g: usize, h: usize| {
        let p = potential[g * hyp_ids + h];
        p / (gt_count[g] + hyp_count[h] - p)
    };

    let n_alpha = alphas().count();
    let mut tp = vec![0.0; n_alpha];
    let mut fne = vec![0.0; n_alpha];
    let mut fp = vec![0.0; n_alpha];
    let mut loc = vec![0.0; n_alpha];
    let mut matches = vec![vec![0.0; gt_ids * hyp_ids]; n_alpha];
    for f in frames {
        let (n, m) = (f.gt.len(), f.hyp.len());
        if n == 0 || m == 0 {
            for a in 0..n_alpha {
                fp[a] += m as f64;
                fne[a] += n as f64;
            }
            continue;
        }
        let pairs = max_score_matching(
            n,
            m,
            |r, c| FINE * alignment(f.gt[r], f.hyp[c]) * f.sim(r, c),
            EPS,
        );
        for (a, alpha) in alphas().enumerate() {
            let kept: Vec<&(usize, usize)> = pairs
                .iter()
                .filter(|(r, c)| f.sim(*r, *c) >= alpha - EPS)
                .collect();
            let k = kept.len() as f64;
            tp[a] += k;
            fne[a] += n as f64 - k;
            fp[a] += m as f64 - k;
            for (r, c) in kept {
                loc[a] += f.sim(*r, *c);
                matches[a][f.gt[*r] * hyp_ids + f.hyp[*c]] += 1.0;
            }
        }
    }
    let mut sum = Hota::default();
    for a in 0..n_alpha {
        let mut ass = 0.0;
        for g in 0..gt_ids {
            for h in 0..hyp_ids {
                let k = matches[a][g * hyp_ids + h];
                if k > 0.0 {
                    ass += k * k / (gt_count[g] + hyp_count[h] - k).max(1.0);
                }
            }
        }
        let ass_a = ass / tp[a].max(1.0);
        let det_a = tp[a] / (tp[a] + fne[a] + fp[a]).max(1.0);
        sum.hota += (det_a * ass_a).sqrt();
        sum.det_a += det_a;
        sum.ass_a += ass_a;
        sum.loc_a += loc[a].max(1e-10) / tp[a].max(1e-10);
    }
    let n = n_alpha as f64;
    Hota {
        hota: sum.hota / n,
        det_a: sum.det_a / n,
        ass_a: sum.ass_a / n,
        loc_a: sum.loc_a / n,
    }
}
