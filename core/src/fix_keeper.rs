//! What every autopilot output is told of the fix, whatever its wire: the
//! latest estimate carried forward to the moment a message goes out, and the
//! one rule on how good it still is (a fresh tower fix, a usable coast, or
//! none). MAVLink (`autopilot_link`) and ROS 2 / PX4 over Zenoh (`ros_link`)
//! both ask it, so they never disagree.

use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Point3, Vector3};
use towernav_geometry::{Attitude, Datum, Geodetic};
use towernav_protocol::{EdgeState, PoseEstimate};

use crate::filter::horizontal_sigma;

/// One frame's estimate, as the outputs need it.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkEstimate {
    pub pose: PoseEstimate,
    pub attitude: Attitude,
    pub velocity_in_world: Vector3<f64>,
    pub velocity_covariance: Matrix3<f64>,
}

/// How long a fix stays good.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixRules {
    /// The fix is fresh (a 3-D fix) only this long after a tower fix.
    pub fresh_fix: Duration,
    /// Coasting, the fix is usable at most this long after the last tower
    /// fix; then none.
    pub coast_fix: Duration,
    /// Coasting, the fix is usable only while the predicted horizontal
    /// 1-sigma (its ellipse's major axis) is within this, metres.
    pub coast_max_sigma_m: f64,
    /// The filter's white acceleration, m/s^2: how a prediction's error grows
    /// beyond its velocity's.
    pub accel_sigma: f64,
}

/// How good the fix is at a given moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixKind {
    /// Within `fresh_fix` of a tower fix.
    Fresh,
    /// Predicted since the last tower fix, still within the coasting limits.
    Coasting,
    /// None, or worth nothing.
    None,
}

pub struct FixKeeper {
    rules: FixRules,
    datum: Datum,
    latest: Option<(Instant, LinkEstimate)>,
    last_tower_fix: Option<Instant>,
    state: EdgeState,
}

impl FixKeeper {
    pub fn new(rules: FixRules, datum: Datum) -> Self {
        Self {
            rules,
            datum,
            latest: None,
            last_tower_fix: None,
            state: EdgeState::Initializing,
        }
    }

    /// A frame's outcome: its estimate (none when the filter reports none) and
    /// the edge's state. A pose with towers used is a fresh tower fix.
    pub fn handle_estimate(
        &mut self,
        now: Instant,
        estimate: Option<LinkEstimate>,
        state: EdgeState,
    ) {
        self.state = state;
        if let Some(e) = estimate {
            if !e.pose.towers_used.is_empty() {
                self.last_tower_fix = Some(now);
            }
            self.latest = Some((now, e));
        } else if state == EdgeState::NoFix {
            // Lost: nothing to predict from any more.
            self.latest = None;
        }
    }

    pub fn state(&self) -> EdgeState {
        self.state
    }

    /// The latest estimate as it came, if any is held.
    pub fn latest(&self) -> Option<&LinkEstimate> {
        self.latest.as_ref().map(|(_, e)| e)
    }

    /// How good the fix is at `now`.
    pub fn fix(&self, now: Instant) -> FixKind {
        let since_fix = self
            .last_tower_fix
            .map(|at| now.saturating_duration_since(at));
        let estimating = self.latest.is_some()
            && matches!(self.state, EdgeState::Localized | EdgeState::Coasting);
        let worth_little = || {
            self.predicted(now).is_none_or(|p| {
                let c = &p.covariance;
                let en = nalgebra::Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]);
                horizontal_sigma(&en) > self.rules.coast_max_sigma_m
            })
        };
        match since_fix {
            Some(age) if estimating && age <= self.rules.fresh_fix => FixKind::Fresh,
            Some(age) if estimating && age <= self.rules.coast_fix && !worth_little() => {
                FixKind::Coasting
            }
            _ => FixKind::None,
        }
    }

    /// The latest estimate carried to `now` at its velocity, its covariance
    /// grown by the velocity's and the filter's acceleration noise.
    pub fn predicted(&self, now: Instant) -> Option<PoseEstimate> {
        let (at, e) = self.latest.as_ref()?;
        let dt = now.saturating_duration_since(*at).as_secs_f64();
        let mut pose = e.pose.clone();
        let p = Point3::new(pose.east_m, pose.north_m, pose.up_m) + e.velocity_in_world * dt;
        let Geodetic {
            lat_deg,
            lon_deg,
            height_m,
        } = self.datum.to_geodetic(&p);
        (pose.east_m, pose.north_m, pose.up_m) = (p.x, p.y, p.z);
        (pose.lat_deg, pose.lon_deg, pose.alt_m) = (lat_deg, lon_deg, height_m);
        pose.time_s += dt;
        pose.coast_s += dt;
        // Position error after dt: the velocity's error times dt, plus the
        // white acceleration's (sigma dt^2 / 2)^2 per axis; cross terms with
        // the position's error are left out.
        let accel = (self.rules.accel_sigma * dt * dt / 2.0).powi(2);
        for r in 0..3 {
            for c in 0..3 {
                pose.covariance[r][c] += e.velocity_covariance[(r, c)] * dt * dt;
            }
            pose.covariance[r][r] += accel;
        }
        if dt > 0.0 {
            // A prediction is not a tower fix.
            pose.towers_used.clear();
        }
        Some(pose)
    }
}
