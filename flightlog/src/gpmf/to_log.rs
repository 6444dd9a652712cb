//! A GoPro's telemetry as a flight log.
//!
//! - GNSS: the camera's `GPS9` (fix 2D/3D, DOP <= 5) or `GPS5` (with the
//!   payload's `GPSF` fix and `GPSP` DOP), whose altitude GoPro documents as
//!   above the WGS84 ellipsoid (turned into mean sea level here); without
//!   them, a Karma's `GLPI` (MAVLink GLOBAL_POSITION_INT, above sea level).
//! - Barometer: a Karma's `GLPI` height above home.
//! - Attitude: a Karma's `ATTD` (the vehicle's, MAVLink ATTITUDE; the
//!   gimbal's pitch is then the camera mount); else the camera's own, roll
//!   and pitch from `GRAV` and yaw from the GPS track's course, which takes
//!   the camera to look along the track (fly it with a zero camera mount).
//!   A camera without `GRAV` (before the HERO8) and without a Karma is
//!   refused, saying what the chain needs instead.
//!
//! `GRAV` is read in the image's axes (x right, y down, z out of the lens):
//! a camera held level and upright reads (0, 1, 0).

use towernav_geometry::{Attitude, msl_from_ellipsoid_m as msl, wrap_angle};

use super::{Stream, Telemetry};
use crate::samples::{AttitudeSample, BaroSample, GnssSample};
use crate::{FlightLog, LogError};

/// Course over ground needs this speed to mean a heading.
const COURSE_MIN_SPEED_M_S: f64 = 1.0;
/// Fixes this far apart give one course.
const COURSE_BASELINE_S: f64 = 1.0;
/// A course stands for the camera's yaw this long either side.
const COURSE_HOLD_S: f64 = 1.5;
/// GPS9's DOP and GPSP's DOP x 100 above which a fix is dropped.
const MAX_DOP: f64 = 5.0;

