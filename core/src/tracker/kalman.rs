//! Constant-velocity Kalman filter in box space: (cx, cy, w, h) and their rates.
//!
//! Noise scales with box height, as in DeepSORT, so near and far towers are
//! trusted alike in relative terms. Rates are per second; `dt` comes from frame times.

use nalgebra::{SMatrix, SVector};
use towernav_geometry::PixelBox;

type State = SVector<f64, 8>;
type Cov = SMatrix<f64, 8, 8>;
type Meas = SVector<f64, 4>;

/// Relative position noise of a measurement (fraction of box height).
const POS_STD: f64 = 0.05;
/// Relative rate noise, per second.
const VEL_STD: f64 = 0.2;

#[derive(Debug, Clone)]
pub struct BoxKalman {
    x: State,
    p: Cov,
}

fn measurement(b: &PixelBox) -> Meas {
    Meas::new(b.center_x(), b.center_y(), b.width(), b.height())
}

impl BoxKalman {
    pub fn new(b: &PixelBox) -> Self {
        let z = measurement(b);
        let h = b.height().max(1.0);
        let mut x = State::zeros();
        x.fixed_rows_mut::<4>(0).copy_from(&z);
        let mut p = Cov::zeros();
        for i in 0..4 {
            p[(i, i)] = (2.0 * POS_STD * h).powi(2);
            p[(i + 4, i + 4)] = (10.0 * VEL_STD * h).powi(2);
        }
        Self { x, p }
    }

    /// Constant-velocity prediction. F = [[I, dt I], [0, I]] couples only each
    /// position with its rate, so F P F^T is done in 4x4 blocks (8x8 products
    /// cost several times more, in every track, every frame).
    pub fn predict(&mut self, dt: f64) {
        let dt = dt.max(0.0);
        let h = self.x[3].max(1.0);
        let rates = self.x.fixed_rows::<4>(4).into_owned();
        self.x.fixed_rows_mut::<4>(0).axpy(dt, &rates, 1.0);
        let p11 = self.p.fixed_view::<4, 4>(0, 0).into_owned();
        let p12 = self.p.fixed_view::<4, 4>(0, 4).into_owned();
        let p21 = self.p.fixed_view::<4, 4>(4, 0).into_owned();
        let p22 = self.p.fixed_view::<4, 4>(4, 4).into_owned();
        let mut n11 = p11 + (p12 + p21) * dt + p22 * (dt * dt);
        let n12 = p12 + p22 * dt;
        let n21 = p21 + p22 * dt;
        let mut n22 = p22;
        for i in 0..4 {
            n11[(i, i)] += (POS_STD * h).powi(2) * dt;
            n22[(i, i)] += (VEL_STD * h).powi(2) * dt;
        }
        self.p.fixed_view_mut::<4, 4>(0, 0).copy_from(&n11);
        self.p.fixed_view_mut::<4, 4>(0, 4).copy_from(&n12);
        self.p.fixed_view_mut::<4, 4>(4, 0).copy_from(&n21);
        self.p.fixed_view_mut::<4, 4>(4, 4).copy_from(&n22);
    }

    /// Measurement update with H = [I 0]: only the position block enters S.
    pub fn update(&mut self, b: &PixelBox) {
        let z = measurement(b);
        let h = self.x[3].max(1.0);
        let mut s = self.p.fixed_view::<4, 4>(0, 0).into_owned();
        for i in 0..4 {
            s[(i, i)] += (POS_STD * h).powi(2);
        }
        let Some(s_inv) = s.try_inverse() else {
            // Degenerate covariance: restart from the measurement rather than diverge.
            *self = Self::new(b);
            return;
        };
        // K = P H^T S^-1 = (first four columns of P) S^-1.
        let p_ht = self.p.fixed_view::<8, 4>(0, 0).into_owned();
        let k = p_ht * s_inv;
        let innovation = z - self.x.fixed_rows::<4>(0);
        self.x += k * innovation;
        // P = P - K H P, and H P is the first four rows of P.
        let hp = self.p.fixed_view::<4, 8>(0, 0).into_owned();
        self.p -= k * hp;
    }

    /// Move the state to where the camera's own motion put the box
    /// (camera-motion compensation): the centre and size follow, rates stay.
    pub fn warp(&mut self, to: &PixelBox) {
        self.x[0] = to.center_x();
        self.x[1] = to.center_y();
        self.x[2] = to.width();
        self.x[3] = to.height();
    }

    /// Squared Mahalanobis distance of a measured box from the predicted one
    /// (4 dof: centre and size), for DeepSORT-style gating.
    pub fn mahalanobis2(&self, b: &PixelBox) -> f64 {
        let h = self.x[3].max(1.0);
        let r = SMatrix::<f64, 4, 4>::from_diagonal_element((POS_STD * h).powi(2));
        let hm = SMatrix::<f64, 4, 8>::identity();
        let s = hm * self.p * hm.transpose() + r;
        let d = measurement(b) - hm * self.x;
        s.try_inverse()
            .map_or(f64::INFINITY, |si| (d.transpose() * si * d)[(0, 0)])
    }

    pub fn bbox(&self) -> PixelBox {
        let (cx, cy) = (self.x[0], self.x[1]);
        let (w, h) = (self.x[2].max(1.0), self.x[3].max(1.0));
        PixelBox::new(cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn learns_a_constant_velocity() {
        let mut kf = BoxKalman::new(&PixelBox::new(100.0, 100.0, 120.0, 200.0));
        for i in 1..=30 {
            kf.predict(1.0 / 30.0);
            let x = 100.0 + 60.0 * i as f64 / 30.0;
            kf.update(&PixelBox::new(x, 100.0, x + 20.0, 200.0));
        }
        kf.predict(0.5);
        let predicted = kf.bbox().center_x();
        assert!(
            (predicted - (110.0 + 60.0 * 1.5)).abs() < 3.0,
            "{predicted}"
        );
    }
}
