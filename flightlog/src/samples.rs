//! Time-stamped samples, and attitude between them.

use nalgebra::UnitQuaternion;
use towernav_geometry::{Attitude, Geodetic, geoid_height_m};

/// The body's attitude at a time on the log's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttitudeSample {
    pub time_s: f64,
    pub attitude: Attitude,
}

/// A GNSS fix at a time on the log's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssSample {
    pub time_s: f64,
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Above mean sea level, as receivers and autopilots log it.
    pub alt_msl_m: f64,
    /// Where the log gives it: a receiver's velocity comes from the
    /// carrier's Doppler shift, good to centimetres a second where its
    /// position wanders by metres, so it tells how the position's error
    /// changes.
    pub velocity: Option<GroundVelocity>,
}

/// Velocity over the ground, metres a second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundVelocity {
    pub north_mps: f64,
    pub east_mps: f64,
}

impl GroundVelocity {
    /// `None` unless both are finite.
    pub fn new(north_mps: f64, east_mps: f64) -> Option<Self> {
        (north_mps.is_finite() && east_mps.is_finite()).then_some(Self {
            north_mps,
            east_mps,
        })
    }

    /// From the ground speed and the course over ground, degrees
    /// clockwise from north, as ArduPilot's `GPS` and MAVLink's
    /// `GPS_RAW_INT` log it.
    pub fn from_course(speed_mps: f64, course_deg: f64) -> Option<Self> {
        let c = course_deg.to_radians();
        Self::new(speed_mps * c.cos(), speed_mps * c.sin())
    }
}

impl GnssSample {
    /// The fix with its height above the WGS84 ellipsoid (through the EGM96
    /// geoid), as the rest of the project places points; `None` for a
    /// latitude or longitude out of range.
    pub fn geodetic(&self) -> Option<Geodetic> {
        let h = self.alt_msl_m + geoid_height_m(self.lat_deg, self.lon_deg);
        Geodetic::new(self.lat_deg, self.lon_deg, h).ok()
    }
}

/// The barometer's altitude at a time on the log's clock, metres on the
/// autopilot's own zero (ArduPilot's is the ground at boot, PX4's the
/// standard atmosphere's sea level): only its changes mean anything.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaroSample {
    pub time_s: f64,
    pub altitude_m: f64,
}

/// The barometer at `time_s`, linear between the readings around it (at
/// most [`MAX_GNSS_GAP_S`] apart); `None` outside the log or across a gap.
pub(crate) fn baro_at(samples: &[BaroSample], time_s: f64) -> Option<f64> {
    let i = samples.partition_point(|b| b.time_s < time_s);
    let after = samples.get(i)?;
    if after.time_s == time_s {
        return Some(after.altitude_m);
    }
    let before = samples.get(i.checked_sub(1)?)?;
    if after.time_s - before.time_s > MAX_GNSS_GAP_S {
        return None;
    }
    let w = (time_s - before.time_s) / (after.time_s - before.time_s);
    Some(before.altitude_m + (after.altitude_m - before.altitude_m) * w)
}

/// Fixes further apart than this are a gap, not a track to interpolate.
pub const MAX_GNSS_GAP_S: f64 = 1.0;

/// The fix at `time_s`, linear between the fixes around it (at most
/// [`MAX_GNSS_GAP_S`] apart); `None` outside the log or across a gap.
pub(crate) fn gnss_at(samples: &[GnssSample], time_s: f64) -> Option<GnssSample> {
    let i = samples.partition_point(|g| g.time_s < time_s);
    let after = samples.get(i)?;
    if after.time_s == time_s {
        return Some(*after);
    }
    let before = samples.get(i.checked_sub(1)?)?;
    if after.time_s - before.time_s > MAX_GNSS_GAP_S {
        return None;
    }
    let w = (time_s - before.time_s) / (after.time_s - before.time_s);
    let mix = |a: f64, b: f64| a + (b - a) * w;
    Some(GnssSample {
        time_s,
        lat_deg: mix(before.lat_deg, after.lat_deg),
        lon_deg: mix(before.lon_deg, after.lon_deg),
        alt_msl_m: mix(before.alt_msl_m, after.alt_msl_m),
        velocity: before.velocity.zip(after.velocity).and_then(|(a, b)| {
            GroundVelocity::new(mix(a.north_mps, b.north_mps), mix(a.east_mps, b.east_mps))
        }),
    })
}

/// Sorts by time and keeps one sample per time (the first): logs repeat
/// and reorder messages around reboots of the logger.
pub(crate) fn tidy<T>(samples: &mut Vec<T>, time: impl Fn(&T) -> f64) {
    samples.sort_by(|a, b| time(a).total_cmp(&time(b)));
    samples.dedup_by(|b, a| time(a) == time(b));
}

/// Logs stamp to the millisecond: a frame within this of the first or last
/// sample takes that sample, rather than falling outside by a rounding.
pub const END_TOLERANCE_S: f64 = 1e-3;