/// The telemetry as a flight log on the video's clock.
pub fn flight_log(t: &Telemetry) -> Result<FlightLog, LogError> {
    let gnss = gnss(t);
    let barometer = t
        .stream("GLPI")
        .map(|s| {
            s.samples
                .iter()
                .filter_map(|x| {
                    Some(BaroSample {
                        time_s: x.time_s,
                        altitude_m: *x.values.get(4)?,
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    let attitude = if let Some(attd) = t.stream("ATTD") {
        attd.samples
            .iter()
            .filter_map(|x| {
                let (roll, pitch, yaw) = (*x.values.get(1)?, *x.values.get(2)?, *x.values.get(3)?);
                Some(AttitudeSample {
                    time_s: x.time_s,
                    attitude: Attitude::from_ned(roll, pitch, yaw),
                })
            })
            .collect()
    } else if let Some(grav) = t.stream("GRAV") {
        let course = course(&gnss);
        if course.is_empty() {
            return Err(LogError::bare(format!(
                "GPMF: the camera's gravity vector gives its roll and pitch, but its yaw comes \
                 from the GPS track's course and the track never moves at {COURSE_MIN_SPEED_M_S} m/s \
                 or more ({} GPS fixes): give the aircraft's flight log as --log",
                gnss.len()
            )));
        }
        camera_attitude(grav, &course)
    } else {
        return Err(LogError::bare(format!(
            "GPMF: no attitude: the camera records no gravity vector (GRAV comes with the HERO8 \
             and later) and no Karma attitude (ATTD); give the aircraft's flight log as --log \
             and the MP4 as --video (streams found: {})",
            t.streams
                .iter()
                .map(|s| s.key.as_str())
                .collect::<Vec<_>>()
                .join(" ")
        )));
    };
    Ok(FlightLog {
        attitude,
        gnss,
        barometer,
    })
}

fn gnss(t: &Telemetry) -> Vec<GnssSample> {
    let fix = |lat: f64, lon: f64, alt: f64, time_s: f64| GnssSample {
        time_s,
        lat_deg: lat,
        lon_deg: lon,
        alt_msl_m: alt,
        // GPS5 and GPS9 give the speed, not its direction.
        velocity: None,
    };
    if let Some(gps9) = t.stream("GPS9") {
        return gps9
            .samples
            .iter()
            .filter_map(|x| {
                let v = &x.values;
                let (lat, lon, alt) = (*v.first()?, *v.get(1)?, *v.get(2)?);
                let good = *v.get(8)? >= 2.0 && *v.get(7)? <= MAX_DOP;
                good.then(|| fix(lat, lon, msl(lat, lon, alt), x.time_s))
            })
            .collect();
    }
    if let Some(gps5) = t.stream("GPS5") {
        // One fix state and one DOP per payload, at the payload's start.
        let latest = |key: &str, time_s: f64| {
            t.stream(key).and_then(|s| {
                s.samples
                    .iter()
                    .take_while(|x| x.time_s <= time_s + 1e-9)
                    .last()
                    .and_then(|x| x.values.first().copied())
            })
        };
        return gps5
            .samples
            .iter()
            .filter_map(|x| {
                let v = &x.values;
                let (lat, lon, alt) = (*v.first()?, *v.get(1)?, *v.get(2)?);
                let fixed = latest("GPSF", x.time_s).is_none_or(|f| f >= 2.0);
                let precise = latest("GPSP", x.time_s).is_none_or(|p| p <= MAX_DOP * 100.0);
                (fixed && precise).then(|| fix(lat, lon, msl(lat, lon, alt), x.time_s))
            })
            .collect();
    }
    t.stream("GLPI")
        .map(|s| {
            s.samples
                .iter()
                .filter_map(|x| {
                    let v = &x.values;
                    Some(fix(*v.get(1)?, *v.get(2)?, *v.get(3)?, x.time_s))
                })
                .collect()
        })
        .unwrap_or_default()
}

/// (time, ENU yaw) of the track's course wherever it moves fast enough.
fn course(gnss: &[GnssSample]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for (i, a) in gnss.iter().enumerate() {
        let Some(b) = gnss[i..]
            .iter()
            .find(|b| b.time_s >= a.time_s + COURSE_BASELINE_S)
        else {
            break;
        };
        let north = (b.lat_deg - a.lat_deg).to_radians() * 6_371_000.0;
        let east =
            (b.lon_deg - a.lon_deg).to_radians() * 6_371_000.0 * a.lat_deg.to_radians().cos();
        let dt = b.time_s - a.time_s;
        if north.hypot(east) / dt >= COURSE_MIN_SPEED_M_S {
            out.push(((a.time_s + b.time_s) / 2.0, north.atan2(east)));
        }
    }
    out
}

/// The camera's attitude from its gravity vector and the nearest course.
fn camera_attitude(grav: &Stream, course: &[(f64, f64)]) -> Vec<AttitudeSample> {
    grav.samples
        .iter()
        .filter_map(|x| {
            let (gx, gy, gz) = (*x.values.first()?, *x.values.get(1)?, *x.values.get(2)?);
            let norm = (gx * gx + gy * gy + gz * gz).sqrt();
            if norm < 1e-6 {
                return None;
            }
            let (gx, gy, gz) = (gx / norm, gy / norm, gz / norm);
            let i = course.partition_point(|c| c.0 < x.time_s);
            let nearest = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter_map(|j| course.get(j))
                .min_by(|a, b| (a.0 - x.time_s).abs().total_cmp(&(b.0 - x.time_s).abs()))?;
            if (nearest.0 - x.time_s).abs() > COURSE_HOLD_S {
                return None;
            }
            Some(AttitudeSample {
                time_s: x.time_s,
                attitude: Attitude {
                    roll: gx.atan2(gy),
                    pitch: -gz.clamp(-1.0, 1.0).asin(),
                    yaw: wrap_angle(nearest.1),
                },
            })
        })
        .collect()
}
