//! MAVLink telemetry logs as ground stations (QGroundControl, Mission
//! Planner, MAVProxy) write them: each record is the receive time (u64,
//! big-endian microseconds since the Unix epoch) followed by one MAVLink 1
//! or 2 frame. Messages carry the autopilot's boot time; GPS_RAW_INT, whose
//! own stamp may be either clock, is placed by its receive time against the
//! ATTITUDE messages' boot time.

use mavlink::MavlinkReader;
use mavlink::dialects::common::{GpsFixType, MavMessage};
use towernav_geometry::Attitude;

use crate::samples::{AttitudeSample, BaroSample, GnssSample, GroundVelocity};
use crate::{FlightLog, LogError};

const STAMP: usize = 8;

/// The length of the MAVLink frame that starts `bytes`, from its header.
fn frame_len(bytes: &[u8]) -> Option<usize> {
    match *bytes {
        [0xFE, payload, ..] => Some(6 + usize::from(payload) + 2),
        [0xFD, payload, incompat, ..] => {
            Some(10 + usize::from(payload) + 2 + if incompat & 1 == 1 { 13 } else { 0 })
        }
        _ => None,
    }
}

pub(crate) fn parse(bytes: &[u8]) -> Result<FlightLog, LogError> {
    let mut attitude = Vec::new();
    let mut global = Vec::new();
    let mut raw: Vec<(u64, GnssSample)> = Vec::new();
    let mut clock_offsets_us: Vec<i64> = Vec::new();
    // ALTITUDE's barometric climb, and VFR_HUD's altitude stamped by the
    // latest ATTITUDE's boot time (VFR_HUD has no time of its own).
    let (mut altitude, mut hud) = (Vec::new(), Vec::new());
    let mut vehicle: Option<u32> = None;
    let mut at = 0usize;
    let mut records = 0usize;
    while at < bytes.len() {
        let rest = &bytes[at..];
        let Some(stamp) = rest.get(..STAMP) else {
            return Err(truncated(at, records));
        };
        let received_us = u64::from_be_bytes(stamp.try_into().expect("eight bytes"));
        let frame = &rest[STAMP..];
        let Some(len) = frame_len(frame) else {
            return Err(LogError::bare(format!(
                "byte {}: record {} has no MAVLink frame after its time stamp (not a .tlog?)",
                at + STAMP,
                records + 1
            )));
        };
        let Some(frame) = frame.get(..len) else {
            return Err(truncated(at, records));
        };
        at += STAMP + len;
        records += 1;
        // A frame of a message this dialect does not know, or with a bad
        // CRC, is skipped: logs hold other dialects' messages.
        let Ok((header, message)) = MavlinkReader::new(frame).read_any_message::<MavMessage>()
        else {
            continue;
        };
        match message {
            MavMessage::ATTITUDE(a) => {
                if *vehicle.get_or_insert(header.system_id) != header.system_id {
                    continue;
                }
                let boot_us = i64::from(a.time_boot_ms) * 1000;
                clock_offsets_us.push(received_us as i64 - boot_us);
                attitude.push(AttitudeSample {
                    time_s: f64::from(a.time_boot_ms) / 1000.0,
                    attitude: Attitude::from_ned(
                        f64::from(a.roll),
                        f64::from(a.pitch),
                        f64::from(a.yaw),
                    ),
                });
            }
            MavMessage::GLOBAL_POSITION_INT(p) if vehicle.is_none_or(|v| v == header.system_id) => {
                global.push(GnssSample {
                    time_s: f64::from(p.time_boot_ms) / 1000.0,
                    lat_deg: f64::from(p.lat) * 1e-7,
                    lon_deg: f64::from(p.lon) * 1e-7,
                    alt_msl_m: f64::from(p.alt) * 1e-3,
                    // cm/s, x north and y east.
                    velocity: GroundVelocity::new(f64::from(p.vx) / 100.0, f64::from(p.vy) / 100.0),
                });
            }
            MavMessage::GPS_RAW_INT(g) if vehicle.is_none_or(|v| v == header.system_id) => {
                if matches!(
                    g.fix_type,
                    GpsFixType::GPS_FIX_TYPE_NO_GPS
                        | GpsFixType::GPS_FIX_TYPE_NO_FIX
                        | GpsFixType::GPS_FIX_TYPE_2D_FIX
                ) {
                    continue;
                }
                raw.push((
                    received_us,
                    GnssSample {
                        time_s: 0.0,
                        lat_deg: f64::from(g.lat) * 1e-7,
                        lon_deg: f64::from(g.lon) * 1e-7,
                        alt_msl_m: f64::from(g.alt) * 1e-3,
                        // cm/s and centidegrees; UINT16_MAX where unknown.
                        velocity: (g.vel != u16::MAX && g.cog != u16::MAX)
                            .then(|| {
                                GroundVelocity::from_course(
                                    f64::from(g.vel) / 100.0,
                                    f64::from(g.cog) / 100.0,
                                )
                            })
                            .flatten(),
                    },
                ));
            }
            MavMessage::ALTITUDE(a) if vehicle.is_none_or(|v| v == header.system_id) => {
                // `time_usec` is boot time or UNIX time: a UNIX time
                // (over 11 days) takes the latest ATTITUDE's boot time.
                let time_s = if a.time_usec < 1_000_000_000_000 {
                    Some(a.time_usec as f64 / 1e6)
                } else {
                    attitude.last().map(|s| s.time_s)
                };
                let altitude_m = f64::from(a.altitude_monotonic);
                if let Some(time_s) = time_s
                    && altitude_m.is_finite()
                {
                    altitude.push(BaroSample { time_s, altitude_m });
                }
            }
            MavMessage::VFR_HUD(h) if vehicle.is_none_or(|v| v == header.system_id) => {
                if let Some(last) = attitude.last()
                    && h.alt.is_finite()
                {
                    hud.push(BaroSample {
                        time_s: last.time_s,
                        altitude_m: f64::from(h.alt),
                    });
                }
            }
            _ => {}
        }
    }
    let barometer = if altitude.is_empty() { hud } else { altitude };
    // Receive time less boot time: the smallest is the least delayed
    // message's, the best estimate of the two clocks' offset.
    let gnss = match clock_offsets_us.iter().min() {
        Some(offset) if !raw.is_empty() => raw
            .into_iter()
            .map(|(received_us, g)| GnssSample {
                time_s: (received_us as i64 - offset) as f64 / 1e6,
                ..g
            })
            .collect(),
        _ => global,
    };
    Ok(FlightLog {
        attitude,
        gnss,
        barometer,
    })
}

fn truncated(at: usize, records: usize) -> LogError {
    LogError::bare(format!(
        "cut short at byte {at}, in the record after the {records} read"
    ))
}
