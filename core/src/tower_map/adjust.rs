//! Every tower of a flight placed at once, with the pose's errors solved
//! beside them.
//!
//! Towers triangulated one by one each inherit the GNSS error averaged over
//! their own views, and the heading error of each pass. Those errors are
//! shared: every tower in view at one moment sees the camera from the same
//! wrong place and turned by the same wrong heading. So the adjustment
//! solves, with the feet, the GNSS error of each second of flight and the
//! heading error of each second, each a first-order Gauss-Markov process
//! with the receiver's and the attitude's sigma and correlation time as its
//! prior, and one constant yaw of the camera against the attitude for the
//! whole flight (its boresight). What the views cannot tell apart (all
//! towers and all camera positions moved together) stays with the prior:
//! the flight's mean GNSS error, which the covariance reports.
//!
//! Where the log gives velocities, how the GNSS error changed from one
//! second to the next is measured too (`drift`): the logged track less the
//! one its velocities integrate to.
//!
//! Each view gives one equation, its measured bearing against the bearing
//! from its corrected camera to its tower, linearised about the current
//! estimate: `n . (foot + gnss_error) + range * (heading_error + boresight)
//! = n . (foot0 + gnss_error0) + range * (measured - predicted bearing)`,
//! with `n` the unit normal of the predicted bearing. Gauss-Newton with
//! Huber weights, a fixed number of rounds; each round's system is solved
//! by `bordered`.

use std::collections::BTreeMap;

use nalgebra::{Matrix2, Matrix3, Point2, Rotation3, Vector2, Vector3};
use towernav_geometry::wrap_angle;

use super::bordered::Bordered;
use super::drift::GnssDrift;
use super::triangulate::{TowerView, TriangulationParams};

/// Seconds of flight that share one GNSS error and one heading error.
const BIN_S: f64 = 1.0;
const ROUNDS: usize = 8;
/// A velocity's error is forgotten within this, s: over a gap of `t`
/// seconds the velocities' track wanders by `sigma * sqrt(2 * this * t)`.
const VELOCITY_CORRELATION_S: f64 = 1.0;
/// How far a tower may be from where it started, one sigma: no constraint
/// at all, only there so that a tower without views leaves the system
/// solvable.
const START_SIGMA_M: f64 = 1e4;
/// A view's line is never trusted closer than this: within 150 m the box's
/// centre leaves the axis of a 6-9 m wide lattice tower by 0.2 degrees
/// (one sigma, measured on a rendered survey with exact poses), about
/// 0.4 m at the range where most near views are.
pub const MIN_LINE_SIGMA_M: f64 = 0.4;

/// The feet, their covariances and the camera's position error over time.
#[derive(Debug, Clone)]
pub struct Adjustment {
    pub feet: Vec<Point2<f64>>,
    pub covariances: Vec<Matrix2<f64>>,
    /// Each view's weight in the last round (Huber, 1 for an inlier), per
    /// tower, in the views' order.
    pub weights: Vec<Vec<f64>>,
    gnss: BTreeMap<i64, Vector2<f64>>,
    heading: BTreeMap<i64, f64>,
    /// The camera's constant yaw against the attitude, rad.
    pub boresight: f64,
    /// What the log's velocities say of the GNSS error's change within
    /// each second; empty where they were left out.
    drift: GnssDrift,
}

impl Adjustment {
    /// The GNSS error solved for the second holding `time_s` (zero where no
    /// view was).
    pub fn gnss_error(&self, time_s: f64) -> Vector2<f64> {
        self.gnss
            .get(&bin(time_s))
            .copied()
            .unwrap_or_else(Vector2::zeros)
    }

    /// The heading error solved for the second holding `time_s`, with the
    /// boresight, rad.
    pub fn heading_error(&self, time_s: f64) -> f64 {
        self.heading.get(&bin(time_s)).copied().unwrap_or(0.0) + self.boresight
    }

    /// `view` with its camera moved by the GNSS error and its rays turned
    /// back by the heading error solved for its second.
    pub fn corrected(&self, view: &TowerView) -> TowerView {
        let e = self.gnss_error(view.time_s) + within_second(&self.drift, view.time_s);
        let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), -self.heading_error(view.time_s));
        TowerView {
            camera_in_world: view.camera_in_world - Vector3::new(e.x, e.y, 0.0),
            centre_ray: turn * view.centre_ray,
            top_ray: turn * view.top_ray,
            foot_ray: turn * view.foot_ray,
            ..*view
        }
    }
}

fn bin(time_s: f64) -> i64 {
    (time_s / BIN_S).floor() as i64
}

/// The middle of a second's bin, where its GNSS error is solved.
fn bin_middle(bin: i64) -> f64 {
    (bin as f64 + 0.5) * BIN_S
}

/// How much the GNSS error at `time_s` differs from its second's, by the
/// log's velocities (zero without them): the error wanders by 0.64 m
/// within a second, which the velocities measure to centimetres.
fn within_second(drift: &GnssDrift, time_s: f64) -> Vector2<f64> {
    drift
        .change(bin_middle(bin(time_s)), time_s)
        .unwrap_or_else(Vector2::zeros)
}

