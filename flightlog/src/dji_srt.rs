//! DJI's per-frame telemetry subtitles (`.SRT` beside each video). One cue
//! per frame (or per second on older models); what a cue holds depends on
//! the model family:
//!
//! - bracketed, current (Mavic 3, Mini 3/4, Air 3, Avata 2):
//!   `[latitude: 3.41531] [longitude: -3.37440] [rel_alt: -2.400 abs_alt: 0.401]`,
//!   some with `[gb_yaw: 130.6 gb_pitch: -26.5 gb_roll: 0.0]` and `[focal_len: 24.00]`;
//! - bracketed, Air 2 / Air 2S: `[altitude: 117.000000]` instead of the pair;
//! - bracketed, Mavic 2 era: `[latitude : -20.25] [longtitude : 149.02]`
//!   (sic), no height, and on some files no cue times;
//! - `GPS(lon,lat,sats)` with `HOME(...)` and `BAROMETER:1.9` or `Hb:1.9`
//!   (Mavic Pro, Phantom 4), or `GPS(lat,lon,0.0M) BAROMETER:0.3M` (Matrice 300);
//! - one line of `GPS (lon, lat, sats)`, `H 85.80m` and, on the Phantom 4
//!   RTK, `F.PRY (pitch°, roll°, yaw°)` (aircraft) and `G.PRY (...)` (gimbal).
//!
//! Heights as given: `rel_alt`, `BAROMETER`, `Hb` and `H` are above the
//! take-off point (the barometer's); `abs_alt` and Air 2's `altitude` are
//! DJI's absolute altitude, taken as above mean sea level. Times are the
//! cue's start, seconds from the start of the video; a file without cues
//! takes them from its date lines.

use std::sync::LazyLock;

use regex::Regex;
use towernav_geometry::Attitude;

use crate::samples::{AttitudeSample, BaroSample, GnssSample};
use crate::{FlightLog, LogError};

/// One cue's telemetry.
#[derive(Debug, Clone, PartialEq)]
pub struct SrtFrame {
    /// The cue's start, seconds from the start of the video.
    pub time_s: f64,
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Above the take-off point.
    pub rel_alt_m: Option<f64>,
    /// DJI's absolute altitude (above mean sea level).
    pub abs_alt_m: Option<f64>,
    /// The gimbal's (the camera's) yaw, pitch and roll, degrees, yaw
    /// clockwise from north and pitch -90 straight down.
    pub gimbal_ypr_deg: Option<[f64; 3]>,
    /// The aircraft's, where the file has them.
    pub aircraft_ypr_deg: Option<[f64; 3]>,
    /// The lens's focal length as written (mm; Air 2's are tenths).
    pub focal_len: Option<f64>,
}

fn re(pattern: &str) -> Regex {
    Regex::new(pattern).unwrap_or_else(|e| panic!("a fixed pattern: {e}"))
}

static CUE: LazyLock<Regex> = LazyLock::new(|| {
    re(r"(\d+):(\d{2}):(\d{2})[,.](\d{1,3})\s*-->\s*(\d+):(\d{2}):(\d{2})[,.](\d{1,3})")
});
static DATE: LazyLock<Regex> = LazyLock::new(|| {
    re(r"(\d{4})[-.](\d{1,2})[-.](\d{1,2})\s+(\d{1,2}):(\d{2}):(\d{2})(?:[.,](\d{1,3}))?")
});
static LAT: LazyLock<Regex> = LazyLock::new(|| re(r"\[latitude\s*:\s*(-?[\d.]+)\]"));
static LON: LazyLock<Regex> = LazyLock::new(|| re(r"\[longt?itude\s*:\s*(-?[\d.]+)\]"));
static REL_ALT: LazyLock<Regex> = LazyLock::new(|| re(r"rel_alt\s*:\s*(-?[\d.]+)"));
static ABS_ALT: LazyLock<Regex> = LazyLock::new(|| re(r"abs_alt\s*:\s*(-?[\d.]+)"));
static ALTITUDE: LazyLock<Regex> = LazyLock::new(|| re(r"\[altitude\s*:\s*(-?[\d.]+)\]"));
static GIMBAL: LazyLock<Regex> = LazyLock::new(|| {
    re(r"gb_yaw\s*:\s*(-?[\d.]+)\s+gb_pitch\s*:\s*(-?[\d.]+)\s+gb_roll\s*:\s*(-?[\d.]+)")
});
static FOCAL: LazyLock<Regex> = LazyLock::new(|| re(r"focal_len\s*:\s*(-?[\d.]+)"));
/// `GPS(a,b,c)` or `GPS (a, b, c)`; a trailing `M` on c marks the Matrice
/// order (lat, lon, altitude), else it is (lon, lat, satellites).
static GPS: LazyLock<Regex> =
    LazyLock::new(|| re(r"GPS\s*\(\s*(-?[\d.]+)\s*,\s*(-?[\d.]+)\s*,\s*(-?[\d.]+)\s*(M|m)?\s*\)"));
