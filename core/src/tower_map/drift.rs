//! How the log's GNSS error changes over a flight, from its velocities.
//!
//! A receiver's position wanders by metres over tens of seconds; its
//! velocity, from the carrier's Doppler shift, is good to centimetres a
//! second. So the logged position less the track its velocities integrate
//! to is the position's error plus one unknown constant: between two
//! seconds it changes as the error does, to what the velocity's own error
//! integrates to. The adjustment takes those changes as measurements
//! beside its Gauss-Markov prior, which alone lets the error of one second
//! differ from the next by 0.64 m (1.5 m, 10 s).

use nalgebra::{Point2, Vector2};

/// One fix of the log, on the flight's clock, in the world's east-north.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftFix {
    pub time_s: f64,
    pub position: Point2<f64>,
    pub velocity: Vector2<f64>,
}

/// Fixes further apart than this break the track: the velocity between
/// them is not known.
const MAX_GAP_S: f64 = 2.0;
/// The windows `window_miss` compares the two tracks over.
const WINDOW_S: f64 = 10.0;

/// The logged position less the integrated velocity, over each unbroken
/// stretch of fixes with a velocity.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GnssDrift {
    stretches: Vec<Vec<(f64, Vector2<f64>)>>,
}

impl GnssDrift {
    /// From the fixes in time order; a fix out of order or further than
    /// 2 s from the last starts a new stretch.
    pub fn new(fixes: &[DriftFix]) -> Self {
        let mut stretches: Vec<Vec<(f64, Vector2<f64>)>> = Vec::new();
        let mut flown = Vector2::zeros();
        let mut last: Option<&DriftFix> = None;
        for f in fixes {
            let joined =
                last.is_some_and(|l| f.time_s > l.time_s && f.time_s - l.time_s <= MAX_GAP_S);
            match last.filter(|_| joined) {
                Some(l) => flown += (l.velocity + f.velocity) * (0.5 * (f.time_s - l.time_s)),
                None => {
                    flown = Vector2::zeros();
                    stretches.push(Vec::new());
                }
            }
            if let Some(s) = stretches.last_mut() {
                s.push((f.time_s, f.position.coords - flown));
            }
            last = Some(f);
        }
        stretches.retain(|s| s.len() >= 2);
        Self { stretches }
    }

    pub fn is_empty(&self) -> bool {
        self.stretches.is_empty()
    }

    /// How much the GNSS error changed from `from_s` to `to_s`; `None`
    /// where the two are not within one unbroken stretch.
    pub fn change(&self, from_s: f64, to_s: f64) -> Option<Vector2<f64>> {
        let s = self.stretches.iter().find(|s| covers(s, from_s))?;
        covers(s, to_s).then(|| at(s, to_s) - at(s, from_s))
    }

    /// How far the velocities' track misses the positions' over 10 s
    /// windows, the median, metres: what the GNSS error wanders in 10 s
    /// (`expected_window_miss`) where the velocities are right, far more
    /// where they are read wrong (units, axes, a lag) or made up.
    pub fn window_miss(&self) -> Option<f64> {
        let mut misses = Vec::new();
        for s in &self.stretches {
            for (i, &(t0, _)) in s.iter().enumerate() {
                let Some(j) = s[i..].iter().position(|(t, _)| *t >= t0 + WINDOW_S) else {
                    break;
                };
                let (t1, _) = s[i + j];
                misses.push((at(s, t1) - at(s, t0)).norm());
            }
        }
        if misses.is_empty() {
            return None;
        }
        misses.sort_by(f64::total_cmp);
        Some(misses[misses.len() / 2])
    }
}

/// The median of `window_miss` for right velocities and a Gauss-Markov
/// GNSS error of `sigma_m` per axis and `correlation_s`: the change over
/// 10 s has `sigma_m * sqrt(2 (1 - exp(-10 / correlation_s)))` per axis,
/// and the median length of a 2-D normal vector is 1.18 of that.
pub fn expected_window_miss(sigma_m: f64, correlation_s: f64) -> f64 {
    let keep = if correlation_s > 0.0 {
        (-WINDOW_S / correlation_s).exp()
    } else {
        0.0
    };
    1.18 * sigma_m * (2.0 * (1.0 - keep)).sqrt()
}

fn covers(s: &[(f64, Vector2<f64>)], t: f64) -> bool {
    matches!((s.first(), s.last()), (Some(a), Some(b)) if a.0 <= t && t <= b.0)
}

/// The stretch's value at `t`, linear between fixes.
fn at(s: &[(f64, Vector2<f64>)], t: f64) -> Vector2<f64> {
    let i = s.partition_point(|(ts, _)| *ts < t).clamp(1, s.len() - 1);
    let ((ta, a), (tb, b)) = (s[i - 1], s[i]);
    let w = if tb > ta {
        ((t - ta) / (tb - ta)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + (b - a) * w
}

#[cfg(test)]
#[path = "drift_tests.rs"]
mod tests;
