//! UTC as an offset from the monotonic clock: the links to the autopilot
//! and to ROS 2 stamp their messages with it, with time passed in.

use std::time::Instant;

/// UTC at a monotonic instant: set at start, reset (by the MAVLink link)
/// from the autopilot's SYSTEM_TIME when it has GNSS time.
#[derive(Debug, Clone, Copy)]
pub struct UnixClock {
    pub at: Instant,
    pub unix_us: u64,
}

impl UnixClock {
    /// UTC at `now`, microseconds.
    pub fn unix_us(&self, now: Instant) -> u64 {
        let since = now.saturating_duration_since(self.at).as_micros() as u64;
        let before = self.at.saturating_duration_since(now).as_micros() as u64;
        (self.unix_us + since).saturating_sub(before)
    }
}