static BARO: LazyLock<Regex> = LazyLock::new(|| re(r"(?:BAROMETER|Hb)\s*:\s*(-?[\d.]+)"));
static HEIGHT: LazyLock<Regex> = LazyLock::new(|| re(r"(?:^|[,\s])H\s+(-?[\d.]+)m"));
static PRY: LazyLock<Regex> = LazyLock::new(|| {
    re(r"([FG])\.PRY\s*\(\s*(-?[\d.]+)°?\s*,\s*(-?[\d.]+)°?\s*,\s*(-?[\d.]+)°?\s*\)")
});

fn num(re: &Regex, text: &str) -> Option<f64> {
    re.captures(text)?.get(1)?.as_str().parse().ok()
}

/// The date line's time, seconds on a day count of its own (only
/// differences between cues are used).
fn date_s(text: &str) -> Option<f64> {
    let c = DATE.captures(text)?;
    let n = |i: usize| c.get(i)?.as_str().parse::<u32>().ok();
    let month = time::Month::try_from(u8::try_from(n(2)?).ok()?).ok()?;
    let date = time::Date::from_calendar_date(
        i32::try_from(n(1)?).ok()?,
        month,
        u8::try_from(n(3)?).ok()?,
    )
    .ok()?;
    let ms: f64 = c
        .get(7)
        .map_or(Some(0.0), |m| format!("0.{:0<3}", m.as_str()).parse().ok())?;
    Some(
        f64::from(date.to_julian_day()) * 86_400.0
            + f64::from(n(4)? * 3600 + n(5)? * 60 + n(6)?)
            + ms,
    )
}

fn cue_start_s(text: &str) -> Option<f64> {
    let c = CUE.captures(text)?;
    let n = |i: usize| c.get(i).and_then(|m| m.as_str().parse::<f64>().ok());
    let ms = c.get(4)?.as_str();
    let frac: f64 = format!("0.{ms:0<3}").parse().ok()?;
    Some(n(1)? * 3600.0 + n(2)? * 60.0 + n(3)? + frac)
}

