//! One-to-one matching by maximum total score (Hungarian / Kuhn-Munkres, from `pathfinding`).

use pathfinding::prelude::{Matrix, kuhn_munkres};

/// Scores are fixed-point for the integer solver; 1e6 keeps six decimals.
const SCALE: f64 = 1e6;

/// Matches rows to columns maximising the total score. Pairs whose score is
/// below `min_score` (or not finite) are never returned.
pub fn max_score_matching(
    rows: usize,
    cols: usize,
    score: impl Fn(usize, usize) -> f64,
    min_score: f64,
) -> Vec<(usize, usize)> {
    if rows == 0 || cols == 0 {
        return Vec::new();
    }
    let allowed = |r: usize, c: usize| {
        let s = score(r, c);
        (s.is_finite() && s >= min_score && s > 0.0).then_some(s)
    };
    let weight = |r: usize, c: usize| allowed(r, c).map_or(0, |s| (s * SCALE).round() as i64);
    // kuhn_munkres needs no more rows than columns.
    let transpose = rows > cols;
    let (n, m) = if transpose {
        (cols, rows)
    } else {
        (rows, cols)
    };
    let mut data = Vec::with_capacity(n * m);
    for i in 0..n {
        for j in 0..m {
            data.push(if transpose {
                weight(j, i)
            } else {
                weight(i, j)
            });
        }
    }
    let Ok(matrix) = Matrix::from_vec(n, m, data) else {
        return Vec::new();
    };
    let (_, assigned) = kuhn_munkres(&matrix);
    assigned
        .into_iter()
        .enumerate()
        .map(|(i, j)| if transpose { (j, i) } else { (i, j) })
        .filter(|&(r, c)| allowed(r, c).is_some())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn picks_the_best_total_not_the_greedy_pair() {
        // Greedy would take (0,0)=0.9 and leave row 1 with 0.1; optimum is 0.8 + 0.8.
        let s = [[0.9, 0.8], [0.8, 0.1]];
        let mut m = max_score_matching(2, 2, |r, c| s[r][c], 0.0);
        m.sort();
        assert_eq!(m, [(0, 1), (1, 0)]);
    }

    #[test]
    fn pairs_under_the_threshold_are_dropped_and_shapes_may_differ() {
        let s = [[0.5], [0.05], [0.7]];
        assert_eq!(max_score_matching(3, 1, |r, c| s[r][c], 0.3), [(2, 0)]);
        assert!(max_score_matching(0, 4, |_, _| 1.0, 0.0).is_empty());
    }

    proptest! {
        #[test]
        fn matching_is_one_to_one(rows in 1usize..6, cols in 1usize..6, seed in proptest::collection::vec(0.0f64..1.0, 36)) {
            let m = max_score_matching(rows, cols, |r, c| seed[r * 6 + c], 0.2);
            let mut rs: Vec<_> = m.iter().map(|p| p.0).collect();
            let mut cs: Vec<_> = m.iter().map(|p| p.1).collect();
            rs.sort(); rs.dedup(); cs.sort(); cs.dedup();
            prop_assert_eq!(rs.len(), m.len());
            prop_assert_eq!(cs.len(), m.len());
            prop_assert!(m.iter().all(|&(r, c)| seed[r * 6 + c] >= 0.2));
        }
    }
}
