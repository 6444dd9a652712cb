//! The MAVLink link to the autopilot as a state machine without I/O: what to
//! send and when, in the manner of the daemon core. The shell feeds it each
//! frame's estimate (`handle_estimate`), the autopilot's messages
//! (`handle_message`) and its timer (`handle_timeout` at `poll_timeout`), and
//! sends what `poll_transmit` hands back.
//!
//! - HEARTBEAT at 1 Hz, whatever the camera does.
//! - The position (GPS_INPUT or GLOBAL_POSITION_SENSOR) at its own rate, also
//!   when there is no estimate: then GPS_INPUT says NO_FIX, so the autopilot
//!   sees a lost fix, not a dead link.
//! - The fix is 3-D only within `fresh_fix` of a tower fix; coasting, it is
//!   2-D (its accuracy growing with the filter's covariance) while that
//!   covariance stays within `coast_max_sigma_m`, for at most `coast_fix`;
//!   then none.
//! - ODOMETRY at its own rate, the filter's estimate predicted to the moment
//!   it goes out, with quality -1 once the pose is lost.
//! - STATUSTEXT on every change of the fix.
//! - TIMESYNC requests are answered, so the autopilot can map our stamps to
//!   its clock; an autopilot heartbeating under another system id is logged; SYSTEM_TIME with a GNSS time sets the clock we stamp with;
//!   GLOBAL_POSITION_INT is kept as the autopilot's own position.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    GLOBAL_POSITION_INT_DATA, GpsFixType, MavAutopilot, MavMessage, MavSeverity, TIMESYNC_DATA,
};
use towernav_geometry::{Attitude, Datum, GeoidCache};
use towernav_protocol::{EdgeState, Health, PoseEstimate};

use crate::autopilot::{global_position, gps_input, heartbeat, odometry, status_text};
pub use crate::fix_keeper::LinkEstimate;
use crate::fix_keeper::{FixKeeper, FixKind, FixRules};
use crate::unix_clock::UnixClock;

/// How often HEARTBEAT goes out (MAVLink's microservices expect 1 Hz).
pub const HEARTBEAT_EVERY: Duration = Duration::from_secs(1);

/// Which position message the autopilot gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PositionMessage {
    /// GPS_INPUT: a GNSS stand-in (ArduPilot GPS_TYPE 14, PX4's MAVLink GPS).
    GpsInput,
    /// GLOBAL_POSITION_SENSOR: PX4's auxiliary global position (AGP).
    AuxGlobalPosition,
}

/// What the link is told once, at start.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkConfig {
    /// The vehicle's system id, which the edge sends as; an autopilot
    /// heartbeating under another is told in the log.
    pub system_id: u8,
    /// The position message and its period; `None`: none.
    pub position: Option<(PositionMessage, Duration)>,
    /// ODOMETRY's period; `None`: none.
    pub odometry_every: Option<Duration>,
    /// The fix is 3-D only this long after a tower fix.
    pub fresh_fix: Duration,
    /// Coasting, the fix is 2-D at most this long after the last tower fix;
    /// then none.
    pub coast_fix: Duration,
    /// Coasting, the fix is 2-D only while the predicted horizontal 1-sigma
    /// (its ellipse's major axis) is within this, metres: a stalled camera
    /// loses the fix as soon as the prediction is worth little.
    pub coast_max_sigma_m: f64,
    /// The filter's white acceleration, m/s^2: how a prediction's error grows
    /// beyond its velocity's.
    pub accel_sigma: f64,
}

impl LinkConfig {
    /// The rules on how long a fix stays good.
    pub fn fix_rules(&self) -> FixRules {
        FixRules {
            fresh_fix: self.fresh_fix,
            coast_fix: self.coast_fix,
            coast_max_sigma_m: self.coast_max_sigma_m,
            accel_sigma: self.accel_sigma,
        }
    }
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            system_id: 1,
            position: Some((PositionMessage::GpsInput, Duration::from_millis(200))),
            odometry_every: None,
            fresh_fix: Duration::from_secs(1),
            coast_fix: Duration::from_secs(20),
            coast_max_sigma_m: 5.0,
            accel_sigma: 1.5,
        }
    }
}

/// The autopilot's own position (GLOBAL_POSITION_INT), while its GNSS is good.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutopilotPosition {
    pub received: Instant,
    /// Latitude, longitude, altitude above mean sea level, and the same
    /// above the ellipsoid (through the geoid), as towernav's geodesy wants.
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_msl_m: f64,
    pub height_m: f64,
    /// Heading, radians clockwise from north, when known.
    pub heading_rad: Option<f64>,
}

