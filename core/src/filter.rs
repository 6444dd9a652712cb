//! An EKF over position and velocity (constant-velocity model driven by white
//! acceleration) that fuses per-frame fixes, gates them by their innovation,
//! coasts through frames with no tower, and says when it has lost the pose.
//! Between steps the horizontal velocity turns with the IMU's yaw: the UAV
//! flies nose first, so a prediction through a turn with no tower in view
//! follows it round instead of flying on along the old track.
//!
//! It reports an estimate only while its horizontal 1-sigma is within
//! `max_report_sigma_m`, a fused fix as much as a coast: an estimate the
//! autopilot should not lean on is not sent. After an outage the filter
//! coasts; how long it reports follows from how well the velocity was known
//! (and any velocity fused meanwhile), not from a clock. Its prediction
//! still guides tower identity until `max_coast_s` (20 s) after the last
//! fix, when it is lost and the next good fix restarts it. A run of
//! `restart_after_rejections` rejected fixes also restarts it from the newest
//! fix: a filter that rejects everything has itself gone wrong. A restart needs
//! a fix from two or more towers, and after a loss one within reach of the
//! last estimate at `max_speed_mps`; or one tower, where the lost state
//! dead-reckoned to the fix (or a position another source gave) is tight
//! enough to tell that tower from its neighbours and the fix agrees with it.

use nalgebra::{Matrix3, Matrix4, Matrix6, Point3, SMatrix, Vector3, Vector6};

use towernav_geometry::frames::wrap_angle;

use crate::localizer::Fix;

/// Chi-square gate on a horizontal (2-D) innovation, 99.9 %.
const HORIZONTAL_GATE_CHI2: f64 = 13.82;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterParams {
    /// White acceleration noise, m/s^2 per axis horizontally and vertically.
    pub accel_sigma_h: f64,
    pub accel_sigma_v: f64,
    /// Chi-square gate on the 3-D innovation (99.9 %).
    pub gate_chi2: f64,
    pub max_coast_s: f64,
    /// Estimates are reported only while the horizontal position's 1-sigma
    /// (the major axis of its ellipse) is at most this, metres, whether a fix
    /// was fused or not: one uncertain fix (a single near tower whose box the
    /// frame cuts) is held back until more agree. The state and its
    /// prediction live on (for identity) until `max_coast_s`.
    pub max_report_sigma_m: f64,
    /// Chi-square gate on a 3-D velocity measurement's innovation (99.9 %).
    pub velocity_gate_chi2: f64,
    /// Velocity correlation time: with no fixes the predicted velocity decays
    /// toward zero with this time constant (infinite: it holds). A UAV
    /// flying a plan keeps its speed through a gap: with 8 s the prediction
    /// fell a tower span behind in 17 s, and the first box back was bound
    /// to the tower behind. Held outright, a velocity that fixes had got
    /// wrong is carried on undamped; 20 s came near it on the long gap
    /// (3.4 against 3.0 m) and did better on the demo's flights (README).
    pub velocity_tau_s: f64,
    pub restart_after_rejections: u32,
    /// Velocity spread at start, m/s.
    pub initial_velocity_sigma: f64,
    /// Fix covariances are scaled by this before fusion: consecutive fixes
    /// share slowly varying errors (the IMU heading, box biases of the same
    /// towers), which a filter assuming independent fixes would average away.
    pub fix_covariance_scale: f64,
    /// The share of a fix's covariance that no averaging removes (errors
    /// that persist from frame to frame: the AHRS's slowly wandering roll
    /// and pitch, a box's systematic offset on one tower, the survey's
    /// error): added to what is reported, so the filter never claims to
    /// know the position much better than one fix does.
    pub persistent_share: f64,
    /// A (re)start needs a fix from at least this many towers: one tower's
    /// fix cannot reveal its own wrong identity or false box. One tower may
    /// restart the filter only against a dead-reckoned prior (see
    /// `one_tower_prior_sigma_m`).
    pub min_restart_towers: usize,
    /// After a loss, a fix from fewer than `min_restart_towers` towers
    /// restarts the filter when the lost state, carried on to the fix's time
    /// at its velocity, is still within this horizontal 1-sigma, metres, and
    /// the fix's horizontal position passes the chi-square gate (99.9 %, two
    /// degrees of freedom) against it: the prior then says which tower
    /// it is and where, and a wrong tower (a span, 150 m or more, away) or a
    /// false box fails the gate. 0 turns one-tower restarts off.
    pub one_tower_prior_sigma_m: f64,
    /// After losing the pose, a restart fix must lie within this speed times
    /// the time since the last estimate (plus `restart_slack_m`) of it.
    pub max_speed_mps: f64,
    pub restart_slack_m: f64,
    /// The published position covariance is the filter's times this. The
    /// filter weighs and gates with a deliberately wide noise model (a
    /// detector's box errors are heavy-tailed); what the autopilot gets is
    /// scaled to the errors a benchmark measured for the detector, so that
    /// its 2-sigma ellipse holds about 95 % of them. The report bound
    /// applies to the filter's own covariance, before the scale.
    pub report_covariance_scale: f64,
    /// The horizontal velocity turns with the IMU's yaw between steps: a
    /// UAV that looks where it flies keeps flying nose first through a turn
    /// with no tower in view, and the prediction should follow it round
    /// rather than fly on along the old track. Off for a platform that
    /// crabs or strafes.
    pub velocity_follows_heading: bool,
}

