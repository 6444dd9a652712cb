//! PX4 ULog (`.ulg`), read by `yule_log`: `vehicle_attitude` (the FRD-to-NED
//! quaternion `q`, w first) and GNSS from `sensor_gps` or
//! `vehicle_gps_position` (receiver fixes), else `vehicle_global_position`.
//! Times are the logger's microseconds since boot.

use yule_log::builder::ULogParserBuilder;
use yule_log::model::inst::{FieldValue, Format};
use yule_log::model::msg::UlogMessage;

use crate::samples::{
    AttitudeSample, BaroSample, GnssSample, GroundVelocity, attitude_of_ned_quaternion,
};
use crate::{FlightLog, LogError};

pub(crate) fn parse(bytes: &[u8]) -> Result<FlightLog, LogError> {
    let parser = ULogParserBuilder::new(bytes)
        .build()
        .map_err(|e| LogError::bare(format!("not a ULog file: {e}")))?;
    let mut attitude = Vec::new();
    let mut receiver = Vec::new();
    let mut fused = Vec::new();
    let mut barometer = Vec::new();
    for (index, message) in parser.enumerate() {
        let message = message.map_err(|e| {
            LogError::bare(if index == 0 {
                format!("not a ULog file: {e}")
            } else {
                format!("message {index}: {e}")
            })
        })?;
        let UlogMessage::LoggedData(logged) = message else {
            continue;
        };
        let data = &logged.data;
        if data.multi_id_index.is_some_and(|i| i != 0) {
            continue;
        }
        let time_s = logged.timestamp as f64 / 1e6;
        match &*data.name {
            "vehicle_attitude" => {
                if let Some(q) = array(data, "q")
                    && let [w, x, y, z] = q[..]
                    && let Some(a) = attitude_of_ned_quaternion(w, x, y, z)
                {
                    attitude.push(AttitudeSample {
                        time_s,
                        attitude: a,
                    });
                }
            }
            "sensor_gps" | "vehicle_gps_position" => {
                if scalar(data, "fix_type").is_some_and(|f| f >= 3.0)
                    && let Some(g) = receiver_fix(data, time_s)
                {
                    receiver.push(g);
                }
            }
            "vehicle_global_position" => {
                if let (Some(lat), Some(lon), Some(alt)) = (
                    scalar(data, "lat"),
                    scalar(data, "lon"),
                    scalar(data, "alt"),
                ) {
                    fused.push(GnssSample {
                        time_s,
                        lat_deg: lat,
                        lon_deg: lon,
                        alt_msl_m: alt,
                        velocity: None,
                    });
                }
            }
            "vehicle_air_data" => {
                if let Some(altitude_m) = scalar(data, "baro_alt_meter").filter(|a| a.is_finite()) {
                    barometer.push(BaroSample { time_s, altitude_m });
                }
            }
            // Older PX4 logs carry the barometer in `sensor_combined`, its
            // time relative to the message's; INT32_MAX marks none.
            "sensor_combined" => {
                if let (Some(relative), Some(altitude_m)) = (
                    scalar(data, "baro_timestamp_relative"),
                    scalar(data, "baro_alt_meter"),
                ) && relative != f64::from(i32::MAX)
                    && altitude_m.is_finite()
                {
                    barometer.push(BaroSample {
                        time_s: time_s + relative / 1e6,
                        altitude_m,
                    });
                }
            }
            _ => {}
        }
    }
    let gnss = if receiver.is_empty() { fused } else { receiver };
    Ok(FlightLog {
        attitude,
        gnss,
        barometer,
    })
}

/// Older messages: `lat`/`lon` in 1e-7 degrees and `alt` in millimetres;
/// newer: `latitude_deg`, `longitude_deg`, `altitude_msl_m`.
fn receiver_fix(data: &Format, time_s: f64) -> Option<GnssSample> {
    let (lat, lon, alt) = match (
        scalar(data, "latitude_deg"),
        scalar(data, "longitude_deg"),
        scalar(data, "altitude_msl_m"),
    ) {
        (Some(lat), Some(lon), Some(alt)) => (lat, lon, alt),
        _ => (
            scalar(data, "lat")? * 1e-7,
            scalar(data, "lon")? * 1e-7,
            scalar(data, "alt")? * 1e-3,
        ),
    };
    // `vel_ned_valid` is 0 where the receiver gave no velocity.
    let velocity = (scalar(data, "vel_ned_valid") != Some(0.0))
        .then(|| GroundVelocity::new(scalar(data, "vel_n_m_s")?, scalar(data, "vel_e_m_s")?))
        .flatten();
    Some(GnssSample {
        time_s,
        lat_deg: lat,
        lon_deg: lon,
        alt_msl_m: alt,
        velocity,
    })
}

fn field<'a>(data: &'a Format, name: &str) -> Option<&'a FieldValue> {
    data.fields
        .iter()
        .find(|f| &*f.name == name)
        .map(|f| &f.value)
}

fn scalar(data: &Format, name: &str) -> Option<f64> {
    use FieldValue::*;
    let v = match field(data, name)? {
        ScalarU8(x) => f64::from(*x),
        ScalarU16(x) => f64::from(*x),
        ScalarU32(x) => f64::from(*x),
        ScalarU64(x) => *x as f64,
        ScalarI8(x) => f64::from(*x),
        ScalarI16(x) => f64::from(*x),
        ScalarI32(x) => f64::from(*x),
        ScalarI64(x) => *x as f64,
        ScalarF32(x) => f64::from(*x),
        ScalarF64(x) => *x,
        _ => return None,
    };
    v.is_finite().then_some(v)
}

fn array(data: &Format, name: &str) -> Option<Vec<f64>> {
    match field(data, name)? {
        FieldValue::ArrayF32(v) => Some(v.iter().map(|x| f64::from(*x)).collect()),
        FieldValue::ArrayF64(v) => Some(v.clone()),
        _ => None,
    }
}