/// Autopilots send SYSTEM_TIME with 0 until they have GNSS time; any time
/// before 2020 is not a real one.
const EARLIEST_REAL_UNIX_US: u64 = 1_577_836_800_000_000;

pub struct AutopilotLink {
    config: LinkConfig,
    clock: UnixClock,
    geoid: GeoidCache,
    fix: FixKeeper,
    health: Health,
    reported_fix: Option<GpsFixType>,
    autopilot_position: Option<AutopilotPosition>,
    autopilot_system: Option<u8>,
    next_heartbeat: Instant,
    next_position: Instant,
    next_odometry: Instant,
    out: VecDeque<MavMessage>,
}

impl AutopilotLink {
    /// A link starting at `now`, when UTC is `unix_now_us`.
    pub fn new(config: LinkConfig, datum: Datum, now: Instant, unix_now_us: u64) -> Self {
        let rules = config.fix_rules();
        Self {
            config,
            clock: UnixClock {
                at: now,
                unix_us: unix_now_us,
            },
            geoid: GeoidCache::default(),
            fix: FixKeeper::new(rules, datum),
            health: Health::Ok,
            reported_fix: None,
            autopilot_position: None,
            autopilot_system: None,
            next_heartbeat: now,
            next_position: now,
            next_odometry: now,
            out: VecDeque::new(),
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
        self.fix.handle_estimate(now, estimate, state);
        self.report_fix_change(now);
    }

    /// The daemon's health, for the heartbeat.
    pub fn handle_health(&mut self, health: Health) {
        self.health = health;
    }

    /// A message from the autopilot, sent by `from` (system and component id).
    pub fn handle_message(&mut self, now: Instant, from: (u8, u8), message: &MavMessage) {
        match message {
            MavMessage::HEARTBEAT(h) if h.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID => {
                let first = self.autopilot_system.replace(from.0).is_none();
                if first && from.0 != self.config.system_id {
                    tracing::warn!(
                        autopilot = from.0,
                        ours = self.config.system_id,
                        "the autopilot heartbeats as another system than mavlink.system_id: it may ignore what the edge sends"
                    );
                }
            }
            // A request (tc1 0): answer with our clock, in nanoseconds, to its sender.
            MavMessage::TIMESYNC(t) if t.tc1 == 0 => {
                let ours_ns = self.clock.unix_us(now).saturating_mul(1000) as i64;
                self.out.push_back(MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: ours_ns,
                    ts1: t.ts1,
                    target_system: from.0,
                    target_component: from.1,
                }));
            }
            MavMessage::SYSTEM_TIME(t) if t.time_unix_usec >= EARLIEST_REAL_UNIX_US => {
                self.clock = UnixClock {
                    at: now,
                    unix_us: t.time_unix_usec,
                };
            }
            MavMessage::GLOBAL_POSITION_INT(p) => {
                self.autopilot_position = autopilot_position(now, p).map(|mut p| {
                    p.height_m = p.alt_msl_m + self.geoid.height_m(p.lat_deg, p.lon_deg);
                    p
                });
            }
            _ => {}
        }
    }

    /// The system id the autopilot heartbeats as, once it has.
    pub fn autopilot_system(&self) -> Option<u8> {
        self.autopilot_system
    }

    /// The autopilot's last own position, if it has sent one.
    pub fn autopilot_position(&self) -> Option<&AutopilotPosition> {
        self.autopilot_position.as_ref()
    }

    /// UTC at `now`, microseconds, as the link stamps its messages.
    pub fn unix_us(&self, now: Instant) -> u64 {
        self.clock.unix_us(now)
    }

    /// When `handle_timeout` is next due.
    pub fn poll_timeout(&self) -> Instant {
        let mut due = self.next_heartbeat;
        if self.config.position.is_some() {
            due = due.min(self.next_position);
        }
        if self.config.odometry_every.is_some() {
            due = due.min(self.next_odometry);
        }
        due
    }

    /// Queues whatever is due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        self.report_fix_change(now);
        if now >= self.next_heartbeat {
            self.out.push_back(MavMessage::HEARTBEAT(heartbeat(
                self.fix.state(),
                self.health,
            )));
            self.next_heartbeat = next_due(self.next_heartbeat, HEARTBEAT_EVERY, now);
        }
        if let Some((message, every)) = self.config.position
            && now >= self.next_position
        {
            self.queue_position(now, message);
            self.next_position = next_due(self.next_position, every, now);
        }
        if let Some(every) = self.config.odometry_every
            && now >= self.next_odometry
        {
            if let Some(pose) = self.predicted(now) {
                let quality = match self.fix_type(now) {
                    GpsFixType::GPS_FIX_TYPE_3D_FIX => 100,
                    GpsFixType::GPS_FIX_TYPE_2D_FIX => 50,
                    _ => -1,
                };
                let attitude = self.fix.latest().map(|e| e.attitude);
                let attitude = attitude.unwrap_or(Attitude::level(pose.yaw_rad));
                let unix = self.clock.unix_us(now);
                self.out.push_back(MavMessage::ODOMETRY(odometry(
                    &pose, &attitude, unix, quality,
                )));
            }
            self.next_odometry = next_due(self.next_odometry, every, now);
        }
    }

    /// The next message to send, oldest first.
    pub fn poll_transmit(&mut self) -> Option<MavMessage> {
        self.out.pop_front()
    }

    /// The fix the autopilot is told of at `now`.
    pub fn fix_type(&self, now: Instant) -> GpsFixType {
        match self.fix.fix(now) {
            FixKind::Fresh => GpsFixType::GPS_FIX_TYPE_3D_FIX,
            FixKind::Coasting => GpsFixType::GPS_FIX_TYPE_2D_FIX,
            FixKind::None => GpsFixType::GPS_FIX_TYPE_NO_FIX,
        }
    }

    /// The latest estimate carried to `now` at its velocity, its covariance
    /// grown by the velocity's and the filter's acceleration noise.
    pub fn predicted(&self, now: Instant) -> Option<PoseEstimate> {
        self.fix.predicted(now)
    }

    fn queue_position(&mut self, now: Instant, message: PositionMessage) {
        let fix = self.fix_type(now);
        let pose = self.predicted(now);
        let unix = self.clock.unix_us(now);
        let geoid = pose
            .as_ref()
            .map_or(0.0, |p| self.geoid.height_m(p.lat_deg, p.lon_deg));
        match (message, pose) {
            (PositionMessage::GpsInput, pose) => {
                let reported = pose.filter(|_| fix != GpsFixType::GPS_FIX_TYPE_NO_FIX);
                self.out.push_back(MavMessage::GPS_INPUT(gps_input(
                    reported.as_ref(),
                    fix,
                    geoid,
                    unix,
                )));
            }
            (PositionMessage::AuxGlobalPosition, Some(pose)) => {
                let healthy = fix == GpsFixType::GPS_FIX_TYPE_3D_FIX;
                self.out
                    .push_back(MavMessage::GLOBAL_POSITION_SENSOR(global_position(
                        &pose, geoid, healthy, unix,
                    )));
            }
            // Nothing to say where: PX4 times the source out, as it should.
            (PositionMessage::AuxGlobalPosition, None) => {}
        }
    }

    /// STATUSTEXT when the fix told to the autopilot changes.
    fn report_fix_change(&mut self, now: Instant) {
        let fix = self.fix_type(now);
        if self.reported_fix == Some(fix) {
            return;
        }
        let first = self.reported_fix.is_none();
        self.reported_fix = Some(fix);
        if first && fix == GpsFixType::GPS_FIX_TYPE_NO_FIX {
            return;
        }
        let (severity, text) = match fix {
            GpsFixType::GPS_FIX_TYPE_3D_FIX => (
                MavSeverity::MAV_SEVERITY_INFO,
                "towernav: 3D fix from towers",
            ),
            GpsFixType::GPS_FIX_TYPE_2D_FIX => (
                MavSeverity::MAV_SEVERITY_WARNING,
                "towernav: coasting, no tower fix",
            ),
            _ => (MavSeverity::MAV_SEVERITY_ERROR, "towernav: position lost"),
        };
        self.out
            .push_back(MavMessage::STATUSTEXT(status_text(severity, text)));
    }
}

/// The period after `due`, or half a period from `now` when the timer ran
/// late: a late timer does not fire a burst.
fn next_due(due: Instant, every: Duration, now: Instant) -> Instant {
    (due + every).max(now + every / 2)
}

fn autopilot_position(now: Instant, p: &GLOBAL_POSITION_INT_DATA) -> Option<AutopilotPosition> {
    // Autopilots send zeros before their first GNSS fix.
    if p.lat == 0 && p.lon == 0 {
        return None;
    }
    Some(AutopilotPosition {
        received: now,
        lat_deg: f64::from(p.lat) / 1e7,
        lon_deg: f64::from(p.lon) / 1e7,
        alt_msl_m: f64::from(p.alt) / 1e3,
        height_m: f64::from(p.alt) / 1e3,
        heading_rad: (p.hdg != u16::MAX).then(|| (f64::from(p.hdg) / 100.0).to_radians()),
    })
}

#[cfg(test)]
#[path = "autopilot_link_tests.rs"]
mod tests;