impl Default for FilterParams {
    fn default() -> Self {
        Self {
            accel_sigma_h: 1.5,
            accel_sigma_v: 0.5,
            gate_chi2: 16.27,
            max_coast_s: 20.0,
            max_report_sigma_m: 5.0,
            velocity_gate_chi2: 16.27,
            velocity_tau_s: 20.0,
            restart_after_rejections: 15,
            initial_velocity_sigma: 15.0,
            fix_covariance_scale: 3.0,
            persistent_share: 0.5,
            min_restart_towers: 2,
            one_tower_prior_sigma_m: 25.0,
            max_speed_mps: 20.0,
            restart_slack_m: 30.0,
            report_covariance_scale: 1.0,
            velocity_follows_heading: true,
        }
    }
}

/// What the filter says about one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    pub position_in_world: Point3<f64>,
    pub velocity_in_world: Vector3<f64>,
    pub yaw: f64,
    /// (east, north, up, yaw).
    pub covariance: Matrix4<f64>,
    /// Of the velocity (east, north, up): how fast a prediction's error grows.
    pub velocity_covariance: Matrix3<f64>,
    /// The fix of this frame was fused (false: predicted only, or the fix was gated).
    pub updated: bool,
    /// Seconds since the last accepted fix.
    pub coast_s: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixVerdict {
    Accepted,
    Rejected,
    /// The filter (re)started from this fix.
    Restarted,
    NoFix,
}

#[derive(Debug, Clone)]
pub struct PoseFilter {
    params: FilterParams,
    state: Option<State>,
    rejections: u32,
    /// What a restart is judged against while the filter is not running.
    prior: Option<Prior>,
}

/// The state a restart is judged against.
#[derive(Debug, Clone)]
enum Prior {
    /// The state as the pose was lost: a restart must lie within reach of
    /// it, and one tower must agree with it dead-reckoned.
    Lost(State),
    /// A position another source gave: one tower must agree with it.
    Given(State),
}

impl Prior {
    fn state(&self) -> &State {
        match self {
            Prior::Lost(s) | Prior::Given(s) => s,
        }
    }
}

#[derive(Debug, Clone)]
struct State {
    time_s: f64,
    x: Vector6<f64>,
    p: Matrix6<f64>,
    last_update_s: f64,
    /// The last accepted fix's position covariance.
    fix_covariance: Matrix3<f64>,
    /// The IMU's yaw at `time_s`, when a step gave one.
    yaw: Option<f64>,
}

impl PoseFilter {
    pub fn new(params: FilterParams) -> Self {
        Self {
            params,
            state: None,
            rejections: 0,
            prior: None,
        }
    }

    /// A position another source gives (the autopilot's GNSS before it is
    /// lost) with its 1-sigma at `time_s`: while the filter is not running,
    /// one tower may start it against this prior as after a loss. Its
    /// velocity is unknown (`initial_velocity_sigma`), so the prior widens
    /// past use within a second or two of the source falling silent.
    pub fn set_prior(&mut self, time_s: f64, position_in_world: Point3<f64>, sigma_m: f64) {
        if self.state.is_some() || !sigma_m.is_finite() || sigma_m <= 0.0 {
            return;
        }
        let mut x = Vector6::zeros();
        x.fixed_rows_mut::<3>(0)
            .copy_from(&position_in_world.coords);
        let mut p = Matrix6::zeros();
        for i in 0..3 {
            p[(i, i)] = sigma_m * sigma_m;
            p[(i + 3, i + 3)] = self.params.initial_velocity_sigma.powi(2);
        }
        self.prior = Some(Prior::Given(State {
            time_s,
            x,
            p,
            last_update_s: time_s,
            fix_covariance: Matrix3::zeros(),
            yaw: None,
        }));
    }