/// A view's measured bearing from the camera's logged place.
struct Line {
    tower: usize,
    camera: Point2<f64>,
    /// Radians from east, counter-clockwise.
    bearing: f64,
    second: usize,
    /// 1 over the views of this tower in this second: a tower seen 30 times
    /// a second counts once a second.
    share: f64,
}

/// Where the current estimate puts a view's tower from its corrected
/// camera: range, bearing and the bearing's unit normal.
struct Predicted {
    range: f64,
    bearing: f64,
    normal: Vector2<f64>,
}

impl Predicted {
    fn of(l: &Line, feet: &[Point2<f64>], gnss: &[Vector2<f64>]) -> Self {
        let to = feet[l.tower] - l.camera + gnss[l.second];
        let range = to.norm().max(1.0);
        Self {
            range,
            bearing: to.y.atan2(to.x),
            normal: Vector2::new(-to.y, to.x) / range,
        }
    }

    /// How far off the measured bearing is at the tower's range, metres,
    /// with the second's heading error taken out.
    fn miss(&self, l: &Line, heading: f64) -> f64 {
        self.range * wrap_angle(l.bearing - self.bearing - heading)
    }
}

/// Adjusts the towers `views` shows (one list per tower), starting from
/// `starts`, with the GNSS error's changes `drift` measures (empty: none);
/// `None` where the system is singular.
///
/// Gauss-Newton on the bearings themselves, each linearised about the
/// current estimate: the lines' normals are the predicted bearings', not
/// the measured ones, whose noise would pull every tower seen along a
/// narrow fan of bearings towards the cameras.
pub fn adjust(
    views: &[Vec<TowerView>],
    starts: &[Point2<f64>],
    p: &TriangulationParams,
    drift: &GnssDrift,
) -> Option<Adjustment> {
    let mut seconds = BTreeMap::new();
    for v in views.iter().flatten() {
        seconds.entry(bin(v.time_s)).or_insert(0);
    }
    for (k, index) in seconds.values_mut().enumerate() {
        *index = k;
    }
    let drift = if p.velocity_sigma_mps > 0.0 {
        drift.clone()
    } else {
        GnssDrift::default()
    };
    let lines = lines(views, &seconds, &drift);
    let mut feet = starts.to_vec();
    let mut gnss = vec![Vector2::zeros(); seconds.len()];
    let mut heading = vec![0.0; seconds.len()];
    let mut boresight = 0.0;
    let mut weights: Vec<f64> = vec![1.0; lines.len()];
    let mut covariance = None;
    for round in 0..ROUNDS {
        let predicted: Vec<Predicted> = lines
            .iter()
            .map(|l| Predicted::of(l, &feet, &gnss))
            .collect();
        if round > 0 {
            for ((w, l), at) in weights.iter_mut().zip(&lines).zip(&predicted) {
                let residual = at.miss(l, heading[l.second] + boresight) / line_sigma(at.range, p);
                *w = if residual.abs() <= p.huber_k {
                    1.0
                } else {
                    p.huber_k / residual.abs()
                };
            }
        }
        let s = system(
            &lines,
            &predicted,
            &weights,
            &seconds,
            p,
            starts,
            (&feet, &gnss),
        );
        let s = with_drift(s, &seconds, &drift, p).solve()?;
        for (j, f) in feet.iter_mut().enumerate() {
            *f = Point2::new(s.towers[2 * j], s.towers[2 * j + 1]);
        }
        boresight = s.towers[2 * feet.len()];
        for (k, u) in s.seconds.iter().enumerate() {
            gnss[k] = u.xy();
            heading[k] = u.z;
        }
        covariance = Some(s.towers_covariance);
    }
    let covariance = covariance?;
    let covariances = (0..views.len())
        .map(|j| covariance.fixed_view::<2, 2>(2 * j, 2 * j).into_owned())
        .collect();
    let mut per_tower = vec![Vec::new(); views.len()];
    for (l, w) in lines.iter().zip(weights) {
        per_tower[l.tower].push(w);
    }
    Some(Adjustment {
        feet,
        covariances,
        weights: per_tower,
        gnss: seconds.iter().map(|(b, &k)| (*b, gnss[k])).collect(),
        heading: seconds.iter().map(|(b, &k)| (*b, heading[k])).collect(),
        boresight,
        drift,
    })
}

/// A view's own error at `range`: the box's, at least the tower's width.
fn line_sigma(range: f64, p: &TriangulationParams) -> f64 {
    (range * p.box_sigma_rad).hypot(MIN_LINE_SIGMA_M)
}

/// Each view's line, its camera moved to its second's GNSS error.
fn lines(views: &[Vec<TowerView>], seconds: &BTreeMap<i64, usize>, drift: &GnssDrift) -> Vec<Line> {
    let mut lines = Vec::new();
    for (tower, tower_views) in views.iter().enumerate() {
        let mut per_second: BTreeMap<i64, usize> = BTreeMap::new();
        for v in tower_views {
            *per_second.entry(bin(v.time_s)).or_default() += 1;
        }
        for v in tower_views {
            let d = v.centre_ray.xy();
            if d.norm() < 1e-9 {
                continue;
            }
            let b = bin(v.time_s);
            lines.push(Line {
                tower,
                camera: v.camera_in_world.xy() - within_second(drift, v.time_s),
                bearing: d.y.atan2(d.x),
                second: seconds[&b],
                share: 1.0 / per_second[&b] as f64,
            });
        }
    }
    lines
}

