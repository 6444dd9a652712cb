//! The fix for ROS 2 and for PX4's Zenoh module, as a state machine without
//! I/O (as `autopilot_link` is for MAVLink): the shell feeds it each frame's
//! estimate (`handle_estimate`), PX4's clock as `vehicle_attitude` shows it
//! (`handle_px4_time`) and its timer (`handle_timeout` at `poll_timeout`),
//! and publishes what `poll_transmit` hands back.
//!
//! At `rate` it sends, predicted to that moment:
//! - `NavSatFix`: STATUS_FIX with its ENU covariance while the fix is fresh
//!   or coasting within the limits (`FixRules`), STATUS_NO_FIX after, so a
//!   lost fix is never silence;
//! - `PoseWithCovarianceStamped` and `Odometry` in the `map` frame (ENU,
//!   origin the mission datum) with `base_link` FLU (REP 103/105), while
//!   there is a usable fix;
//! - PX4's auxiliary global position: a fix only while it is fresh (the
//!   MAVLink rule), else latitude and longitude NaN, which PX4's EKF2 takes
//!   as "stop fusing" at once. A prediction is never fed back as a fix: it
//!   is the autopilot's own dead reckoning, counted twice.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Vector3};
use towernav_geometry::{Attitude, Datum, GeoidCache};
use towernav_protocol::ros2::msgs::{
    Header, NavSatFix, Odometry, PoseWithCovariance, PoseWithCovarianceStamped, Px4GlobalPosition,
    Stamp, nav_sat_status,
};
use towernav_protocol::{EdgeState, PoseEstimate};

use crate::filter::horizontal_sigma;
use crate::fix_keeper::{FixKeeper, FixKind, FixRules, LinkEstimate};
use crate::unix_clock::UnixClock;

/// What the link is told once, at start.
#[derive(Debug, Clone, PartialEq)]
pub struct RosLinkConfig {
    /// How often everything goes out.
    pub every: Duration,
    /// Publish the ROS 2 topics.
    pub ros2: bool,
    /// Publish PX4's auxiliary global position, under this source id.
    pub px4_source_id: Option<u8>,
    pub fix: FixRules,
    /// The local frame (`map`) and the body's (`base_link`).
    pub map_frame: String,
    pub base_frame: String,
    /// The attitude's 1-sigma about the body's x and y (roll, pitch), radians:
    /// the autopilot's, not estimated here.
    pub roll_pitch_sigma_rad: f64,
}

/// One message to publish.
#[derive(Debug, Clone, PartialEq)]
pub enum RosOutput {
    NavSatFix(Box<NavSatFix>),
    Pose(Box<PoseWithCovarianceStamped>),
    Odometry(Box<Odometry>),
    Px4(Box<Px4GlobalPosition>),
}

/// The variance put on what is not measured (the twist's angular rates).
pub const UNMEASURED_VARIANCE: f64 = 1e6;

/// PX4's clock against UTC: its `vehicle_attitude` stamps lag their arrival
/// by the link's latency, so the largest offset seen is the best; it is let
/// down slowly (the clocks drift) and reset when PX4 reboots.
#[derive(Debug, Clone, Copy)]
struct Px4Clock {
    offset_us: f64,
    at: Instant,
}

/// How fast the kept offset may fall, microseconds per second (200 ppm).
const PX4_CLOCK_SLACK_US_PER_S: f64 = 200.0;
/// An offset this much lower than the kept one is a reboot, not latency.
const PX4_REBOOT_US: f64 = 1e6;

pub struct RosLink {
    config: RosLinkConfig,
    fix: FixKeeper,
    geoid: GeoidCache,
    clock: UnixClock,
    px4_clock: Option<Px4Clock>,
    next: Instant,
    /// Counts re-acquisitions after a lost fix, for PX4's reset counter.
    resets: u8,
    had_fresh: bool,
    lost: bool,
    out: VecDeque<RosOutput>,
}

impl RosLink {
    /// A link starting at `now`, when UTC is `unix_now_us`.
    pub fn new(config: RosLinkConfig, datum: Datum, now: Instant, unix_now_us: u64) -> Self {
        Self {
            fix: FixKeeper::new(config.fix, datum),
            config,
            geoid: GeoidCache::default(),
            clock: UnixClock {
                at: now,
                unix_us: unix_now_us,
            },
            px4_clock: None,
            next: now,
            resets: 0,
            had_fresh: false,
            lost: false,
            out: VecDeque::new(),
        }
    }

