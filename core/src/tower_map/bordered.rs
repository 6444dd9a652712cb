//! Normal equations shaped like a survey's: a few unknowns per second of
//! flight, each second tied only to the next (a block-tridiagonal part),
//! bordered by the towers' unknowns, which every second may touch. Solved
//! by eliminating the seconds (block LDL^T, then the towers' Schur
//! complement), so an hour of flight costs what its length does, not its
//! cube.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix3xX, Vector3};

/// `[tt tb; tb^T bb] [x_t; x_b] = [rhs_t; rhs_b]`, `bb` block-tridiagonal
/// with 3x3 blocks.
#[derive(Debug, Clone)]
pub struct Bordered {
    pub tt: DMatrix<f64>,
    /// Towers by seconds: `tt.nrows()` x `3 * seconds`.
    pub tb: DMatrix<f64>,
    pub diagonal: Vec<Matrix3<f64>>,
    /// `below[k]` is the block of row `k`, column `k - 1` (`below[0]` unused).
    pub below: Vec<Matrix3<f64>>,
    pub rhs_t: DVector<f64>,
    pub rhs_b: Vec<Vector3<f64>>,
}

/// The solution, and the towers' covariance (the inverse of their Schur
/// complement: the seconds' unknowns marginalised out).
#[derive(Debug, Clone)]
pub struct Solution {
    pub towers: DVector<f64>,
    pub seconds: Vec<Vector3<f64>>,
    pub towers_covariance: DMatrix<f64>,
}

impl Bordered {
    pub fn zeros(towers: usize, seconds: usize) -> Self {
        Self {
            tt: DMatrix::zeros(towers, towers),
            tb: DMatrix::zeros(towers, 3 * seconds),
            diagonal: vec![Matrix3::zeros(); seconds],
            below: vec![Matrix3::zeros(); seconds],
            rhs_t: DVector::zeros(towers),
            rhs_b: vec![Vector3::zeros(); seconds],
        }
    }

    /// `None` where the system is not positive definite.
    pub fn solve(&self) -> Option<Solution> {
        let n = self.tt.nrows();
        let seconds = self.diagonal.len();
        // Right-hand sides for the seconds' block: tb^T's columns, then rhs_b.
        let mut r: Vec<Matrix3xX<f64>> = (0..seconds)
            .map(|k| {
                let mut m = Matrix3xX::zeros(n + 1);
                for row in 0..3 {
                    for j in 0..n {
                        m[(row, j)] = self.tb[(j, 3 * k + row)];
                    }
                    m[(row, n)] = self.rhs_b[k][row];
                }
                m
            })
            .collect();
        // Block LDL^T: d[k] = A_kk - L_k A_{k-1,k}, L_k = A_{k,k-1} d[k-1]^-1.
        let mut d_inv: Vec<Matrix3<f64>> = Vec::with_capacity(seconds);
        let mut l: Vec<Matrix3<f64>> = vec![Matrix3::zeros(); seconds];
        for k in 0..seconds {
            let mut d = self.diagonal[k];
            if k > 0 {
                l[k] = self.below[k] * d_inv[k - 1];
                d -= l[k] * self.below[k].transpose();
                let (head, tail) = r.split_at_mut(k);
                tail[0] -= l[k] * &head[k - 1];
            }
            d_inv.push(d.cholesky()?.inverse());
        }
        for k in (0..seconds).rev() {
            if k + 1 < seconds {
                let (head, tail) = r.split_at_mut(k + 1);
                head[k] -= self.below[k + 1].transpose() * &tail[0];
            }
            r[k] = d_inv[k] * &r[k];
        }
        // r now holds bb^-1 [tb^T | rhs_b]: the towers' Schur complement.
        let mut schur = self.tt.clone();
        let mut reduced = self.rhs_t.clone();
        for (k, rk) in r.iter().enumerate() {
            let tb_k = self.tb.columns(3 * k, 3);
            schur -= tb_k * rk.columns(0, n);
            reduced -= tb_k * rk.column(n);
        }
        let chol = schur.cholesky()?;
        let towers = chol.solve(&reduced);
        let towers_covariance = chol.inverse();
        let seconds = r
            .iter()
            .map(|rk| rk.column(n) - rk.columns(0, n) * &towers)
            .collect();
        Some(Solution {
            towers,
            seconds,
            towers_covariance,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same system as one dense matrix.
    fn dense(b: &Bordered) -> (DMatrix<f64>, DVector<f64>) {
        let n = b.tt.nrows();
        let m = n + 3 * b.diagonal.len();
        let mut a = DMatrix::zeros(m, m);
        a.view_mut((0, 0), (n, n)).copy_from(&b.tt);
        a.view_mut((0, n), (n, m - n)).copy_from(&b.tb);
        a.view_mut((n, 0), (m - n, n)).copy_from(&b.tb.transpose());
        for k in 0..b.diagonal.len() {
            let i = n + 3 * k;
            a.view_mut((i, i), (3, 3)).copy_from(&b.diagonal[k]);
            if k > 0 {
                a.view_mut((i, i - 3), (3, 3)).copy_from(&b.below[k]);
                a.view_mut((i - 3, i), (3, 3))
                    .copy_from(&b.below[k].transpose());
            }
        }
        let mut rhs = DVector::zeros(m);
        rhs.rows_mut(0, n).copy_from(&b.rhs_t);
        for k in 0..b.diagonal.len() {
            rhs.fixed_rows_mut::<3>(n + 3 * k).copy_from(&b.rhs_b[k]);
        }
        (a, rhs)
    }

    #[test]
    fn agrees_with_the_dense_solve() {
        // A random positive definite system of this shape, seeded.
        let (towers, seconds) = (4, 7);
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut b = Bordered::zeros(towers, seconds);
        b.tb = DMatrix::from_fn(towers, 3 * seconds, |_, _| next());
        for k in 0..seconds {
            b.below[k] = Matrix3::from_fn(|_, _| next()) * 0.3;
            b.rhs_b[k] = Vector3::from_fn(|_, _| next());
        }
        b.rhs_t = DVector::from_fn(towers, |_, _| next());
        // Diagonally dominant: positive definite.
        b.tt = DMatrix::identity(towers, towers) * 20.0;
        for k in 0..seconds {
            b.diagonal[k] = Matrix3::identity() * 20.0;
        }
        let (a, rhs) = dense(&b);
        let x = a.clone().cholesky().expect("definite").solve(&rhs);
        let covariance = a.cholesky().expect("definite").inverse();
        let s = b.solve().expect("definite");
        assert!((s.towers - x.rows(0, towers)).norm() < 1e-10);
        for k in 0..seconds {
            assert!((s.seconds[k] - x.fixed_rows::<3>(towers + 3 * k)).norm() < 1e-10);
        }
        assert!((s.towers_covariance - covariance.view((0, 0), (towers, towers))).norm() < 1e-10);
    }
}