    /// Whether `fix` may (re)start the filter at `time_s`.
    fn may_start_from(&self, time_s: f64, fix: &Fix, imu_yaw: f64) -> bool {
        if fix.towers_used.len() < self.params.min_restart_towers {
            return !fix.towers_used.is_empty() && self.prior_agrees(time_s, fix, imu_yaw);
        }
        match &self.prior {
            Some(Prior::Lost(s)) => {
                // The last estimate: the state's position, as of its last fix.
                let last = Point3::from(s.x.fixed_rows::<3>(0).into_owned());
                let reach = self.params.max_speed_mps * (time_s - s.last_update_s).abs()
                    + self.params.restart_slack_m;
                (fix.position_in_world - last).norm() <= reach
            }
            _ => true,
        }
    }

    /// Whether the dead-reckoned prior is tight enough to name the fix's
    /// tower and the fix passes the gate against it.
    fn prior_agrees(&self, time_s: f64, fix: &Fix, imu_yaw: f64) -> bool {
        let Some(prior) = self.prior.as_ref().map(Prior::state) else {
            return false;
        };
        if time_s < prior.time_s {
            return false;
        }
        let mut s = prior.clone();
        s.predict(&self.params, time_s, Some(imu_yaw));
        let p = s.p.fixed_view::<2, 2>(0, 0).into_owned();
        if horizontal_sigma(&p) > self.params.one_tower_prior_sigma_m {
            return false;
        }
        let r = fix.covariance.fixed_view::<2, 2>(0, 0).into_owned()
            * self.params.fix_covariance_scale.max(1e-6);
        let d = fix.position_in_world.coords.xy() - s.x.fixed_rows::<2>(0);
        (p + r)
            .try_inverse()
            .is_some_and(|ci| (d.transpose() * ci * d)[(0, 0)] <= HORIZONTAL_GATE_CHI2)
    }

    /// Where the filter expects the UAV at `time_s` (no state change).
    pub fn predicted_position(&self, time_s: f64) -> Option<Point3<f64>> {
        let s = self.state.as_ref()?;
        let dt = (time_s - s.time_s).max(0.0);
        if time_s - s.last_update_s > self.params.max_coast_s {
            return None;
        }
        let (reach, _) = velocity_decay(dt, self.params.velocity_tau_s);
        Some(Point3::from(
            s.x.fixed_rows::<3>(0) + s.x.fixed_rows::<3>(3) * reach,
        ))
    }

    /// The state's position as of its last step, reported or not.
    pub fn position(&self) -> Option<Point3<f64>> {
        let s = self.state.as_ref()?;
        Some(Point3::from(s.x.fixed_rows::<3>(0).into_owned()))
    }

    /// Whether a fix was accepted within the last `within_s` seconds: the
    /// prediction is good enough to judge tower identities by.
    pub fn tracking(&self, time_s: f64, within_s: f64) -> bool {
        self.state
            .as_ref()
            .is_some_and(|s| time_s - s.last_update_s <= within_s)
    }

    /// Advance to `time_s`, fuse `fix` if it passes the gate, and report.
    /// `yaw` and `yaw_variance` come from the fix when there is one, else the IMU.
    pub fn step(
        &mut self,
        time_s: f64,
        fix: Option<&Fix>,
        imu_yaw: f64,
        imu_yaw_variance: f64,
    ) -> (Option<Estimate>, FixVerdict) {
        if let Some(s) = &self.state
            && (time_s - s.last_update_s > self.params.max_coast_s || time_s < s.time_s)
        {
            // Lost, or time ran backwards (a new flight): start over.
            let backwards = time_s < s.time_s;
            self.prior = self.state.take().filter(|_| !backwards).map(Prior::Lost);
        }
        let verdict = match (fix, self.state.is_some()) {
            (None, _) => {
                self.predict(time_s, Some(imu_yaw));
                FixVerdict::NoFix
            }
            (Some(f), false) => {
                if self.may_start_from(time_s, f, imu_yaw) {
                    self.start(time_s, f, imu_yaw);
                    FixVerdict::Restarted
                } else {
                    FixVerdict::Rejected
                }
            }
            (Some(f), true) => {
                self.predict(time_s, Some(imu_yaw));
                if self.update(f) {
                    self.rejections = 0;
                    FixVerdict::Accepted
                } else {
                    self.rejections += 1;
                    if self.rejections >= self.params.restart_after_rejections
                        && f.towers_used.len() >= self.params.min_restart_towers
                    {
                        self.start(time_s, f, imu_yaw);
                        FixVerdict::Restarted
                    } else {
                        FixVerdict::Rejected
                    }
                }
            }
        };
        let Some(s) = &self.state else {
            return (None, verdict);
        };
        let mut covariance = Matrix4::zeros();
        covariance.fixed_view_mut::<3, 3>(0, 0).copy_from(
            &(s.p.fixed_view::<3, 3>(0, 0) + s.fix_covariance * self.params.persistent_share),
        );
        // The bound ends a coast and holds back an uncertain fix alike.
        if horizontal_sigma(&covariance.fixed_view::<2, 2>(0, 0).into_owned())
            > self.params.max_report_sigma_m
        {
            return (None, verdict);
        }
        let (yaw, yaw_var) = match fix {
            Some(f) if verdict != FixVerdict::Rejected => (f.yaw, f.covariance[(3, 3)]),
            _ => (imu_yaw, imu_yaw_variance),
        };
        let scale = self.params.report_covariance_scale;
        if scale.is_finite() && scale > 0.0 {
            covariance.fixed_view_mut::<3, 3>(0, 0).scale_mut(scale);
        }
        covariance[(3, 3)] = yaw_var;
        let estimate = Estimate {
            position_in_world: Point3::from(s.x.fixed_rows::<3>(0).into_owned()),
            velocity_in_world: s.x.fixed_rows::<3>(3).into_owned(),
            yaw,
            covariance,
            velocity_covariance: s.p.fixed_view::<3, 3>(3, 3).into_owned(),
            updated: matches!(verdict, FixVerdict::Accepted | FixVerdict::Restarted),
            coast_s: time_s - s.last_update_s,
        };
        (Some(estimate), verdict)
    }