    /// A frame's outcome: its estimate (none when the filter reports none)
    /// and the edge's state.
    pub fn handle_estimate(
        &mut self,
        now: Instant,
        estimate: Option<LinkEstimate>,
        state: EdgeState,
    ) {
        self.fix.handle_estimate(now, estimate, state);
    }

    /// PX4's time since boot, microseconds, as a message stamped it that
    /// arrived at `now`.
    pub fn handle_px4_time(&mut self, now: Instant, px4_us: u64) {
        let sample = px4_us as f64 - self.clock.unix_us(now) as f64;
        self.px4_clock = Some(match self.px4_clock {
            Some(kept) => {
                let slack =
                    now.saturating_duration_since(kept.at).as_secs_f64() * PX4_CLOCK_SLACK_US_PER_S;
                let held = kept.offset_us - slack;
                // Lower by far: PX4 rebooted. Higher: less latency than before.
                if sample < held - PX4_REBOOT_US || sample >= held {
                    Px4Clock {
                        offset_us: sample,
                        at: now,
                    }
                } else {
                    kept
                }
            }
            None => Px4Clock {
                offset_us: sample,
                at: now,
            },
        });
    }

    /// PX4's clock at `now`, once it has been seen.
    pub fn px4_time_us(&self, now: Instant) -> Option<u64> {
        self.px4_clock
            .map(|c| (self.clock.unix_us(now) as f64 + c.offset_us).max(0.0) as u64)
    }

    /// How good the fix is at `now`.
    pub fn fix(&self, now: Instant) -> FixKind {
        self.fix.fix(now)
    }

    pub fn poll_timeout(&self) -> Instant {
        self.next
    }

    /// Queues whatever is due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if now < self.next {
            return;
        }
        // A late timer does not fire a burst.
        self.next = (self.next + self.config.every).max(now + self.config.every / 2);
        let kind = self.fix.fix(now);
        let pose = self.fix.predicted(now);
        let usable = pose.as_ref().filter(|_| kind != FixKind::None);
        let stamp = Stamp::from_unix_us(self.clock.unix_us(now));
        let header = |frame: &str| Header {
            stamp,
            frame_id: frame.to_owned(),
        };
        let (map_frame, base_frame) = (
            self.config.map_frame.clone(),
            self.config.base_frame.clone(),
        );
        if self.config.ros2 {
            let fix = self.nav_sat_fix(header(&base_frame), usable);
            self.out.push_back(RosOutput::NavSatFix(Box::new(fix)));
            if let (Some(pose), Some(latest)) = (usable, self.fix.latest()) {
                let with_cov =
                    pose_with_covariance(pose, &latest.attitude, self.config.roll_pitch_sigma_rad);
                self.out
                    .push_back(RosOutput::Pose(Box::new(PoseWithCovarianceStamped {
                        header: header(&map_frame),
                        pose: with_cov.clone(),
                    })));
                let (linear, twist_covariance) = twist(latest, pose.yaw_rad);
                self.out.push_back(RosOutput::Odometry(Box::new(Odometry {
                    header: header(&map_frame),
                    child_frame_id: base_frame.clone(),
                    pose: with_cov,
                    linear,
                    angular: [0.0; 3],
                    twist_covariance,
                })));
            }
        }
        if let Some(id) = self.config.px4_source_id {
            let fresh = pose.as_ref().filter(|_| kind == FixKind::Fresh);
            match (fresh.is_some(), self.had_fresh) {
                (true, _) if self.lost => {
                    self.resets = self.resets.wrapping_add(1);
                    self.lost = false;
                }
                (true, _) => self.had_fresh = true,
                (false, true) => self.lost = true,
                (false, false) => {}
            }
            let message = self.px4_position(now, id, fresh);
            self.out.push_back(RosOutput::Px4(Box::new(message)));
        }
    }

    /// The next message to publish, oldest first.
    pub fn poll_transmit(&mut self) -> Option<RosOutput> {
        self.out.pop_front()
    }

    fn nav_sat_fix(&self, header: Header, pose: Option<&PoseEstimate>) -> NavSatFix {
        let Some(p) = pose else {
            return NavSatFix {
                header,
                status: nav_sat_status::STATUS_NO_FIX,
                service: 0,
                latitude: f64::NAN,
                longitude: f64::NAN,
                altitude: f64::NAN,
                position_covariance: [0.0; 9],
                position_covariance_type: nav_sat_status::COVARIANCE_TYPE_UNKNOWN,
            };
        };
        let mut position_covariance = [0.0; 9];
        for r in 0..3 {
            for c in 0..3 {
                position_covariance[r * 3 + c] = p.covariance[r][c];
            }
        }
        NavSatFix {
            header,
            status: nav_sat_status::STATUS_FIX,
            service: 0,
            latitude: p.lat_deg,
            longitude: p.lon_deg,
            altitude: p.alt_m,
            position_covariance,
            position_covariance_type: nav_sat_status::COVARIANCE_TYPE_KNOWN,
        }
    }

    fn px4_position(
        &mut self,
        now: Instant,
        id: u8,
        fresh: Option<&PoseEstimate>,
    ) -> Px4GlobalPosition {
        let stamp = self.px4_time_us(now).unwrap_or(0);
        let mut m = Px4GlobalPosition {
            timestamp_us: stamp,
            timestamp_sample_us: stamp,
            id,
            lat_deg: f64::NAN,
            lon_deg: f64::NAN,
            alt_amsl_m: f32::NAN,
            alt_ellipsoid_m: f32::NAN,
            eph_m: f32::NAN,
            epv_m: f32::NAN,
            lat_lon_reset_counter: self.resets,
        };
        if let Some(p) = fresh {
            let c = &p.covariance;
            let en = nalgebra::Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]);
            let geoid = self.geoid.height_m(p.lat_deg, p.lon_deg);
            m.lat_deg = p.lat_deg;
            m.lon_deg = p.lon_deg;
            m.alt_amsl_m = (p.alt_m - geoid) as f32;
            m.alt_ellipsoid_m = p.alt_m as f32;
            m.eph_m = horizontal_sigma(&en) as f32;
            m.epv_m = c[2][2].max(0.0).sqrt() as f32;
        }
        m
    }
}

