//! Surveyed towers as the survey's reference.
//!
//! The views cannot see the GNSS error the whole flight shares: every
//! tower and every camera moved together fit them as well. A record the
//! crew surveyed can. The towers placed by the flight are moved by one
//! translation, the weighted mean of the anchors' offsets, and keep their
//! shape: holding each anchor inside the adjustment instead would make the
//! pose errors of the seconds it was seen explain its box's own errors
//! (the centre off the axis of a near tower), and carry them to every
//! other tower seen then (measured on four rendered flights: held inside,
//! worse than no anchor on two; moved by the translation, better on three).

use nalgebra::{Matrix2, Point2, Vector2};

/// A tower whose place is known independently of the flight (a surveyed
/// record), with its one-sigma horizontal accuracy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    pub foot: Point2<f64>,
    pub sigma_m: f64,
}

/// A record anchors the tower it lies within this many sigmas of, or this
/// close to: a flight's ellipses hold its shared GNSS error only roughly (a
/// lawnmower's 0.7 m offset lay outside a 0.2 m minor axis), so the sigmas
/// alone would refuse the records that correct it.
const GATE_SIGMAS: f64 = 3.0;
const GATE_M: f64 = 2.0;
/// No record is taken as tighter than this: one claiming a millimetre
/// would outweigh every other anchor for nothing.
const MIN_SIGMA_M: f64 = 0.01;

/// The translation that takes the towers onto their anchors, with its
/// covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shift {
    pub by: Vector2<f64>,
    pub covariance: Matrix2<f64>,
}

/// Each anchor given to the nearest tower that holds it within three sigmas
/// of the two together, or within 2 m (one anchor per tower, the nearer
/// kept). A surveyed record that the flight contradicts anchors nothing:
/// it could only pull.
pub fn pair(
    feet: &[Point2<f64>],
    covariances: &[Matrix2<f64>],
    anchors: &[Anchor],
) -> Vec<Option<Anchor>> {
    let mut held: Vec<Option<(Anchor, f64)>> = vec![None; feet.len()];
    for anchor in anchors {
        let fit = feet
            .iter()
            .zip(covariances)
            .enumerate()
            .filter_map(|(j, (f, c))| {
                let d = anchor.foot - f;
                let m2 = (d.transpose() * combined(c, anchor).try_inverse()? * d)[0];
                let inside = m2 <= GATE_SIGMAS.powi(2) || d.norm() <= GATE_M;
                inside.then_some((j, d.norm()))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((j, d)) = fit
            && held[j].is_none_or(|(_, kept)| d < kept)
        {
            held[j] = Some((*anchor, d));
        }
    }
    held.into_iter().map(|h| h.map(|(a, _)| a)).collect()
}

/// The weighted mean of the paired anchors' offsets (record minus tower),
/// each weighted by the inverse of the tower's and the record's
/// covariances together, with a prior of `prior_sigma_m` (the GNSS error's
/// sigma: the error the flight shares is no larger) about no shift, so
/// that one anchor placed loosely along its rays moves the rest by little
/// along them; `None` without a pair.
pub fn shift(
    feet: &[Point2<f64>],
    covariances: &[Matrix2<f64>],
    paired: &[Option<Anchor>],
    prior_sigma_m: f64,
) -> Option<Shift> {
    paired.iter().any(Option::is_some).then_some(())?;
    let mut information = Matrix2::identity() / prior_sigma_m.max(MIN_SIGMA_M).powi(2);
    let mut sum = Vector2::zeros();
    for ((f, c), anchor) in feet.iter().zip(covariances).zip(paired) {
        let Some(anchor) = anchor else { continue };
        let w = combined(c, anchor).try_inverse()?;
        information += w;
        sum += w * (anchor.foot - f);
    }
    let covariance = information.try_inverse()?;
    Some(Shift {
        by: covariance * sum,
        covariance,
    })
}

fn combined(tower: &Matrix2<f64>, anchor: &Anchor) -> Matrix2<f64> {
    tower + Matrix2::identity() * anchor.sigma_m.max(MIN_SIGMA_M).powi(2)
}

#[cfg(test)]
#[path = "anchor_tests.rs"]
mod tests;