    fn start(&mut self, time_s: f64, fix: &Fix, imu_yaw: f64) {
        self.prior = None;
        let mut x = Vector6::zeros();
        x.fixed_rows_mut::<3>(0)
            .copy_from(&fix.position_in_world.coords);
        let mut p = Matrix6::zeros();
        p.fixed_view_mut::<3, 3>(0, 0).copy_from(
            &(fix.covariance.fixed_view::<3, 3>(0, 0) * self.params.fix_covariance_scale.max(1e-6)),
        );
        let v2 = self.params.initial_velocity_sigma.powi(2);
        for i in 3..6 {
            p[(i, i)] = v2;
        }
        self.state = Some(State {
            time_s,
            x,
            p,
            last_update_s: time_s,
            fix_covariance: fix.covariance.fixed_view::<3, 3>(0, 0).into_owned(),
            yaw: imu_yaw.is_finite().then_some(imu_yaw),
        });
        self.rejections = 0;
    }

    /// Advances the state to `time_s`; `yaw` is the IMU's then, if known.
    fn predict(&mut self, time_s: f64, yaw: Option<f64>) {
        let params = self.params;
        if let Some(s) = &mut self.state {
            s.predict(&params, time_s, yaw);
        }
    }

    /// Fuses a velocity measured by another source (visual-inertial
    /// odometry, optical flow), east-north-up in m/s, at `time_s`: it slows
    /// how fast the position's uncertainty grows while no tower is in view.
    /// `false` when there is no state to fuse into, the measurement is from
    /// before the state, or its innovation fails the gate.
    pub fn update_velocity(
        &mut self,
        time_s: f64,
        velocity_in_world: &Vector3<f64>,
        covariance: &Matrix3<f64>,
    ) -> bool {
        let gate = self.params.velocity_gate_chi2;
        if self
            .state
            .as_ref()
            .is_none_or(|s| time_s < s.time_s || time_s - s.last_update_s > self.params.max_coast_s)
        {
            return false;
        }
        self.predict(time_s, None);
        let Some(s) = &mut self.state else {
            return false;
        };
        s.fuse_block(3, velocity_in_world, covariance, gate)
    }

    /// Fuse a fix's position; `false` if its innovation fails the gate.
    fn update(&mut self, fix: &Fix) -> bool {
        let gate = self.params.gate_chi2;
        let scale = self.params.fix_covariance_scale.max(1e-6);
        let Some(s) = &mut self.state else {
            return false;
        };
        let r: Matrix3<f64> = fix.covariance.fixed_view::<3, 3>(0, 0).into_owned() * scale;
        if !s.fuse_block(0, &fix.position_in_world.coords, &r, gate) {
            return false;
        }
        s.last_update_s = s.time_s;
        s.fix_covariance = fix.covariance.fixed_view::<3, 3>(0, 0).into_owned();
        true
    }
}