/// The attitude at `time_s` by spherical interpolation of the body's
/// rotation (right through yaw's wrap and steep banks); `None` outside
/// (beyond [`END_TOLERANCE_S`]).
pub(crate) fn slerp_at(samples: &[AttitudeSample], time_s: f64) -> Option<Attitude> {
    let (first, last) = (samples.first()?, samples.last()?);
    if time_s < first.time_s {
        return (first.time_s - time_s <= END_TOLERANCE_S).then_some(first.attitude);
    }
    if time_s > last.time_s {
        return (time_s - last.time_s <= END_TOLERANCE_S).then_some(last.attitude);
    }
    let i = samples.partition_point(|s| s.time_s < time_s);
    let after = samples.get(i)?;
    if after.time_s == time_s {
        return Some(after.attitude);
    }
    let before = samples.get(i.checked_sub(1)?)?;
    let f = (time_s - before.time_s) / (after.time_s - before.time_s);
    let (q0, q1) = (
        before.attitude.world_from_body(),
        after.attitude.world_from_body(),
    );
    let q = q0.try_slerp(&q1, f, 1e-12).unwrap_or(q0);
    Some(attitude_of(&q))
}

/// Roll, pitch and yaw of `world_from_body = Rz(yaw) Ry(-pitch) Rx(roll)`.
pub(crate) fn attitude_of(q: &UnitQuaternion<f64>) -> Attitude {
    // nalgebra's euler_angles are (roll, pitch', yaw) of Rz Ry(pitch') Rx.
    let (roll, pitch, yaw) = q.euler_angles();
    Attitude {
        roll,
        pitch: -pitch,
        yaw,
    }
}

/// An autopilot's FRD-to-NED quaternion `(w, x, y, z)` as our attitude.
pub(crate) fn attitude_of_ned_quaternion(w: f64, x: f64, y: f64, z: f64) -> Option<Attitude> {
    let q = nalgebra::Quaternion::new(w, x, y, z);
    if !(q.norm() > 0.5 && q.norm() < 1.5) {
        return None;
    }
    let (roll, pitch, yaw) = UnitQuaternion::from_quaternion(q).euler_angles();
    Some(Attitude::from_ned(roll, pitch, yaw))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use towernav_geometry::wrap_angle;

    #[test]
    fn a_fix_between_fixes_is_interpolated_and_a_gap_is_not_bridged() {
        let fix = |t: f64, lat: f64| GnssSample {
            time_s: t,
            lat_deg: lat,
            lon_deg: 10.0,
            alt_msl_m: 100.0 + t,
            velocity: GroundVelocity::new(t, -t),
        };
        let fixes = [fix(0.0, 50.0), fix(0.5, 50.001), fix(3.0, 50.002)];
        let mid = gnss_at(&fixes, 0.25).expect("between fixes");
        assert!((mid.lat_deg - 50.0005).abs() < 1e-12 && (mid.alt_msl_m - 100.25).abs() < 1e-12);
        assert_eq!(mid.velocity, GroundVelocity::new(0.25, -0.25));
        assert_eq!(gnss_at(&fixes, 0.5), Some(fixes[1]));
        assert!(
            gnss_at(&fixes, 1.0).is_none(),
            "2.5 s between fixes is a gap"
        );
        assert!(gnss_at(&fixes, -0.1).is_none() && gnss_at(&fixes, 3.1).is_none());
        // MSL to the ellipsoid: the geoid's undulation is added.
        let g = fixes[0].geodetic().expect("valid");
        let n = geoid_height_m(50.0, 10.0);
        assert!((g.height_m - (100.0 + n)).abs() < 1e-9 && n.abs() > 1.0);
    }

    fn at(time_s: f64, roll: f64, pitch: f64, yaw: f64) -> AttitudeSample {
        AttitudeSample {
            time_s,
            attitude: Attitude { roll, pitch, yaw },
        }
    }

    #[test]
    fn slerp_takes_yaw_the_short_way_and_stops_at_the_ends() {
        let d = |x: f64| x.to_radians();
        let samples = [at(0.0, 0.0, 0.0, d(170.0)), at(1.0, 0.0, 0.0, d(-170.0))];
        let mid = slerp_at(&samples, 0.5).expect("inside");
        assert!(
            (wrap_angle(mid.yaw) - std::f64::consts::PI).abs() < 1e-9,
            "{mid:?}"
        );
        assert!(slerp_at(&samples, -0.01).is_none());
        assert!(slerp_at(&samples, 1.01).is_none());
        assert_eq!(slerp_at(&samples, 1.0), Some(samples[1].attitude));
    }

    #[test]
    fn a_ned_quaternion_reads_as_its_euler_angles() {
        // Heading 90 (east), 10 degrees nose up: q = Rz(90) Ry(10) in NED.
        let q = UnitQuaternion::from_euler_angles(0.0, 10f64.to_radians(), 90f64.to_radians());
        let a = attitude_of_ned_quaternion(q.w, q.i, q.j, q.k).expect("unit");
        assert!(a.yaw.abs() < 1e-12 && (a.pitch - 10f64.to_radians()).abs() < 1e-12);
        assert!(attitude_of_ned_quaternion(0.0, 0.0, 0.0, 0.0).is_none());
    }

    proptest! {
        #[test]
        fn euler_angles_round_trip(roll in -1.4f64..1.4, pitch in -1.4f64..1.4, yaw in -3.1f64..3.1) {
            let a = Attitude { roll, pitch, yaw };
            let back = attitude_of(&a.world_from_body());
            prop_assert!((back.roll - roll).abs() < 1e-9 && (back.pitch - pitch).abs() < 1e-9);
            prop_assert!(wrap_angle(back.yaw - yaw).abs() < 1e-9);
        }
    }
}