/// The pose in `map` (ENU at the datum) with `base_link` FLU: position and
/// the estimated yaw with its covariance, roll and pitch the autopilot's.
pub fn pose_with_covariance(
    pose: &PoseEstimate,
    attitude: &Attitude,
    roll_pitch_sigma_rad: f64,
) -> PoseWithCovariance {
    let q = Attitude {
        yaw: pose.yaw_rad,
        ..*attitude
    }
    .world_from_body();
    let c = &pose.covariance;
    let mut covariance = [0.0; 36];
    // (e, n, u, yaw) -> (x, y, z, rx, ry, rz): yaw is rz.
    let index = [0usize, 1, 2, 5];
    for (i, &ri) in index.iter().enumerate() {
        for (j, &rj) in index.iter().enumerate() {
            covariance[ri * 6 + rj] = c[i][j];
        }
    }
    covariance[3 * 6 + 3] = roll_pitch_sigma_rad.powi(2);
    covariance[4 * 6 + 4] = roll_pitch_sigma_rad.powi(2);
    PoseWithCovariance {
        position: [pose.east_m, pose.north_m, pose.up_m],
        orientation: [q.i, q.j, q.k, q.w],
        covariance,
    }
}

/// The velocity in the body's FLU axes under the estimated yaw (level: the
/// filter estimates no roll or pitch), with its covariance; angular rates
/// are not measured.
fn twist(latest: &LinkEstimate, yaw: f64) -> ([f64; 3], [f64; 36]) {
    let r = Matrix3::from(nalgebra::Rotation3::from_axis_angle(
        &Vector3::z_axis(),
        -yaw,
    ));
    let v = r * latest.velocity_in_world;
    let cv = r * latest.velocity_covariance * r.transpose();
    let mut covariance = [0.0; 36];
    for i in 0..3 {
        for j in 0..3 {
            covariance[i * 6 + j] = cv[(i, j)];
        }
        covariance[(i + 3) * 6 + i + 3] = UNMEASURED_VARIANCE;
    }
    ([v.x, v.y, v.z], covariance)
}

#[cfg(test)]
#[path = "ros_link_tests.rs"]
mod tests;
