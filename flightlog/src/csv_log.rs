//! The project's CSV: `time_s,roll_deg,pitch_deg,heading_deg` (heading
//! clockwise from north, as autopilots log it), with optional
//! `lat_deg,lon_deg,alt_msl_m` columns for a GNSS reference and
//! `vel_north_mps,vel_east_mps` for its velocity.

use towernav_geometry::Attitude;

use crate::samples::{AttitudeSample, GnssSample, GroundVelocity};
use crate::{FlightLog, LogError};

#[derive(serde::Deserialize)]
struct Row {
    time_s: f64,
    roll_deg: f64,
    pitch_deg: f64,
    heading_deg: f64,
    lat_deg: Option<f64>,
    lon_deg: Option<f64>,
    alt_msl_m: Option<f64>,
    vel_north_mps: Option<f64>,
    vel_east_mps: Option<f64>,
}

pub(crate) fn parse(bytes: &[u8]) -> Result<FlightLog, LogError> {
    let mut attitude: Vec<AttitudeSample> = Vec::new();
    let mut gnss = Vec::new();
    for (i, row) in csv::Reader::from_reader(bytes)
        .deserialize::<Row>()
        .enumerate()
    {
        let line = i + 2;
        let bad = |reason: String| LogError::bare(format!("line {line}: {reason}"));
        let r = row.map_err(|e| bad(e.to_string()))?;
        if ![r.time_s, r.roll_deg, r.pitch_deg, r.heading_deg]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(bad("a value is not a finite number".into()));
        }
        if attitude.last().is_some_and(|s| r.time_s <= s.time_s) {
            return Err(bad(format!("time {} does not increase", r.time_s)));
        }
        attitude.push(AttitudeSample {
            time_s: r.time_s,
            attitude: Attitude::from_ned(
                r.roll_deg.to_radians(),
                r.pitch_deg.to_radians(),
                r.heading_deg.to_radians(),
            ),
        });
        if let (Some(lat), Some(lon), Some(alt)) = (r.lat_deg, r.lon_deg, r.alt_msl_m) {
            gnss.push(GnssSample {
                time_s: r.time_s,
                lat_deg: lat,
                lon_deg: lon,
                alt_msl_m: alt,
                velocity: r
                    .vel_north_mps
                    .zip(r.vel_east_mps)
                    .and_then(|(n, e)| GroundVelocity::new(n, e)),
            });
        }
    }
    Ok(FlightLog {
        attitude,
        gnss,
        barometer: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use crate::{FlightLog, LogFormat};

    #[test]
    fn a_bad_line_is_named() {
        let parse = |text: &str| FlightLog::parse(LogFormat::Csv, text.as_bytes());
        let err = parse("time_s,roll_deg,pitch_deg,heading_deg\n0,0,0,0\n0,1,1,1\n")
            .expect_err("time repeats")
            .to_string();
        assert!(
            err.contains("line 3") && err.contains("does not increase"),
            "{err}"
        );
        let err = parse("time_s,roll_deg,pitch_deg,heading_deg\n0,x,0,0\n")
            .expect_err("not a number")
            .to_string();
        assert!(err.contains("line 2"), "{err}");
        let log = parse("time_s,roll_deg,pitch_deg,heading_deg,lat_deg,lon_deg,alt_msl_m\n0,0,0,0,47.1,8.5,500\n")
            .expect("with GNSS");
        assert_eq!(log.gnss.len(), 1);
    }
}
