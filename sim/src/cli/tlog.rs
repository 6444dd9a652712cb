//! A flight as the ground station's telemetry log (`.tlog`) would hold it:
//! each record the receive time (big-endian microseconds since the Unix
//! epoch) and one MAVLink 2 frame. The autopilot's clock starts
//! [`BOOT_LEAD_S`] before the camera's, as a real one boots before the
//! recording starts, so a replay needs that camera-to-log offset.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use mavlink::dialects::common::{
    ALTITUDE_DATA, ATTITUDE_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, MavAutopilot,
    MavMessage, MavModeFlag, MavState, MavType,
};
use mavlink::{MavHeader, write_v2_msg};
use nalgebra::Point3;
use towernav_geometry::{Attitude, Datum, geoid_height_m};
use towernav_sim::gnss::{GnssNoise, GnssParams};
use towernav_sim::{Barometer, BarometerParams};

/// Seconds the autopilot has been up when the camera's first frame is taken.
pub const BOOT_LEAD_S: f64 = 12.5;
/// The Unix time of the autopilot's boot in these logs (2026-06-01 10:00 UTC).
const BOOT_UNIX_US: u64 = 1_780_308_000_000_000;
/// Fixes a second in GLOBAL_POSITION_INT, as ArduPilot and PX4 stream it by default.
pub const GNSS_RATE_HZ: f64 = 10.0;
/// The ground station's receive delay after the autopilot's stamp.
const LINK_DELAY_US: u64 = 15_000;

/// One frame's state for the log: flight time, the IMU's attitude, the true position.
pub struct LogRow {
    pub time_s: f64,
    pub attitude: Attitude,
    pub position_in_world: Point3<f64>,
}

/// Writes ATTITUDE for every row, GLOBAL_POSITION_INT at [`GNSS_RATE_HZ`]
/// with GNSS noise, ALTITUDE at the same rate with a barometer's
/// (`altitude_monotonic`, zero at the datum's height), and a HEARTBEAT a second.
pub struct TlogWriter {
    out: std::io::BufWriter<std::fs::File>,
    datum: Datum,
    gnss: GnssNoise,
    barometer: Barometer,
    sequence: u8,
    next_fix_s: f64,
    next_heartbeat_s: f64,
    previous: Option<(f64, Point3<f64>)>,
}

impl TlogWriter {
    pub fn create(path: &Path, datum: Datum, gnss: GnssParams, seed: u64) -> anyhow::Result<Self> {
        let file =
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        Ok(Self {
            out: std::io::BufWriter::new(file),
            datum,
            gnss: GnssNoise::new(gnss, seed),
            barometer: Barometer::new(BarometerParams::default(), seed, 0.0),
            sequence: 0,
            next_fix_s: 0.0,
            next_heartbeat_s: 0.0,
            previous: None,
        })
    }

    pub fn write(&mut self, row: &LogRow) -> anyhow::Result<()> {
        let boot_s = row.time_s + BOOT_LEAD_S;
        let boot_ms = (boot_s * 1000.0).round() as u32;
        if row.time_s >= self.next_heartbeat_s {
            self.next_heartbeat_s += 1.0;
            self.record(boot_s, &MavMessage::HEARTBEAT(heartbeat()))?;
        }
        let a = &row.attitude;
        self.record(
            boot_s,
            &MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: boot_ms,
                roll: a.roll as f32,
                pitch: a.pitch as f32,
                yaw: a.yaw_from_north() as f32,
                ..ATTITUDE_DATA::DEFAULT
            }),
        )?;
        if row.time_s >= self.next_fix_s {
            self.next_fix_s += 1.0 / GNSS_RATE_HZ;
            let fix = self.gnss.fix(row.time_s, &row.position_in_world);
            let message = self.position(boot_ms, row, &fix);
            self.record(boot_s, &MavMessage::GLOBAL_POSITION_INT(message))?;
            let altitude = self.barometer.read(row.position_in_world.z) as f32;
            self.record(
                boot_s,
                &MavMessage::ALTITUDE(ALTITUDE_DATA {
                    time_usec: u64::from(boot_ms) * 1000,
                    altitude_monotonic: altitude,
                    altitude_amsl: f32::NAN,
                    altitude_local: altitude,
                    altitude_relative: altitude,
                    altitude_terrain: f32::NAN,
                    bottom_clearance: f32::NAN,
                }),
            )?;
        }
        self.previous = Some((row.time_s, row.position_in_world));
        Ok(())
    }

    fn position(
        &mut self,
        boot_ms: u32,
        row: &LogRow,
        fix: &Point3<f64>,
    ) -> GLOBAL_POSITION_INT_DATA {
        let g = self.datum.to_geodetic(fix);
        let msl = g.height_m - geoid_height_m(g.lat_deg, g.lon_deg);
        // Velocity from the truth's last step with the receiver's error,
        // north-east-down, cm/s.
        let v = self.previous.map_or(nalgebra::Vector3::zeros(), |(t, p)| {
            (row.position_in_world - p) / (row.time_s - t).max(1e-3)
        });
        let ground = self.gnss.velocity(row.time_s, v.xy());
        GLOBAL_POSITION_INT_DATA {
            time_boot_ms: boot_ms,
            lat: (g.lat_deg * 1e7).round() as i32,
            lon: (g.lon_deg * 1e7).round() as i32,
            alt: (msl * 1e3).round() as i32,
            relative_alt: (fix.z * 1e3).round() as i32,
            vx: (ground.y * 100.0).round() as i16,
            vy: (ground.x * 100.0).round() as i16,
            vz: (-v.z * 100.0).round() as i16,
            hdg: (row.attitude.yaw_from_north().to_degrees().rem_euclid(360.0) * 100.0).round()
                as u16,
        }
    }

    fn record(&mut self, boot_s: f64, message: &MavMessage) -> anyhow::Result<()> {
        let received_us = BOOT_UNIX_US + (boot_s * 1e6).round() as u64 + LINK_DELAY_US;
        self.out.write_all(&received_us.to_be_bytes())?;
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        write_v2_msg(&mut self.out, header, message).context("encoding a MAVLink frame")?;
        Ok(())
    }

    pub fn finish(mut self) -> anyhow::Result<()> {
        self.out.flush().context("writing the tlog")
    }
}

fn heartbeat() -> HEARTBEAT_DATA {
    HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    }
}
