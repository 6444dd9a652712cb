//! Session recording and replay as MCAP, the robotics log standard: one
//! channel per Zenoh key, the payloads exactly as they crossed the wire (JSON),
//! so Foxglove or `mcap cat` can read a towernav session too.
//!
//! Liveliness is recorded on the `alive` key with the payload `put` or `delete`.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use towernav_protocol::Keys;

use crate::events::{NetEvent, decode_alive, decode_sample};

#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("recording {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("recording {path}: {source}")]
    Mcap {
        path: PathBuf,
        source: mcap::McapError,
    },
}

/// Payloads of liveliness changes in a recording.
pub const ALIVE_PUT: &[u8] = b"put";
pub const ALIVE_DELETE: &[u8] = b"delete";

pub struct Recorder {
    writer: mcap::Writer<BufWriter<File>>,
    channels: HashMap<String, u16>,
    path: PathBuf,
    sequence: u32,
}

impl Recorder {
    pub fn create(path: &Path) -> Result<Self, RecordingError> {
        let file = File::create(path).map_err(|source| RecordingError::Io {
            path: path.into(),
            source,
        })?;
        let writer =
            mcap::Writer::new(BufWriter::new(file)).map_err(|source| RecordingError::Mcap {
                path: path.into(),
                source,
            })?;
        Ok(Self {
            writer,
            channels: HashMap::new(),
            path: path.into(),
            sequence: 0,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn messages(&self) -> u32 {
        self.sequence
    }

    fn err(&self) -> impl Fn(mcap::McapError) -> RecordingError + '_ {
        |source| RecordingError::Mcap {
            path: self.path.clone(),
            source,
        }
    }

    /// One sample, stamped with the ground station's receive time.
    pub fn write(
        &mut self,
        key: &str,
        payload: &[u8],
        log_time_ns: u64,
    ) -> Result<(), RecordingError> {
        let channel_id = match self.channels.get(key) {
            Some(&id) => id,
            None => {
                let id = self
                    .writer
                    .add_channel(0, key, "json", &BTreeMap::new())
                    .map_err(|source| RecordingError::Mcap {
                        path: self.path.clone(),
                        source,
                    })?;
                self.channels.insert(key.to_owned(), id);
                id
            }
        };
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        self.writer
            .write_to_known_channel(&header, payload)
            .map_err(self.err())
    }

    /// Writes the summary and index; a recording not finished is still readable up to its last chunk.
    pub fn finish(mut self) -> Result<u32, RecordingError> {
        self.writer.finish().map_err(self.err())?;
        Ok(self.sequence)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct RecordedSample {
    pub log_time_ns: u64,
    pub key: String,
    pub payload: Vec<u8>,
}

impl RecordedSample {
    /// The event this sample stood for when it was live.
    pub fn event(&self) -> Option<NetEvent> {
        if Keys::parse_alive(&self.key).is_ok() {
            return Some(decode_alive(&self.key, self.payload != ALIVE_DELETE));
        }
        decode_sample(&self.key, &self.payload)
    }
}

/// Every message of a recording, in log-time order.
pub fn read(path: &Path) -> Result<Vec<RecordedSample>, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.into(),
        source,
    })?;
    let mcap_err = |source| RecordingError::Mcap {
        path: path.into(),
        source,
    };
    let mut samples = Vec::new();
    for message in mcap::MessageStream::new(&bytes).map_err(mcap_err)? {
        let message = message.map_err(mcap_err)?;
        samples.push(RecordedSample {
            log_time_ns: message.log_time,
            key: message.channel.topic.clone(),
            payload: message.data.into_owned(),
        });
    }
    samples.sort_by_key(|s| s.log_time_ns);
    Ok(samples)
}

/// Plays a recording into the app at its recorded pace (`speed` times faster;
/// 0 as fast as possible). The file is read, and refused, before the thread starts.
pub fn spawn_replay(
    path: &Path,
    speed: f64,
    tx: std::sync::mpsc::Sender<NetEvent>,
    wake: impl Fn() + Send + 'static,
) -> Result<(), RecordingError> {
    let samples = read(path)?;
    let name = path.display().to_string();
    let spawned = std::thread::Builder::new()
        .name("towernav-gs-replay".into())
        .spawn(move || {
            let start = std::time::Instant::now();
            let t0 = samples.first().map_or(0, |s| s.log_time_ns);
            for s in &samples {
                if speed > 0.0 {
                    let due = (s.log_time_ns - t0) as f64 * 1e-9 / speed;
                    let wait = due - start.elapsed().as_secs_f64();
                    if wait > 0.0 {
                        std::thread::sleep(std::time::Duration::from_secs_f64(wait));
                    }
                }
                if let Some(event) = s.event()
                    && tx.send(event).is_err()
                {
                    return;
                }
                wake();
            }
            let _ = tx.send(NetEvent::Notice(format!(
                "replay of {name} finished ({} messages)",
                samples.len()
            )));
            wake();
        });
    spawned.map(|_| ()).map_err(|source| RecordingError::Io {
        path: path.into(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::pose;
    use towernav_protocol::{NodeId, PoseEstimate, encode};

    #[test]
    fn a_recording_replays_the_same_events_in_order() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("session.mcap");
        let keys = Keys::new(NodeId::new("demo").expect("valid"));
        let uav = NodeId::new("uav1").expect("valid");
        let mut rec = Recorder::create(&path).expect("create");
        rec.write(&keys.alive(&uav), ALIVE_PUT, 5).expect("write");
        for seq in 0..3 {
            let p = pose("uav1", 30.52, 114.36, seq);
            rec.write(
                &keys.uav_key::<PoseEstimate>(&uav),
                &encode(&p).expect("encode"),
                10 + seq,
            )
            .expect("write");
        }
        rec.write(&keys.alive(&uav), ALIVE_DELETE, 20)
            .expect("write");
        assert_eq!(rec.finish().expect("finish"), 5);

        let samples = read(&path).expect("read");
        let events: Vec<NetEvent> = samples.iter().filter_map(RecordedSample::event).collect();
        assert_eq!(events.len(), 5);
        assert!(matches!(&events[0], NetEvent::Alive { alive: true, .. }));
        assert!(matches!(&events[2], NetEvent::Pose(p) if p.seq == 1));
        assert!(matches!(&events[4], NetEvent::Alive { alive: false, .. }));
    }

    #[test]
    fn a_file_that_is_not_mcap_is_refused_with_its_path() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("notes.mcap");
        std::fs::write(&path, b"hello").expect("write");
        let err = read(&path).expect_err("not mcap");
        assert!(err.to_string().contains("notes.mcap"), "{err}");
    }
}