impl State {
    /// Advances to `time_s`: the constant-velocity model, the velocity
    /// turned with the IMU's yaw (`yaw`, if known) and decaying.
    fn predict(&mut self, params: &FilterParams, time_s: f64, yaw: Option<f64>) {
        let yaw = yaw.filter(|y| y.is_finite());
        // The turn since the last step, applied to the velocity at its start.
        let turn = match (self.yaw, yaw) {
            (Some(before), Some(now)) if params.velocity_follows_heading => {
                Some(wrap_angle(now - before))
            }
            _ => None,
        };
        if yaw.is_some() {
            self.yaw = yaw;
        }
        let dt = (time_s - self.time_s).max(0.0);
        if dt == 0.0 && turn.is_none() {
            return;
        }
        let (reach, keep) = velocity_decay(dt, params.velocity_tau_s);
        let mut turn_v = Matrix3::identity();
        if let Some(a) = turn {
            let (sin, cos) = a.sin_cos();
            turn_v[(0, 0)] = cos;
            turn_v[(0, 1)] = -sin;
            turn_v[(1, 0)] = sin;
            turn_v[(1, 1)] = cos;
        }
        let mut f = Matrix6::identity();
        f.fixed_view_mut::<3, 3>(0, 3).copy_from(&(turn_v * reach));
        f.fixed_view_mut::<3, 3>(3, 3).copy_from(&(turn_v * keep));
        let mut q = Matrix6::zeros();
        for i in 0..3 {
            let a2 = if i < 2 {
                params.accel_sigma_h.powi(2)
            } else {
                params.accel_sigma_v.powi(2)
            };
            q[(i, i)] = a2 * dt.powi(3) / 3.0;
            q[(i, i + 3)] = a2 * dt.powi(2) / 2.0;
            q[(i + 3, i)] = a2 * dt.powi(2) / 2.0;
            q[(i + 3, i + 3)] = a2 * dt;
        }
        self.x = f * self.x;
        self.p = f * self.p * f.transpose() + q;
        self.time_s = time_s;
    }

    /// Fuses a direct measurement `z` (covariance `r`) of the three states
    /// from `first` (0: position, 3: velocity); `false`, unchanged, if its
    /// innovation fails the chi-square `gate`.
    fn fuse_block(&mut self, first: usize, z: &Vector3<f64>, r: &Matrix3<f64>, gate: f64) -> bool {
        let mut h = SMatrix::<f64, 3, 6>::zeros();
        for i in 0..3 {
            h[(i, first + i)] = 1.0;
        }
        let innovation = z - h * self.x;
        let Some(cov_inv) = (h * self.p * h.transpose() + r).try_inverse() else {
            return false;
        };
        let nis = (innovation.transpose() * cov_inv * innovation)[(0, 0)];
        if !nis.is_finite() || nis > gate {
            return false;
        }
        let gain = self.p * h.transpose() * cov_inv;
        self.x += gain * innovation;
        // Joseph form keeps P symmetric and positive.
        let i_kh = Matrix6::identity() - gain * h;
        self.p = i_kh * self.p * i_kh.transpose() + gain * r * gain.transpose();
        true
    }
}

/// A horizontal covariance's 1-sigma along its ellipse's major axis.
pub fn horizontal_sigma(p: &nalgebra::Matrix2<f64>) -> f64 {
    let (a, b, c) = (p[(0, 0)], p[(1, 1)], p[(0, 1)]);
    let major = 0.5 * (a + b) + (0.25 * (a - b).powi(2) + c * c).sqrt();
    major.max(0.0).sqrt()
}

