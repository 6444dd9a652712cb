//! GoPro's telemetry (GPMF) from inside an MP4, on the video's clock: the
//! camera's GPS (`GPS5`, `GPS9`), its gravity vector (`GRAV`) and orientation
//! (`CORI`), its IMU (`ACCL`, `GYRO`), and what a GoPro Karma records of the
//! vehicle's MAVLink (`ATTD` attitude, `GLPI` global position, `GPRI` raw GPS).
//!
//! A sample's time is its payload's span in the MP4 shared evenly among the
//! payload's samples, as GoPro's own parser times them.

mod klv;
pub mod mp4_track;
mod to_log;

use std::io::{Read, Seek};

pub use to_log::flight_log;

use crate::LogError;

/// One measurement, seconds from the start of the video.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub time_s: f64,
    pub values: Vec<f64>,
}

/// Every sample of one key from one device.
#[derive(Debug, Clone, PartialEq)]
pub struct Stream {
    /// `DVID`: 1 for the camera, another for a device attached to it.
    pub device_id: u32,
    /// `DVNM`: "Camera", "GoPro Karma v1.0", ...
    pub device_name: String,
    /// `STNM`, where the stream names itself.
    pub name: String,
    pub key: String,
    pub samples: Vec<Sample>,
}

/// The GPMF track of one video.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Telemetry {
    pub streams: Vec<Stream>,
    /// The end of the last payload: the video's length as the track sees it.
    pub duration_s: f64,
}

impl Telemetry {
    /// Reads the GPMF track of an MP4 (`Ok(None)` if it has none).
    pub fn read<R: Read + Seek>(r: &mut R) -> Result<Option<Self>, LogError> {
        let Some(payloads) = mp4_track::gpmf_payloads(r)? else {
            return Ok(None);
        };
        let mut t = Telemetry::default();
        for (i, p) in payloads.iter().enumerate() {
            let bytes = mp4_track::read_payload(r, p)?;
            let streams = klv::payload_streams(&bytes).map_err(|e| {
                LogError::bare(format!(
                    "payload {} (at {:.3} s): {}",
                    i + 1,
                    p.start_s,
                    e.reason
                ))
            })?;
            for s in streams {
                t.push(s, p.start_s, p.end_s);
            }
            t.duration_s = t.duration_s.max(p.end_s);
        }
        Ok(Some(t))
    }

    fn push(&mut self, s: klv::PayloadStream, start_s: f64, end_s: f64) {
        let key = String::from_utf8_lossy(&s.key).into_owned();
        let at = match self
            .streams
            .iter()
            .position(|x| x.device_id == s.device_id && x.key == key)
        {
            Some(i) => i,
            None => {
                self.streams.push(Stream {
                    device_id: s.device_id,
                    device_name: s.device_name,
                    name: s.stream_name,
                    key,
                    samples: Vec::new(),
                });
                self.streams.len() - 1
            }
        };
        let n = s.rows.len().max(1) as f64;
        let step = (end_s - start_s) / n;
        self.streams[at]
            .samples
            .extend(s.rows.into_iter().enumerate().map(|(i, values)| Sample {
                time_s: start_s + i as f64 * step,
                values,
            }));
    }

    /// Whether the video at `path` has a GPMF track (a GoPro's), without
    /// reading the track; `false` for a file that cannot be read as an MP4.
    pub fn in_video(path: &std::path::Path) -> bool {
        std::fs::File::open(path).is_ok_and(|f| {
            matches!(
                mp4_track::gpmf_payloads(&mut std::io::BufReader::new(f)),
                Ok(Some(_))
            )
        })
    }

    /// The first device's stream of `key`, if any has one.
    pub fn stream(&self, key: &str) -> Option<&Stream> {
        self.streams
            .iter()
            .find(|s| s.key == key && !s.samples.is_empty())
    }
}

#[cfg(test)]
#[path = "gpmf_tests.rs"]
mod tests;