/// The telemetry of every cue, in file order. A cue with no position (a
/// title, a model that writes none) is skipped; a file with none at all is
/// refused, naming what was looked for.
pub fn parse_frames(text: &str) -> Result<Vec<SrtFrame>, LogError> {
    let text = text.replace('\r', "");
    let mut frames = Vec::new();
    let mut first_date: Option<f64> = None;
    let mut cues = 0;
    for (block_no, block) in text.split("\n\n").enumerate() {
        let block = block.trim();
        if block.is_empty() {
            continue;
        }
        cues += 1;
        let at = |reason: String| LogError::bare(format!("cue {}: {reason}", block_no + 1));
        let time_s = match cue_start_s(block) {
            Some(t) => t,
            None => match date_s(block) {
                Some(d) => d - *first_date.get_or_insert(d),
                None => continue,
            },
        };
        let (lat, lon, mut abs_alt) =
            if let (Some(lat), Some(lon)) = (num(&LAT, block), num(&LON, block)) {
                (lat, lon, num(&ABS_ALT, block).or(num(&ALTITUDE, block)))
            } else if let Some(c) = GPS.captures(block) {
                let v = |i: usize| c.get(i).and_then(|m| m.as_str().parse::<f64>().ok());
                let (a, b, third) = (v(1), v(2), v(3));
                match (a, b, c.get(4).is_some()) {
                    (Some(lat), Some(lon), true) => (lat, lon, third),
                    (Some(lon), Some(lat), false) => (lat, lon, None),
                    _ => continue,
                }
            } else {
                continue;
            };
        if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) {
            return Err(at(format!(
                "latitude {lat} or longitude {lon} is out of range"
            )));
        }
        // A Matrice writes 0.0M where it has no altitude.
        if abs_alt == Some(0.0) && num(&ALTITUDE, block).is_none() && num(&ABS_ALT, block).is_none()
        {
            abs_alt = None;
        }
        let rel_alt = num(&REL_ALT, block)
            .or_else(|| num(&BARO, block))
            .or_else(|| num(&HEIGHT, block));
        let gimbal = GIMBAL.captures(block).and_then(|c| {
            let v = |i: usize| c.get(i)?.as_str().parse::<f64>().ok();
            Some([v(1)?, v(2)?, v(3)?])
        });
        let mut gimbal_pry = None;
        let mut aircraft_pry = None;
        for c in PRY.captures_iter(block) {
            let v = |i: usize| c.get(i).and_then(|m| m.as_str().parse::<f64>().ok());
            if let (Some(p), Some(r), Some(y)) = (v(2), v(3), v(4)) {
                match c.get(1).map(|m| m.as_str()) {
                    Some("G") => gimbal_pry = Some([y, p, r]),
                    _ => aircraft_pry = Some([y, p, r]),
                }
            }
        }
        frames.push(SrtFrame {
            time_s,
            lat_deg: lat,
            lon_deg: lon,
            rel_alt_m: rel_alt,
            abs_alt_m: abs_alt,
            gimbal_ypr_deg: gimbal.or(gimbal_pry),
            aircraft_ypr_deg: aircraft_pry,
            focal_len: num(&FOCAL, block),
        });
    }
    if frames.is_empty() {
        return Err(LogError::bare(format!(
            "none of its {cues} cues holds a position (looked for [latitude: ..] [longitude: ..] and GPS(..))"
        )));
    }
    Ok(frames)
}

/// A DJI SRT as a flight log: its positions as GNSS (at the absolute
/// altitude, or the height above take-off where the file has no other),
/// its height above take-off as the barometer, and the gimbal's angles as
/// the attitude: with a gimbal the camera's attitude is the gimbal's, so fly
/// it with a zero camera mount. A file without gimbal angles is refused
/// here, saying what the chain needs instead.
pub(crate) fn parse(bytes: &[u8]) -> Result<FlightLog, LogError> {
    let text = String::from_utf8_lossy(bytes);
    let frames = parse_frames(&text)?;
    let mut log = FlightLog {
        attitude: Vec::new(),
        gnss: Vec::new(),
        barometer: Vec::new(),
    };
    for f in &frames {
        log.gnss.push(GnssSample {
            time_s: f.time_s,
            lat_deg: f.lat_deg,
            lon_deg: f.lon_deg,
            alt_msl_m: f.abs_alt_m.or(f.rel_alt_m).unwrap_or(0.0),
            velocity: None,
        });
        if let Some(rel) = f.rel_alt_m {
            log.barometer.push(BaroSample {
                time_s: f.time_s,
                altitude_m: rel,
            });
        }
        if let Some([yaw, pitch, roll]) = f.gimbal_ypr_deg {
            log.attitude.push(AttitudeSample {
                time_s: f.time_s,
                attitude: Attitude::from_ned(
                    roll.to_radians(),
                    pitch.to_radians(),
                    yaw.to_radians(),
                ),
            });
        }
    }
    if log.attitude.is_empty() {
        return Err(LogError::bare(format!(
            "its {} cues have positions but no gimbal angles (this model writes none): \
             the chain needs the camera's attitude; give the aircraft's own flight log \
             as --log instead (a .bin, .tlog, .ulg, or its flight record converted to a \
             CSV of time_s,roll_deg,pitch_deg,heading_deg,lat_deg,lon_deg,alt_msl_m on the \
             video's clock)",
            frames.len()
        )));
    }
    Ok(log)
}

#[cfg(test)]
#[path = "dji_srt_tests.rs"]
mod tests;