/// Over `dt` with velocity correlation time `tau`: how far a unit velocity
/// carries the position, and how much of the velocity remains.
fn velocity_decay(dt: f64, tau: f64) -> (f64, f64) {
    if tau <= 0.0 || !tau.is_finite() {
        return (dt, 1.0);
    }
    let keep = (-dt / tau).exp();
    (tau * (1.0 - keep), keep)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix_at(x: f64, y: f64, sigma: f64) -> Fix {
        let mut covariance = Matrix4::identity() * sigma * sigma;
        covariance[(3, 3)] = 1e-4;
        Fix {
            position_in_world: Point3::new(x, y, 30.0),
            yaw: 0.0,
            covariance,
            towers_used: vec!["A1".into(), "B1".into()],
        }
    }

    #[test]
    fn coasts_through_gaps_and_reports_growing_uncertainty() {
        let mut f = PoseFilter::new(FilterParams::default());
        for i in 0..60 {
            let t = f64::from(i) / 30.0;
            f.step(t, Some(&fix_at(10.0 * t, 0.0, 1.0)), 0.0, 1e-4);
        }
        let (before, _) = f.step(2.0, Some(&fix_at(20.0, 0.0, 1.0)), 0.0, 1e-4);
        let before = before.expect("tracking");
        let (gap, verdict) = f.step(3.0, None, 0.0, 1e-4);
        let (silent, _) = f.step(8.5, None, 0.0, 1e-4);
        assert!(
            silent.is_none(),
            "nothing reported 6.5 s after the last fix"
        );
        assert!(
            f.predicted_position(8.5).is_some(),
            "the prediction still guides identity"
        );
        let gap = gap.expect("coasting");
        assert_eq!(verdict, FixVerdict::NoFix);
        // Carried on at 10 m/s, slowing a little (20 s correlation time).
        assert!(
            (gap.position_in_world.x - 29.75).abs() < 1.0,
            "{}",
            gap.position_in_world
        );
        assert!(gap.covariance[(0, 0)] > before.covariance[(0, 0)]);
        assert!(!gap.updated && (gap.coast_s - 1.0).abs() < 1e-9);
    }

    /// Tracks a UAV flying east at 10 m/s for 2 s, then coasts.
    fn tracked() -> PoseFilter {
        tracked_with(FilterParams::default())
    }

    fn tracked_with(params: FilterParams) -> PoseFilter {
        let mut f = PoseFilter::new(params);
        for i in 0..=60 {
            let t = f64::from(i) / 30.0;
            f.step(t, Some(&fix_at(10.0 * t, 0.0, 1.0)), 0.0, 1e-4);
        }
        f
    }

    #[test]
    fn the_prediction_turns_with_the_heading_through_a_gap() {
        // East at 10 m/s, then no fix while the UAV turns left by 90 degrees
        // over 3 s, nose first, and flies on north.
        let predicted_after_turn = |follows: bool| {
            let mut f = tracked_with(FilterParams {
                velocity_follows_heading: follows,
                ..FilterParams::default()
            });
            for i in 1..=180 {
                let t = 2.0 + f64::from(i) / 30.0;
                let yaw = (f64::from(i) / 90.0).min(1.0) * std::f64::consts::FRAC_PI_2;
                f.step(t, None, yaw, 1e-4);
            }
            let s = f.state.as_ref().expect("still coasting");
            (f.predicted_position(8.0).expect("coasting"), s.x[3], s.x[4])
        };
        let (turned, ve, vn) = predicted_after_turn(true);
        assert!(
            ve.abs() < 0.05 * vn && vn > 0.0,
            "velocity {ve} east, {vn} north"
        );
        let (straight, ..) = predicted_after_turn(false);
        // The nose-first path: a quarter circle of radius 30/pi m from
        // (20, 0), then north for 3 s at 10 m/s.
        let radius = 30.0 / std::f64::consts::PI;
        let truth = Point3::new(20.0 + radius, radius + 30.0, 30.0);
        let miss = |p: Point3<f64>| (p.xy() - truth.xy()).norm();
        assert!(
            miss(turned) < 0.5 * miss(straight),
            "turned {turned} vs straight {straight}, truth {truth}"
        );
    }

    /// Seconds of coast (from 2 s) until the filter stops reporting, and the
    /// largest horizontal 1-sigma it reported meanwhile.
    fn coast(f: &mut PoseFilter, velocity: Option<(f64, f64)>) -> (f64, f64) {
        let mut largest: f64 = 0.0;
        for i in 1..=600 {
            let t = 2.0 + f64::from(i) / 30.0;
            if let Some((v, sigma)) = velocity {
                let c = Matrix3::identity() * sigma * sigma;
                f.update_velocity(t, &Vector3::new(v, 0.0, 0.0), &c);
            }
            match f.step(t, None, 0.0, 1e-4).0 {
                Some(e) => {
                    largest = largest.max(e.covariance[(0, 0)].max(e.covariance[(1, 1)]).sqrt())
                }
                None => return (t - 2.0, largest),
            }
        }
        (20.0, largest)
    }

    #[test]
    fn the_coast_ends_when_the_covariance_says_so_and_a_fused_velocity_prolongs_it() {
        let sigma_max = FilterParams::default().max_report_sigma_m;
        let (alone, largest) = coast(&mut tracked(), None);
        assert!(largest <= sigma_max + 1e-9, "{largest}");
        assert!((1.0..10.0).contains(&alone), "coasted {alone} s");
        let (with_velocity, largest) = coast(&mut tracked(), Some((10.0, 0.2)));
        assert!(largest <= sigma_max + 1e-9, "{largest}");
        assert!(
            with_velocity > 2.0 * alone,
            "{with_velocity} s with a velocity against {alone} s without"
        );
        // The fused velocity carries the prediction at 10 m/s for 5 s.
        let mut g = tracked();
        for i in 1..=150 {
            let t = 2.0 + f64::from(i) / 30.0;
            g.update_velocity(
                t,
                &Vector3::new(10.0, 0.0, 0.0),
                &(Matrix3::identity() * 0.04),
            );
        }
        let p = g.predicted_position(7.0).expect("tracking");
        assert!((p.x - 70.0).abs() < 3.0, "{p}");
    }

    #[test]
    fn an_uncertain_fix_is_fused_but_not_reported_until_the_estimate_is_good() {
        let mut f = tracked();
        f.step(20.0, None, 0.0, 1e-4);
        // After a long coast, one uncertain fix (8 m) is fused but held back;
        // good fixes then bring the estimate under the bound and it is told.
        let (held, verdict) = f.step(20.1, Some(&fix_at(190.0, 0.0, 8.0)), 0.0, 1e-4);
        assert_eq!(verdict, FixVerdict::Accepted);
        assert!(held.is_none(), "{held:?}");
        assert!(f.tracking(20.1, 0.5), "the fix moved the state");
        let mut told = None;
        for i in 1..=10 {
            let t = 20.1 + f64::from(i) / 30.0;
            told = f.step(t, Some(&fix_at(190.0, 0.0, 1.0)), 0.0, 1e-4).0;
        }
        let told = told.expect("reported once the fixes agree");
        let sigma = horizontal_sigma(&told.covariance.fixed_view::<2, 2>(0, 0).into_owned());
        assert!(
            sigma <= FilterParams::default().max_report_sigma_m,
            "{sigma}"
        );
    }

    #[test]
    fn the_published_covariance_is_scaled_but_the_report_bound_is_the_filters() {
        let run = |scale: f64| {
            let mut f = PoseFilter::new(FilterParams {
                report_covariance_scale: scale,
                ..FilterParams::default()
            });
            let mut out = Vec::new();
            for i in 0..60 {
                let t = f64::from(i) / 30.0;
                // Fixes of 4 m: the filter's own 1-sigma stays above the 5 m
                // bound for the first frames, whatever the scale.
                let (e, _) = f.step(t, Some(&fix_at(10.0 * t, 0.0, 4.0)), 0.0, 1e-4);
                out.push(e.map(|e| (e.position_in_world, e.covariance)));
            }
            out
        };
        let (whole, quarter) = (run(1.0), run(0.25));
        assert!(
            whole[0].is_none() && quarter[0].is_none(),
            "held back alike"
        );
        let mut told = 0;
        for (a, b) in whole.iter().zip(&quarter) {
            assert_eq!(a.is_some(), b.is_some(), "the same frames are told");
            if let (Some((pa, ca)), Some((pb, cb))) = (a, b) {
                told += 1;
                assert_eq!(pa, pb, "the estimate itself is the same");
                for i in 0..3 {
                    assert!((cb[(i, i)] - 0.25 * ca[(i, i)]).abs() < 1e-9);
                }
                assert_eq!(ca[(3, 3)], cb[(3, 3)], "yaw is not scaled");
            }
        }
        assert!(told > 30, "{told} told");
    }

    #[test]
    fn a_velocity_is_gated_and_needs_a_state() {
        let mut f = PoseFilter::new(FilterParams::default());
        let c = Matrix3::identity() * 0.01;
        assert!(
            !f.update_velocity(0.0, &Vector3::new(1.0, 0.0, 0.0), &c),
            "no state yet"
        );
        let mut f = tracked();
        assert!(
            !f.update_velocity(2.1, &Vector3::new(60.0, 0.0, 0.0), &c),
            "60 m/s against 10"
        );
        assert!(
            !f.update_velocity(1.0, &Vector3::new(10.0, 0.0, 0.0), &c),
            "from before the state"
        );
        assert!(f.update_velocity(2.1, &Vector3::new(10.5, 0.0, 0.0), &c));
    }

    #[test]
    fn an_inconsistent_fix_is_gated_and_a_long_outage_loses_the_pose() {
        let mut f = PoseFilter::new(FilterParams::default());
        for i in 0..30 {
            f.step(f64::from(i) / 30.0, Some(&fix_at(0.0, 0.0, 1.0)), 0.0, 1e-4);
        }
        let (_, verdict) = f.step(1.0, Some(&fix_at(80.0, 0.0, 1.0)), 0.0, 1e-4);
        assert_eq!(verdict, FixVerdict::Rejected);
        let (lost, _) = f.step(25.0, None, 0.0, 1e-4);
        assert!(lost.is_none(), "no estimate after 24 s without a fix");
        assert!(f.predicted_position(25.0).is_none(), "lost");
        let (back, verdict) = f.step(25.1, Some(&fix_at(80.0, 0.0, 1.0)), 0.0, 1e-4);
        assert_eq!(verdict, FixVerdict::Restarted);
        assert_eq!(back.expect("restarted").position_in_world.x, 80.0);
        // Lost again: a fix farther than the UAV could have flown does not restart it.
        f.step(50.0, None, 0.0, 1e-4);
        let (none, verdict) = f.step(50.5, Some(&fix_at(2000.0, 0.0, 1.0)), 0.0, 1e-4);
        assert!(none.is_none() && verdict == FixVerdict::Rejected);
        let mut single = fix_at(90.0, 0.0, 1.0);
        single.towers_used.truncate(1);
        let (none, verdict) = f.step(50.6, Some(&single), 0.0, 1e-4);
        assert!(
            none.is_none() && verdict == FixVerdict::Rejected,
            "one tower cannot restart once the prior has grown past naming it"
        );
    }

    fn one_tower(x: f64, y: f64) -> Fix {
        let mut fix = fix_at(x, y, 1.0);
        fix.towers_used.truncate(1);
        fix
    }

    #[test]
    fn one_tower_restarts_only_where_a_tight_prior_expects_it() {
        let params = FilterParams::default();
        // Hovering at the origin, a flow sensor holding the velocity at
        // zero through the gap, so the dead-reckoned prior stays tight.
        let mut f = PoseFilter::new(params);
        let still = Matrix3::identity() * 0.05;
        for i in 0..=60 {
            f.step(f64::from(i) / 30.0, Some(&fix_at(0.0, 0.0, 1.0)), 0.0, 1e-4);
        }
        let mut t = 2.0;
        while t < 24.0 {
            t += 0.1;
            f.update_velocity(t, &Vector3::zeros(), &still);
            f.step(t, None, 0.0, 1e-4);
        }
        assert!(f.predicted_position(t).is_none(), "lost after 20 s");
        // A tower 150 m off (the next one along the line) is not it.
        let mut wrong = f.clone();
        assert_eq!(
            wrong.step(24.2, Some(&one_tower(150.0, 0.0)), 0.0, 1e-4).1,
            FixVerdict::Rejected
        );
        let (back, verdict) = f.step(24.2, Some(&one_tower(3.0, -2.0)), 0.0, 1e-4);
        assert_eq!(verdict, FixVerdict::Restarted);
        assert_eq!(back.map(|e| e.updated), Some(true));

        // Without the velocity the prior has grown too wide to name a tower.
        let mut f = PoseFilter::new(params);
        for i in 0..=60 {
            f.step(f64::from(i) / 30.0, Some(&fix_at(0.0, 0.0, 1.0)), 0.0, 1e-4);
        }
        f.step(23.0, None, 0.0, 1e-4);
        assert_eq!(
            f.step(24.2, Some(&one_tower(3.0, -2.0)), 0.0, 1e-4).1,
            FixVerdict::Rejected
        );
        // Off, it never restarts from one tower.
        let mut f = PoseFilter::new(FilterParams {
            one_tower_prior_sigma_m: 0.0,
            ..params
        });
        f.set_prior(0.0, Point3::new(0.0, 0.0, 30.0), 5.0);
        assert_eq!(
            f.step(1.0, Some(&one_tower(1.0, 0.0)), 0.0, 1e-4).1,
            FixVerdict::Rejected
        );
    }

    #[test]
    fn a_given_prior_lets_one_tower_start_the_filter() {
        let mut f = PoseFilter::new(FilterParams::default());
        assert_eq!(
            f.step(0.5, Some(&one_tower(1.0, 0.0)), 0.0, 1e-4).1,
            FixVerdict::Rejected,
            "no prior: one tower cannot start it"
        );
        f.set_prior(0.6, Point3::new(0.0, 0.0, 30.0), 10.0);
        assert_eq!(
            f.step(1.0, Some(&one_tower(80.0, 0.0)), 0.0, 1e-4).1,
            FixVerdict::Rejected,
            "80 m from where the prior puts it"
        );
        assert_eq!(
            f.step(1.1, Some(&one_tower(4.0, 3.0)), 0.0, 1e-4).1,
            FixVerdict::Restarted
        );
        assert!(f.tracking(1.1, 0.1));
    }

    #[test]
    fn persistent_disagreement_restarts_from_the_fixes() {
        let params = FilterParams::default();
        let mut f = PoseFilter::new(params);
        f.step(0.0, Some(&fix_at(0.0, 0.0, 0.5)), 0.0, 1e-4);
        let mut verdicts = Vec::new();
        for i in 1..=params.restart_after_rejections {
            let (_, v) = f.step(
                f64::from(i) / 30.0,
                Some(&fix_at(100.0, 0.0, 0.5)),
                0.0,
                1e-4,
            );
            verdicts.push(v);
        }
        assert_eq!(verdicts.last(), Some(&FixVerdict::Restarted));
        assert!(
            verdicts[..verdicts.len() - 1]
                .iter()
                .all(|v| *v == FixVerdict::Rejected)
        );
    }
}