/// The normal equations: the views, then the priors. The border holds the
/// feet, then the boresight.
fn system(
    lines: &[Line],
    predicted: &[Predicted],
    weights: &[f64],
    seconds: &BTreeMap<i64, usize>,
    p: &TriangulationParams,
    starts: &[Point2<f64>],
    (feet, gnss): (&[Point2<f64>], &[Vector2<f64>]),
) -> Bordered {
    let bore = 2 * starts.len();
    let mut a = Bordered::zeros(bore + 1, seconds.len());
    // A mount held as calibrated (sigma 0) pins the boresight at zero.
    a.tt[(bore, bore)] += 1.0 / p.boresight_sigma_rad.powi(2).max(1e-12);
    for (j, start) in starts.iter().enumerate() {
        let w = 1.0 / (START_SIGMA_M * START_SIGMA_M);
        for axis in 0..2 {
            a.tt[(2 * j + axis, 2 * j + axis)] += w;
            a.rhs_t[2 * j + axis] += w * start[axis];
        }
    }
    for ((l, at), w) in lines.iter().zip(predicted).zip(weights) {
        let sigma = line_sigma(at.range, p);
        let w = w * l.share / (sigma * sigma);
        let n = at.normal;
        // range * (measured - predicted bearing), linear in the unknowns:
        // n . (foot + gnss) + range * (heading + boresight)
        //   = n . (foot0 + gnss0) + miss.
        let u = Vector3::new(n.x, n.y, at.range);
        let (j, k) = (2 * l.tower, l.second);
        let rhs = n.dot(&(feet[l.tower].coords + gnss[k])) + at.miss(l, 0.0);
        // The border's row: the foot's two columns, then the boresight's.
        let border = [(j, n.x), (j + 1, n.y), (bore, at.range)];
        for (row, x) in border {
            for (col, y) in border {
                a.tt[(row, col)] += w * x * y;
            }
            a.rhs_t[row] += w * x * rhs;
            for c in 0..3 {
                a.tb[(row, 3 * k + c)] += w * x * u[c];
            }
        }
        a.diagonal[k] += w * u * u.transpose();
        a.rhs_b[k] += w * u * rhs;
    }
    let gnss_var = p.position_sigma_m.powi(2).max(1e-6);
    let heading_var = p.bearing_sigma_rad.powi(2).max(1e-12);
    let variance = Vector3::new(gnss_var, gnss_var, heading_var);
    let correlation = Vector3::new(
        p.position_correlation_s,
        p.position_correlation_s,
        p.bearing_correlation_s,
    );
    // A stationary first-order Gauss-Markov prior: the first second's
    // variance, then each step's, (x_k - keep x_{k-1})^2 / (var (1 - keep^2)).
    let times: Vec<f64> = seconds.keys().map(|b| bin_middle(*b)).collect();
    if !times.is_empty() {
        a.diagonal[0] += Matrix3::from_diagonal(&variance.map(|v| 1.0 / v));
    }
    for k in 1..times.len() {
        let gap = times[k] - times[k - 1];
        let keep = correlation.map(|c| if c > 0.0 { (-gap / c).exp() } else { 0.0 });
        let w = variance.zip_map(&keep, |v, c| 1.0 / (v * (1.0 - c * c)).max(1e-12));
        a.diagonal[k] += Matrix3::from_diagonal(&w);
        a.diagonal[k - 1] += Matrix3::from_diagonal(&w.component_mul(&keep.component_mul(&keep)));
        a.below[k] -= Matrix3::from_diagonal(&w.component_mul(&keep));
    }
    a
}

/// The GNSS error's change between consecutive seconds, where `drift`
/// measures it: `(x_k - x_{k-1} - change)^2 / (2 sigma^2 tau gap)`.
fn with_drift(
    mut a: Bordered,
    seconds: &BTreeMap<i64, usize>,
    drift: &GnssDrift,
    p: &TriangulationParams,
) -> Bordered {
    if p.velocity_sigma_mps <= 0.0 {
        return a;
    }
    let times: Vec<f64> = seconds.keys().map(|b| bin_middle(*b)).collect();
    for k in 1..times.len() {
        let gap = times[k] - times[k - 1];
        let Some(change) = drift.change(times[k - 1], times[k]) else {
            continue;
        };
        let w = 1.0 / (2.0 * p.velocity_sigma_mps.powi(2) * VELOCITY_CORRELATION_S * gap);
        for c in 0..2 {
            a.diagonal[k][(c, c)] += w;
            a.diagonal[k - 1][(c, c)] += w;
            a.below[k][(c, c)] -= w;
            a.rhs_b[k][c] += w * change[c];
            a.rhs_b[k - 1][c] -= w * change[c];
        }
    }
    a
}

#[cfg(test)]
#[path = "adjust_tests.rs"]
mod tests;
