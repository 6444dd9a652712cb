//! Lens distortion as OpenCV models it, on normalized image coordinates
//! (`x = X/Z`, `y = Y/Z` in the camera frame): the radial-tangential
//! ("plumb bob") model of `cv::projectPoints` and the equidistant fisheye of
//! `cv::fisheye`. Distorting is closed-form; undistorting is Newton's method,
//! which is what makes calibrated boxes usable by the pinhole geometry.

use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};

/// How a real lens bends rays before they reach the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum Distortion {
    /// An ideal pinhole (or frames undistorted upstream).
    #[default]
    None,
    /// OpenCV's radial-tangential model: coefficients in OpenCV's order
    /// `k1, k2, p1, p2, k3`.
    RadialTangential {
        k1: f64,
        k2: f64,
        p1: f64,
        p2: f64,
        #[serde(default)]
        k3: f64,
    },
    /// OpenCV's fisheye (equidistant) model, `k1..k4` on the angle from the axis.
    Fisheye { k1: f64, k2: f64, k3: f64, k4: f64 },
}

/// Newton stops when a step moves less than this (normalized units, ~1e-9 px).
const STEP_TOLERANCE: f64 = 1e-13;
const MAX_ITERATIONS: usize = 50;

impl Distortion {
    pub fn is_none(&self) -> bool {
        matches!(self, Self::None)
    }

    /// The coefficients in OpenCV's order, for validation and messages.
    pub fn coefficients(&self) -> Vec<f64> {
        match *self {
            Self::None => Vec::new(),
            Self::RadialTangential { k1, k2, p1, p2, k3 } => vec![k1, k2, p1, p2, k3],
            Self::Fisheye { k1, k2, k3, k4 } => vec![k1, k2, k3, k4],
        }
    }

    /// Where a ray through the camera-frame point `(x, y, z)` lands, in
    /// normalized distorted coordinates; `None` behind the camera.
    pub fn distort_ray(&self, x: f64, y: f64, z: f64) -> Option<Vector2<f64>> {
        if z <= 1e-9 {
            return None;
        }
        match *self {
            Self::Fisheye { .. } => {
                // The angle from the axis straight from the ray, exact at wide angles.
                let r = x.hypot(y);
                if r < 1e-300 {
                    return Some(Vector2::zeros());
                }
                let theta = r.atan2(z);
                Some(Vector2::new(x, y) * (self.fisheye_theta_d(theta) / r))
            }
            _ => Some(self.distort(Vector2::new(x / z, y / z))),
        }
    }

    /// The distorted normalized point of an ideal one.
    pub fn distort(&self, p: Vector2<f64>) -> Vector2<f64> {
        match *self {
            Self::None => p,
            Self::RadialTangential { k1, k2, p1, p2, k3 } => {
                let (x, y) = (p.x, p.y);
                let r2 = x * x + y * y;
                let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                Vector2::new(
                    x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                    y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
                )
            }
            Self::Fisheye { .. } => {
                let r = p.norm();
                if r < 1e-300 {
                    return p;
                }
                p * (self.fisheye_theta_d(r.atan()) / r)
            }
        }
    }

    /// The ideal normalized point whose distortion is `d`; `None` where
    /// the model cannot be inverted there (far outside its calibrated field).
    pub fn undistort(&self, d: Vector2<f64>) -> Option<Vector2<f64>> {
        match *self {
            Self::None => Some(d),
            Self::RadialTangential { k1, k2, p1, p2, k3 } => {
                let mut p = d;
                for _ in 0..MAX_ITERATIONS {
                    let (x, y) = (p.x, p.y);
                    let r2 = x * x + y * y;
                    let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                    let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2); // d(radial)/d(r2)
                    let residual = self.distort(p) - d;
                    let jacobian = Matrix2::new(
                        radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
                        2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
                        2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
                        radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
                    );
                    let step = jacobian.try_inverse()? * residual;
                    p -= step;
                    if !p.x.is_finite() || !p.y.is_finite() {
                        return None;
                    }
                    if step.norm() < STEP_TOLERANCE {
                        return (self.distort(p) - d).norm().lt(&1e-9).then_some(p);
                    }
                }
                (self.distort(p) - d).norm().lt(&1e-9).then_some(p)
            }
            Self::Fisheye { .. } => {
                let theta_d = d.norm();
                if theta_d < 1e-300 {
                    return Some(d);
                }
                let theta = self.fisheye_theta(theta_d)?;
                if theta >= std::f64::consts::FRAC_PI_2 {
                    return None;
                }
                Some(d * (theta.tan() / theta_d))
            }
        }
    }

    fn fisheye_poly(&self) -> [f64; 4] {
        match *self {
            Self::Fisheye { k1, k2, k3, k4 } => [k1, k2, k3, k4],
            _ => [0.0; 4],
        }
    }

    /// `theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`.
    fn fisheye_theta_d(&self, theta: f64) -> f64 {
        let [k1, k2, k3, k4] = self.fisheye_poly();
        let t2 = theta * theta;
        theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    }

    fn fisheye_theta(&self, theta_d: f64) -> Option<f64> {
        let [k1, k2, k3, k4] = self.fisheye_poly();
        let mut theta = theta_d;
        for _ in 0..MAX_ITERATIONS {
            let t2 = theta * theta;
            let derivative =
                1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
            if derivative.abs() < 1e-12 {
                return None;
            }
            let step = (self.fisheye_theta_d(theta) - theta_d) / derivative;
            theta -= step;
            if step.abs() < STEP_TOLERANCE {
                break;
            }
        }
        ((self.fisheye_theta_d(theta) - theta_d).abs() < 1e-9 && theta >= 0.0).then_some(theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_distortion_is_the_identity() {
        let p = Vector2::new(0.3, -0.2);
        assert_eq!(Distortion::None.distort(p), p);
        assert_eq!(Distortion::None.undistort(p), Some(p));
    }

    #[test]
    fn barrel_distortion_pulls_points_in() {
        let d = Distortion::RadialTangential {
            k1: -0.3,
            k2: 0.1,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        };
        let p = Vector2::new(0.5, 0.3);
        assert!(d.distort(p).norm() < p.norm());
        let back = d.undistort(d.distort(p)).expect("invertible");
        assert!((back - p).norm() < 1e-12);
    }

    #[test]
    fn the_fisheye_ray_and_point_forms_agree() {
        let d = Distortion::Fisheye {
            k1: -0.01,
            k2: 0.003,
            k3: -0.001,
            k4: 0.0002,
        };
        let from_ray = d.distort_ray(0.4, -0.25, 2.0).expect("ahead");
        let from_point = d.distort(Vector2::new(0.2, -0.125));
        assert!((from_ray - from_point).norm() < 1e-14);
        assert!(d.distort_ray(0.1, 0.1, -1.0).is_none());
    }
}
