//! ArduPilot DataFlash logs (`.bin`), read by `ardupilot-binlog`, which
//! takes each message's layout from the file's own FMT messages, so old
//! (`TimeMS`) and current (`TimeUS`) firmware read alike. Old firmware's
//! `GPS` carries GPS time of week, not boot time: such a fix takes the boot
//! time of the message logged before it (the logger writes in order).

use ardupilot_binlog::{Entry, Reader};
use towernav_geometry::Attitude;

use crate::samples::{AttitudeSample, BaroSample, GnssSample, GroundVelocity};
use crate::{FlightLog, LogError};

/// GPS `Status` of a 3-D fix or better.
const FIX_3D: i64 = 3;

pub(crate) fn parse(bytes: &[u8]) -> Result<FlightLog, LogError> {
    if bytes.get(..2) != Some(&[0xA3, 0x95]) {
        return Err(LogError::bare(
            "it does not start with a DataFlash message header (A3 95): not an ArduPilot .bin log"
                .into(),
        ));
    }
    let mut attitude = Vec::new();
    let mut gnss = Vec::new();
    let mut barometer = Vec::new();
    let mut bad = 0usize;
    let mut last_time_s: Option<f64> = None;
    for (index, entry) in Reader::new(bytes).enumerate() {
        let entry = match entry {
            Ok(e) => e,
            Err(e) => {
                bad += 1;
                if bad > 1000 {
                    return Err(LogError::bare(format!(
                        "message {index}: {e} (and a thousand before it)"
                    )));
                }
                continue;
            }
        };
        let own_time = entry
            .timestamp_usec
            .filter(|_| boot_stamped(&entry))
            .map(|us| us as f64 / 1e6);
        if own_time.is_some() {
            last_time_s = own_time;
        }
        let Some(time_s) = own_time.or(last_time_s) else {
            continue;
        };
        match entry.name.as_str() {
            "ATT" => {
                if let Some(a) = attitude_of(&entry) {
                    attitude.push(AttitudeSample {
                        time_s,
                        attitude: a,
                    });
                }
            }
            // The first receiver only (`I` or `Instance` is 0 where logged).
            "GPS" if instance(&entry) == 0 => {
                if let Some(g) = fix_of(&entry, time_s) {
                    gnss.push(g);
                }
            }
            // The first barometer; `Alt` is metres above its zero at boot.
            "BARO" if instance(&entry) == 0 => {
                if let Some(altitude_m) = entry.get_f64("Alt").filter(|a| a.is_finite()) {
                    barometer.push(BaroSample { time_s, altitude_m });
                }
            }
            _ => {}
        }
    }
    Ok(FlightLog {
        attitude,
        gnss,
        barometer,
    })
}

/// Whether the message's first field is boot time: `TimeUS`, or `TimeMS`
/// everywhere but old firmware's `GPS`, where `TimeMS` is GPS time of week
/// and follows `Status`.
fn boot_stamped(e: &Entry) -> bool {
    match e.labels().first().map(String::as_str) {
        Some("TimeUS") => true,
        Some("TimeMS") => e.name != "GPS",
        _ => false,
    }
}

fn instance(e: &Entry) -> i64 {
    e.get_i64("I")
        .or_else(|| e.get_i64("Instance"))
        .unwrap_or(0)
}

/// `Roll`, `Pitch` in degrees; `Yaw` in degrees clockwise from north.
fn attitude_of(e: &Entry) -> Option<Attitude> {
    let (roll, pitch, yaw) = (e.get_f64("Roll")?, e.get_f64("Pitch")?, e.get_f64("Yaw")?);
    [roll, pitch, yaw]
        .iter()
        .all(|v| v.is_finite())
        .then(|| Attitude::from_ned(roll.to_radians(), pitch.to_radians(), yaw.to_radians()))
}

/// `Lat`/`Lng` in 1e-7 degrees, `Alt` in metres above mean sea level.
fn fix_of(e: &Entry, time_s: f64) -> Option<GnssSample> {
    if e.get_i64("Status")? < FIX_3D {
        return None;
    }
    let (lat, lon) = (e.get_f64("Lat")? * 1e-7, e.get_f64("Lng")? * 1e-7);
    let alt = e.get_f64("Alt")?;
    ((-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon) && alt.is_finite()).then_some(
        GnssSample {
            time_s,
            lat_deg: lat,
            lon_deg: lon,
            alt_msl_m: alt,
            // `Spd` m/s over the ground, `GCrs` degrees from north.
            velocity: e
                .get_f64("Spd")
                .zip(e.get_f64("GCrs"))
                .and_then(|(s, c)| GroundVelocity::from_course(s, c)),
        },
    )
}
